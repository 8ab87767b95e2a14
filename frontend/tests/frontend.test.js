// Unit tests of the front end's pure modules: `npm test` (node --test), also run by pytest.
import assert from "node:assert/strict";
import { test } from "node:test";

import { SSEParser } from "../src/sse.js";
import { bytes, duration, percent, progressLabel } from "../src/format.js";
import { arcPoints, arcSpans, bounds, hex, partBox, screenBox, stockBox, toolShape } from "../src/geometry.js";

test("SSE events split over chunks, with CRLF, comments and multi-line data", () => {
  const p = new SSEParser();
  assert.deepEqual(p.feed("retry: 2000\n\nevent: status\ndata: {\"a\""), []);
  assert.deepEqual(p.feed(":1}\n\n: keep-alive\n\n"), [{ event: "status", data: "{\"a\":1}" }]);
  assert.deepEqual(p.feed("data: x\r\ndata: y\r"), []);
  assert.deepEqual(p.feed("\n\r\n"), [{ event: "message", data: "x\ny" }]);
});

test("percent never shows 100% before the end", () => {
  assert.equal(percent(0), "0%");
  assert.equal(percent(0.996), "99%");
  assert.equal(percent(1), "100%");
  assert.equal(percent(NaN), "0%");
});

test("durations and sizes", () => {
  assert.equal(duration(null), "–");
  assert.equal(duration(42.4), "42 s");
  assert.equal(duration(125), "2 min 05 s");
  assert.equal(duration(7260), "2 h 01 min");
  assert.equal(bytes(512), "512 B");
  assert.equal(bytes(1536), "1.5 KiB");
});

test("engaged arcs keep machine angles counter-clockwise from +X", () => {
  const spans = arcSpans([
    { z_machine_mm: -1.5, radius_mm: 3, entry_machine_deg: 90, exit_machine_deg: 270 },
    { z_machine_mm: -0.5, radius_mm: 3, entry_machine_deg: 350, exit_machine_deg: 370 },
    { z_machine_mm: 0, radius_mm: 3, entry_machine_deg: 10, exit_machine_deg: 10 },
  ]);
  assert.equal(spans.length, 2); // the empty arc is dropped
  const pts = arcPoints(spans[0], 10, 20);
  // a half circle on the -X side of the centre (x = 10 - 3 at its middle), from +Y to -Y
  assert.ok(Math.abs(pts[0][0] - 10) < 1e-9 && Math.abs(pts[0][1] - 23) < 1e-9);
  assert.ok(Math.abs(pts.at(-1)[1] - 17) < 1e-9);
  const mid = pts[Math.floor(pts.length / 2)];
  assert.ok(Math.abs(mid[0] - 7) < 1e-6 && mid[2] === -1.5);
  // the arc across +X wraps through 0 degrees
  const wrap = arcPoints(spans[1], 0, 0);
  assert.ok(wrap.every((p) => p[0] > 2.9));
});

test("tools, stock outlines and bounds", () => {
  assert.deepEqual(toolShape({ kind: "ball", diameter_mm: 6, flute_length_mm: 15 }), { radius: 3, length: 15, ball: true });
  assert.deepEqual(stockBox({ kind: "cylinder", base_center: [0, 0, -10], radius: 5, height: 10 }),
    { min: [-5, -5, -10], max: [5, 5, 0] });
  const b = bounds({ x: [0, 40], y: [-5, 5], z: [5, -1] }, { kind: "box", min: [0, 0, -5], max: [30, 20, 0] });
  assert.deepEqual(b, [[0, -5, -5], [40, 20, 5]]);
});

test("a running job that has done every CL is still writing, not at 100 %", () => {
  const job = (state, done, total) => ({ state, progress: { done, total, fraction: total ? done / total : 0 } });
  assert.equal(progressLabel(job("running", 10, 10)), "10 / 10 CLs · writing results");
  assert.equal(progressLabel(job("running", 5, 10)), "5 / 10 CLs · 50%");
  assert.equal(progressLabel(job("done", 10, 10)), "10 / 10 CLs · 100%");
  assert.equal(progressLabel(job("queued", 0, 10)), "0 / 10 CLs · 0%");
});

test("the view frames the part: the stock, else the CLs that are not rapids", () => {
  const cls = { x: [0, 10, 40, -100], y: [0, 5, 20, 0], z: [50, -1, -2, 50], status: ["rapid", "engaged", "air", "rapid"] };
  assert.deepEqual(partBox({ kind: "box", min: [0, 0, -5], max: [30, 20, 0] }, cls), { min: [0, 0, -5], max: [30, 20, 0] });
  // no stock outline (a STEP stock): the retract at z 50 and the approach at x -100 are left out
  assert.deepEqual(partBox(null, cls), { min: [10, 5, -2], max: [40, 20, -1] });
  // only rapids: all of them, rather than nothing
  assert.deepEqual(partBox(null, { x: [1, 2], y: [3, 4], z: [5, 6], status: ["rapid", "rapid"] }),
    { min: [1, 3, 5], max: [2, 4, 6] });
});

test("the part's screen box holds its eight projected corners", () => {
  const box = { min: [0, 0, -5], max: [30, 20, 0] };
  // an oblique projection: x right, y up the screen at half scale, z up
  const r = screenBox(box, ([x, y, z]) => [x + 0.5 * y, -z - 0.5 * y]);
  assert.deepEqual(r, [0, -10, 40, 5]);
  assert.equal(hex(0x09a3ab), "#09a3ab");
});
