// The 3D view of a job (three.js, Z up, mm) at the CL the slider picks: the workpiece *after* that
// CL (a GLB from /api/jobs/<id>/scene?cl=N, which the service replays on a worker and caches: its
// nodes ipw, contact_faces, tool, entry/exit lines and engaged arcs), the toolpath coloured by CL
// status, the tool at the CL and its engaged arcs (from the slices table: machine angles at
// z_machine_mm), axes at the stock's corner and a legend with a switch per layer. The camera is
// framed once on the part (the stock), so that moving the slider changes the picture, not the view.
// While the job runs, `refresh()` adds the newly finished CLs and follows the latest one until the
// user moves the slider.

import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";

import { api, getJSON } from "./api.js";
import { h } from "./dom.js";
import { arcSpans, hex, LAYER_COLORS, partBox, screenBox, STATUS_COLORS, stockBox, toolShape } from "./geometry.js";
import { number } from "./format.js";

const BACKGROUND = 0xf4f6f8;
const POLL_MS = 400; // asking again for a scene whose workpiece is being computed

// legend rows: [layer key, label, colour]; the layer keys are the GLB's node names where they exist
const LAYERS = [
  ["ipw", "Workpiece after the CL", LAYER_COLORS.ipw],
  ["contact_faces", "Contact faces", LAYER_COLORS.contact_faces],
  ["tool", "Tool at the CL", LAYER_COLORS.tool],
  ["arcs", "Engaged arcs", LAYER_COLORS.arcs],
  ["lines", "Entry / exit lines", LAYER_COLORS.entry_lines],
  ["toolpath", "Toolpath", null],
  ["axes", "Axes (X red, Y green, Z blue)", null],
];

export class JobView {
  constructor(container, jobId) {
    this.jobId = jobId;
    this.canvas = h("canvas", { id: "view3d", class: "view3d", width: 900, height: 560 });
    this.slider = h("input", { type: "range", id: "cl-slider", min: "0", max: "0", value: "0", step: "1",
      "aria-label": "CL" });
    this.clLabel = h("span", { id: "cl-number", class: "cl-number" }, "–");
    this.status = h("span", { id: "mesh-state", class: "muted small" });
    this.info = h("div", { class: "cl-info small", id: "cl-info" });
    this.polar = h("img", { class: "plot polar", alt: "polar plot of the CL", id: "plot-polar", hidden: true });
    this.legend = h("div", { class: "legend small", id: "view-legend" });
    container.append(
      h("div", { class: "view-row" }, this.canvas, this.legend),
      h("label", { class: "slider" }, "CL ", this.slider, this.clLabel),
      this.status,
      h("div", { class: "cl-panel" }, this.info, this.polar));
    this.renderer = new THREE.WebGLRenderer({ canvas: this.canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(1);
    this.renderer.setClearColor(BACKGROUND);
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(40, this.canvas.width / this.canvas.height, 0.1, 10000);
    this.camera.up.set(0, 0, 1);
    this.controls = new OrbitControls(this.camera, this.canvas);
    this.controls.addEventListener("change", () => this.draw());
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 1.6));
    const sun = new THREE.DirectionalLight(0xffffff, 1.6);
    sun.position.set(1, -2, 3);
    this.scene.add(sun);
    // one group per legend layer; the GLB's nodes go into theirs
    this.groups = Object.fromEntries(LAYERS.map(([key]) => [key, new THREE.Group()]));
    for (const [key, g] of Object.entries(this.groups)) {
      g.name = key;
      this.scene.add(g);
    }
    this.stockOutline = new THREE.Group(); // shown until the first workpiece mesh arrives
    this.scene.add(this.stockOutline);
    this.urls = [];
    this.request = 0;
    this.following = true; // a running job: show the latest finished CL until the user picks one
    this.meshPending = null; // the CL whose workpiece is being computed
    this.disposed = false;
    let timer = null;
    this.slider.addEventListener("input", () => {
      this.following = false;
      this.clLabel.textContent = String(this.clAt(Number(this.slider.value)));
      clearTimeout(timer);
      timer = setTimeout(() => this.select(Number(this.slider.value)), 80);
    });
    this.buildLegend();
  }

