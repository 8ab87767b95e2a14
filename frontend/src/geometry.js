// Geometry for the 3D view that does not need three.js (tested with node --test).
//
// Machine frame, Z up, mm. Angles from the slices table are machine angles in degrees:
// counter-clockwise from +X seen from +Z, an arc from entry_machine_deg to exit_machine_deg
// counter-clockwise (exit > entry, at most 360 degrees apart).

const DEG = Math.PI / 180;

// Engaged arcs of one CL as {z, radius, start, length} (radians, counter-clockwise from +X).
export function arcSpans(slices) {
  const out = [];
  for (const s of slices || []) {
    const a0 = Number(s.entry_machine_deg);
    const a1 = Number(s.exit_machine_deg);
    const r = Number(s.radius_mm);
    const z = Number(s.z_machine_mm);
    if (![a0, a1, r, z].every(Number.isFinite) || r <= 0) continue;
    const span = Math.min(360, Math.max(0, a1 - a0));
    if (span <= 0) continue;
    out.push({ z, radius: r, start: a0 * DEG, length: span * DEG });
  }
  return out;
}

// Points of an arc span on a circle around (cx, cy), for line drawing or tests.
export function arcPoints(span, cx, cy, segmentsPerTurn = 96) {
  const n = Math.max(2, Math.ceil((segmentsPerTurn * span.length) / (2 * Math.PI)) + 1);
  const pts = [];
  for (let i = 0; i < n; i++) {
    const a = span.start + (span.length * i) / (n - 1);
    pts.push([cx + span.radius * Math.cos(a), cy + span.radius * Math.sin(a), span.z]);
  }
  return pts;
}

// How to draw a tool: a cylinder of the cutting diameter over the flute length, with a ball end
// for ball mills (the tip of the tool is the CL point).
export function toolShape(tool) {
  const d = Number(tool && tool.diameter_mm) || 6;
  const length = Number(tool && tool.flute_length_mm) || 3 * d;
  const kind = String((tool && tool.kind) || "flat").toLowerCase();
  return { radius: d / 2, length, ball: kind.includes("ball") };
}

// Axis-aligned bounds of the CL points and the stock, [[x0,y0,z0],[x1,y1,z1]].
export function bounds(cls, stock) {
  const lo = [Infinity, Infinity, Infinity];
  const hi = [-Infinity, -Infinity, -Infinity];
  const add = (p) => {
    for (let k = 0; k < 3; k++) {
      lo[k] = Math.min(lo[k], p[k]);
      hi[k] = Math.max(hi[k], p[k]);
    }
  };
  if (cls) for (let i = 0; i < cls.x.length; i++) add([cls.x[i], cls.y[i], cls.z[i]]);
  const box = stockBox(stock);
  if (box) {
    add(box.min);
    add(box.max);
  }
  if (!Number.isFinite(lo[0])) return [[-1, -1, -1], [1, 1, 1]];
  return [lo, hi];
}

// The stock outline as a box {min, max}: boxes as they are, cylinders by their bounding box.
export function stockBox(stock) {
  if (!stock) return null;
  if (stock.kind === "box") return { min: stock.min, max: stock.max };
  if (stock.kind === "cylinder") {
    const [cx, cy, cz] = stock.base_center;
    const r = stock.radius;
    return { min: [cx - r, cy - r, cz], max: [cx + r, cy + r, cz + stock.height] };
  }
  return null;
}

export const STATUS_COLORS = { engaged: 0xe8590c, air: 0x1c7ed6, rapid: 0x868e96, failed: 0xe03131 };

// Colours of the 3D view's layers; those of the GLB's nodes match fusioncut/viz/scene.py's LAYERS.
export const LAYER_COLORS = {
  ipw: 0x9ea3ab, contact_faces: 0xd91414, tool: 0xe6b326, arcs: 0x12b886, entry_lines: 0x1ad940, exit_lines: 0x3373ff,
};

export function hex(color) {
  return `#${color.toString(16).padStart(6, "0")}`;
}

// The box the camera frames: the part, i.e. the stock; without a stock outline, the CLs that are not
// rapids (a program's retracts and approach moves lie far above and beside the part).
export function partBox(stock, cls) {
  const box = stockBox(stock);
  if (box) return { min: [...box.min], max: [...box.max] };
  const cutting = { x: [], y: [], z: [] };
  for (let i = 0; cls && i < cls.x.length; i++) {
    if (cls.status[i] === "rapid") continue;
    for (const k of ["x", "y", "z"]) cutting[k].push(cls[k][i]);
  }
  const [min, max] = bounds(cutting.x.length ? cutting : cls, null);
  return { min, max };
}

// The screen rectangle [x0, y0, x1, y1] that holds the eight corners of `box`, each placed on the
// screen by `project([x, y, z]) -> [sx, sy]`.
export function screenBox(box, project) {
  let [x0, y0, x1, y1] = [Infinity, Infinity, -Infinity, -Infinity];
  for (const x of [box.min[0], box.max[0]]) {
    for (const y of [box.min[1], box.max[1]]) {
      for (const z of [box.min[2], box.max[2]]) {
        const [sx, sy] = project([x, y, z]);
        [x0, y0, x1, y1] = [Math.min(x0, sx), Math.min(y0, sy), Math.max(x1, sx), Math.max(y1, sy)];
      }
    }
  }
  return [x0, y0, x1, y1];
}
