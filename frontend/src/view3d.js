// The 3D view of a job (three.js, Z up, mm): the in-process workpiece (ipw.stl, or the stock outline
// while there is none), the toolpath coloured by CL status, the tool at the chosen CL and its engaged
// arcs (from the slices table: machine angles at z_machine_mm), with a CL slider.

import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { STLLoader } from "three/addons/loaders/STLLoader.js";

import { api, blobURL, getJSON } from "./api.js";
import { h } from "./dom.js";
import { arcSpans, bounds, STATUS_COLORS, stockBox, toolShape } from "./geometry.js";
import { number } from "./format.js";

const BACKGROUND = 0xf4f6f8;
const ARC_COLOR = 0x12b886;

export class JobView {
  constructor(container, jobId) {
    this.jobId = jobId;
    this.container = container;
    this.canvas = h("canvas", { id: "view3d", class: "view3d", width: 900, height: 560 });
    this.slider = h("input", { type: "range", id: "cl-slider", min: "0", max: "0", value: "0", step: "1" });
    this.info = h("div", { class: "cl-info small", id: "cl-info" });
    this.polar = h("img", { class: "plot polar", alt: "polar plot of the CL", id: "plot-polar" });
    container.append(this.canvas,
      h("label", { class: "slider" }, "CL ", this.slider),
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
    this.toolGroup = new THREE.Group();
    this.arcGroup = new THREE.Group();
    this.scene.add(this.toolGroup, this.arcGroup);
    this.urls = [];
    this.request = 0;
    let timer = null;
    this.slider.addEventListener("input", () => {
      clearTimeout(timer);
      timer = setTimeout(() => this.select(Number(this.slider.value)), 60);
    });
  }

  async load() {
    const scene = await getJSON(`/api/jobs/${this.jobId}/scene`);
    this.data = scene;
    const cls = scene.cls;
    const n = cls.cl.length;
    if (!n) throw new Error("no CLs in the results yet");
    const [lo, hi] = bounds(cls, scene.stock);
    await this.addWorkpiece(scene);
    this.addToolpath(cls);
    this.frame(lo, hi);
    this.slider.max = String(n - 1);
    // start at the first engaged CL: there is something to see there
    const first = cls.status.indexOf("engaged");
    this.slider.value = String(first >= 0 ? first : 0);
    await this.select(Number(this.slider.value));
  }

  async addWorkpiece(scene) {
    if (scene.ipw) {
      const r = await api(`/api/jobs/${this.jobId}/files/${scene.ipw}`);
      const geom = new STLLoader().parse(await r.arrayBuffer());
      geom.computeVertexNormals();
      const mesh = new THREE.Mesh(geom, new THREE.MeshStandardMaterial({ color: 0xb8c2cc, metalness: 0.3, roughness: 0.55 }));
      mesh.name = "ipw";
      this.scene.add(mesh);
      return;
    }
    const box = stockBox(scene.stock);
    if (!box) return;
    const size = box.max.map((v, k) => v - box.min[k]);
    const geom = new THREE.BoxGeometry(...size);
    const center = box.min.map((v, k) => v + size[k] / 2);
    const mesh = new THREE.Mesh(geom, new THREE.MeshStandardMaterial({ color: 0xb8c2cc, transparent: true, opacity: 0.45 }));
    mesh.position.set(...center);
    mesh.name = "stock";
    const edges = new THREE.LineSegments(new THREE.EdgesGeometry(geom), new THREE.LineBasicMaterial({ color: 0x495057 }));
    edges.position.copy(mesh.position);
    this.scene.add(mesh, edges);
  }

  addToolpath(cls) {
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
    const line = new THREE.Line(geom, new THREE.LineBasicMaterial({ vertexColors: true }));
    line.name = "toolpath";
    this.scene.add(line);
  }

  frame(lo, hi) {
    const center = new THREE.Vector3((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2);
    const size = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1);
    this.camera.position.set(center.x + 0.6 * size, center.y - 1.3 * size, center.z + 0.9 * size);
    this.camera.near = size / 1000;
    this.camera.far = size * 100;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(center);
    this.controls.update();
  }

  async select(index) {
    const cls = this.data.cls;
    const cl = cls.cl[index];
    const ticket = ++this.request; // a slow answer for an earlier CL must not overwrite a later one
    const detail = await getJSON(`/api/jobs/${this.jobId}/cls/${cl}`);
    if (ticket !== this.request) return;
    const row = detail.cl;
    this.placeTool(row, this.data.tools[row.tool]);
    this.placeArcs(row, detail.slices);
    this.info.textContent = `CL ${cl} · ${row.operation || "–"} · ${String(row.file).split(/[\\/]/).pop()}:${row.line} · ${row.status}`
      + ` · ae ${number(row.ae_mm)} mm · ap ${number(row.ap_mm)} mm · ${detail.slices.length} engaged arc(s)`;
    this.draw();
    this.canvas.dataset.cl = String(cl);
    this.canvas.dataset.arcs = String(detail.slices.length);
    this.canvas.dataset.ready = "1";
    blobURL(`/api/jobs/${this.jobId}/plots/polar?cl=${cl}`).then((u) => {
      if (ticket !== this.request) return URL.revokeObjectURL(u);
      this.urls.push(u);
      this.polar.src = u;
    }).catch(() => {});
  }

  placeTool(row, tool) {
    this.toolGroup.clear();
    const { radius, length, ball } = toolShape(tool);
    const mat = new THREE.MeshStandardMaterial({ color: 0xfab005, transparent: true, opacity: 0.55, metalness: 0.2 });
    const bottom = ball ? radius : 0;
    const body = new THREE.Mesh(new THREE.CylinderGeometry(radius, radius, length - bottom, 48, 1), mat);
    body.rotation.x = Math.PI / 2; // three.js cylinders stand along Y; tools along Z
    body.position.set(row.x, row.y, row.z + bottom + (length - bottom) / 2);
    this.toolGroup.add(body);
    if (ball) {
      const tip = new THREE.Mesh(new THREE.SphereGeometry(radius, 48, 24), mat);
      tip.position.set(row.x, row.y, row.z + radius);
      this.toolGroup.add(tip);
    }
    this.toolGroup.name = "tool";
  }

  placeArcs(row, slices) {
    this.arcGroup.clear();
    // drawn over everything: the arcs lie on the contact surface, inside the workpiece's outline
    const mat = new THREE.MeshBasicMaterial({ color: ARC_COLOR, side: THREE.DoubleSide, depthTest: false });
    for (const s of arcSpans(slices)) {
      const width = Math.max(0.3, 0.2 * s.radius);
      // RingGeometry lies in XY with angles counter-clockwise from +X: exactly machine angles
      const ring = new THREE.Mesh(new THREE.RingGeometry(s.radius, s.radius + width, 64, 1, s.start, s.length), mat);
      ring.position.set(row.x, row.y, s.z);
      ring.renderOrder = 10;
      this.arcGroup.add(ring);
    }
  }

  draw() {
    this.renderer.render(this.scene, this.camera);
  }

  dispose() {
    this.controls.dispose();
    this.renderer.dispose();
    this.urls.forEach((u) => URL.revokeObjectURL(u));
  }
}