  buildLegend() {
    const rows = LAYERS.map(([key, label, color]) => h("label", { class: "layer" },
      h("input", { type: "checkbox", checked: true, dataset: { layer: key }, onchange: (e) => {
        this.groups[key].visible = e.target.checked;
        this.draw();
      } }),
      color === null ? null : h("span", { class: "swatch", style: `background:${hex(color)}` }), ` ${label}`));
    const paths = Object.entries(STATUS_COLORS).map(([status, color]) => h("div", { class: "path-status" },
      h("span", { class: "swatch line", style: `background:${hex(color)}` }), ` ${status}`));
    this.legend.append(h("strong", {}, "Layers"), ...rows, h("strong", {}, "Toolpath by CL status"), ...paths);
  }

  clAt(index) {
    return this.data.cls.cl[index];
  }

  async load() {
    await this.loadCls();
    const box = partBox(this.data.stock, this.data.cls);
    this.addStockOutline();
    this.addAxes(box);
    this.frame(box.min, box.max);
    this.partBox = box;
    const n = this.data.cls.cl.length;
    this.slider.value = String(n - 1); // the latest finished CL: the final workpiece of a done job
    await this.select(n - 1);
  }

  async loadCls() {
    const scene = await getJSON(`/api/jobs/${this.jobId}/scene`);
    if (!scene.cls.cl.length) throw new Error("no CLs in the results yet");
    this.data = scene;
    this.slider.max = String(scene.cls.cl.length - 1);
    this.addToolpath(scene.cls);
  }

  // A running job: take the CLs finished since the last call; follow the latest unless the user moved.
  async refresh() {
    const before = this.data.cls.cl.length;
    await this.loadCls();
    const n = this.data.cls.cl.length;
    if (n !== before && this.following) {
      this.slider.value = String(n - 1);
      // one replay at a time: ask for the latest CL's workpiece once the last one asked for is shown
      if (this.meshPending === null) await this.select(n - 1);
      else await this.showLatest(n - 1);
    } else {
      this.draw();
    }
  }

  addStockOutline() {
    const box = stockBox(this.data.stock);
    if (!box) return;
    const size = box.max.map((v, k) => v - box.min[k]);
    const geom = new THREE.BoxGeometry(...size);
    const edges = new THREE.LineSegments(new THREE.EdgesGeometry(geom), new THREE.LineBasicMaterial({ color: 0x495057 }));
    edges.position.set(...box.min.map((v, k) => v + size[k] / 2));
    this.stockOutline.add(edges);
  }

  addAxes(box) {
    const size = Math.max(...box.max.map((v, k) => v - box.min[k]), 1);
    const axes = new THREE.AxesHelper(0.3 * size);
    axes.position.set(...box.min);
    axes.material.depthTest = false;
    axes.renderOrder = 20;
    this.groups.axes.add(axes);
  }

  addToolpath(cls) {
    this.groups.toolpath.clear();
    const pos = [];
    const col = [];
    const c = new THREE.Color();
    for (let i = 0; i < cls.x.length; i++) {
      pos.push(cls.x[i], cls.y[i], cls.z[i]);
      c.setHex(STATUS_COLORS[cls.status[i]] ?? 0x000000);
      col.push(c.r, c.g, c.b);
    }
    const geom = new THREE.BufferGeometry();
    geom.setAttribute("position", new THREE.Float32BufferAttribute(pos, 3));
    geom.setAttribute("color", new THREE.Float32BufferAttribute(col, 3));
    this.groups.toolpath.add(new THREE.Line(geom, new THREE.LineBasicMaterial({ vertexColors: true })));
  }

  frame(lo, hi) {
    const center = new THREE.Vector3((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2);
    const radius = 0.5 * Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) || 1;
    // the bounding sphere just inside the narrower field of view, seen from the front right, above
    const fov = THREE.MathUtils.degToRad(this.camera.fov) / 2;
    const narrow = Math.min(fov, Math.atan(Math.tan(fov) * this.camera.aspect));
    const dist = (1.1 * radius) / Math.sin(narrow);
    const dir = new THREE.Vector3(0.45, -0.75, 0.55).normalize();
    this.camera.position.copy(center).addScaledVector(dir, dist);
    this.camera.near = dist / 100;
    this.camera.far = dist * 20;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(center);
    this.controls.update();
  }

  // Show CL `index`: its tool, arcs and info as soon as the service answers; the workpiece after it
  // when its mesh is ready (polled in the background while a worker replays the job to it).
  async select(index) {
    const cl = this.clAt(index);
    const ticket = ++this.request; // a slow answer for an earlier CL must not overwrite a later one
    this.clLabel.textContent = String(cl);
    const s = await this.askScene(cl);
    if (ticket !== this.request || this.disposed) return;
    this.showCl(s);
    if (s.state === "pending") this.pollMesh(cl, ticket);
    else await this.meshAnswer(s, ticket);
  }

  async askScene(cl) {
    return (await api(`/api/jobs/${this.jobId}/scene?cl=${cl}`)).json();
  }

  async pollMesh(cl, ticket) {
    this.meshPending = cl;
    this.status.textContent = `computing the workpiece after CL ${cl}…`;
    try {
      for (;;) {
        await new Promise((res) => setTimeout(res, POLL_MS));
        if (ticket !== this.request || this.disposed) return;
        const s = await this.askScene(cl);
        if (ticket !== this.request || this.disposed) return;
        if (s.state !== "pending") {
          await this.meshAnswer(s, ticket);
          return;
        }
      }
    } catch (err) {
      if (ticket === this.request) this.status.textContent = `workpiece after CL ${cl}: ${err.message}`;
    } finally {
      if (this.meshPending === cl) this.meshPending = null;
    }
  }

  async meshAnswer(s, ticket) {
    if (s.state !== "ready") {
      this.status.textContent = `workpiece after CL ${s.cl}: ${s.message}`;
      return;
    }
    const glb = await (await api(s.mesh)).arrayBuffer();
    if (ticket !== this.request || this.disposed) return;
    await this.showWorkpiece(glb, s.cl);
    const shown = this.canvas.dataset.cl;
    this.status.textContent = shown === String(s.cl) ? "" : `the workpiece is shown after CL ${s.cl}; later ones are being computed`;
  }

  // A running job's latest CL while the workpiece of an earlier one is still being computed: its tool
  // and info from the results (no replay asked for), the workpiece stays the one being computed.
  async showLatest(index) {
    const cl = this.clAt(index);
    const d = await getJSON(`/api/jobs/${this.jobId}/cls/${cl}`);
    if (this.disposed || !this.following) return;
    const row = d.cl;
    const spec = this.data.tools[row.tool] || {};
    this.clLabel.textContent = String(cl);
    this.showCl({ cl, total: this.total, contact: row, slices: d.slices,
      tool: { ...spec, position_mm: [row.x, row.y, row.z] } });
  }

  // The tool, arcs and info of a CL (from the results: known at once, before the mesh).
  showCl(s) {
    const row = s.contact;
    this.total = s.total;
    // the exact tool of the CL's GLB, once shown, stays; until then a cylinder (or ball) stands in
    const exact = this.groups.tool.children.some((o) => o.name === "glb-tool" && o.userData.cl === s.cl);
    if (!exact) this.placeTool(s.tool);
    this.placeArcs(s.slices, s.tool.position_mm);
    this.info.textContent = `CL ${s.cl} of ${s.total} · ${row.operation || "–"} · ${String(row.file).split(/[\\/]/).pop()}:${row.line}`
      + ` · ${row.status} · ae ${number(row.ae_mm)} mm · ap ${number(row.ap_mm)} mm · ${s.slices.length} engaged arc(s)`;
    this.draw();
    this.canvas.dataset.cl = String(s.cl);
    this.canvas.dataset.arcs = String(s.slices.length);
    this.canvas.dataset.ready = "1";
    this.showPolar(s.cl);
  }

  showPolar(cl) {
    const ticket = this.request;
    api(`/api/jobs/${this.jobId}/plots/polar?cl=${cl}`).then((r) => r.blob()).then((b) => {
      if (ticket !== this.request) return;
      const u = URL.createObjectURL(b);
      this.urls.push(u);
      this.polar.src = u;
      this.polar.hidden = false;
    }).catch(() => {});
  }

  async showWorkpiece(glb, cl) {
    const gltf = await new GLTFLoader().parseAsync(glb, "");
    const frame = gltf.scene.getObjectByName("machine_frame");
    if (!frame) throw new Error("the scene has no machine_frame node");
    // the GLB's machine_frame node turns mm / Z up into glTF's m / Y up: this view is mm / Z up
    frame.matrix.identity();
    frame.position.set(0, 0, 0);
    frame.quaternion.identity();
    frame.scale.set(1, 1, 1);
    const put = (node, group) => {
      const obj = frame.getObjectByName(node);
      if (obj) group.add(obj);
      return obj;
    };
    this.groups.ipw.clear();
    this.groups.contact_faces.clear();
    this.groups.lines.clear();
    put("ipw", this.groups.ipw);
    put("contact_faces", this.groups.contact_faces);
    for (const name of ["entry_lines", "exit_lines"]) {
      const obj = put(name, this.groups.lines);
      if (obj) obj.traverse((o) => { if (o.material) o.material.depthTest = false; o.renderOrder = 10; });
    }
    this.groups.tool.clear();
    const tool = put("tool", this.groups.tool);
    if (tool) {
      tool.name = "glb-tool";
      tool.userData.cl = cl;
      tool.traverse((o) => { if (o.material) o.material.depthWrite = false; o.renderOrder = 5; });
    }
    this.stockOutline.visible = false;
    const extras = gltf.scene.userData.fusioncut || {};
    this.canvas.dataset.mesh = String(cl);
    this.canvas.dataset.volume = String(extras.ipw_volume_mm3 ?? "");
    this.draw();
  }

  placeTool(tool) {
    this.groups.tool.clear();
    const { radius, length, ball } = toolShape(tool);
    const [x, y, z] = tool.position_mm;
    const mat = new THREE.MeshStandardMaterial({ color: LAYER_COLORS.tool, transparent: true, opacity: 0.55, metalness: 0.2 });
    const bottom = ball ? radius : 0;
    const body = new THREE.Mesh(new THREE.CylinderGeometry(radius, radius, length - bottom, 48, 1), mat);
    body.rotation.x = Math.PI / 2; // three.js cylinders stand along Y; tools along Z
    body.position.set(x, y, z + bottom + (length - bottom) / 2);
    this.groups.tool.add(body);
    if (ball) {
      const tip = new THREE.Mesh(new THREE.SphereGeometry(radius, 48, 24), mat);
      tip.position.set(x, y, z + radius);
      this.groups.tool.add(tip);
    }
  }

  placeArcs(slices, [x, y]) {
    const group = this.groups.arcs;
    group.clear();
    // drawn over everything: the arcs lie on the contact surface, inside the workpiece's outline
    const mat = new THREE.MeshBasicMaterial({ color: LAYER_COLORS.arcs, side: THREE.DoubleSide, depthTest: false });
    for (const s of arcSpans(slices)) {
      const width = Math.max(0.3, 0.2 * s.radius);
      // RingGeometry lies in XY with angles counter-clockwise from +X: exactly machine angles
      const ring = new THREE.Mesh(new THREE.RingGeometry(s.radius, s.radius + width, 64, 1, s.start, s.length), mat);
      ring.position.set(x, y, s.z);
      ring.renderOrder = 10;
      group.add(ring);
    }
  }

  // The part's box on the canvas in CSS pixels from its top left corner (what a screenshot of the
  // canvas shows), for tests and tools.
  partOnScreen() {
    const w = this.canvas.clientWidth || this.canvas.width;
    const ht = this.canvas.clientHeight || this.canvas.height;
    return screenBox(this.partBox, (p) => {
      const v = new THREE.Vector3(...p).project(this.camera);
      return [(v.x + 1) / 2 * w, (1 - v.y) / 2 * ht];
    });
  }

  draw() {
    this.renderer.render(this.scene, this.camera);
    if (this.partBox) this.canvas.dataset.partBox = this.partOnScreen().map((v) => Math.round(v)).join(",");
  }

  dispose() {
    this.disposed = true;
    this.controls.dispose();
    this.renderer.dispose();
    this.urls.forEach((u) => URL.revokeObjectURL(u));
  }
}
