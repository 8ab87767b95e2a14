"""3D scene of one CL: a glTF binary (GLB) file and a self-contained HTML page that shows it.

The GLB holds, each as a named node: ``ipw`` (the workpiece, grey), ``contact_faces`` (its faces that
touch the tool, red), ``tool`` (the tool at the CL, gold, semi-transparent), and the line sets
``entry_lines`` (green), ``exit_lines`` (blue) and ``engaged_arcs`` (orange), see
:class:`fusioncut.engines.brep.export.EngagementLines`. They hang under one node, ``machine_frame``,
whose transform takes the machine frame (mm, Z up) to glTF's (metres, Y up): any glTF viewer shows
the part upright and at its true size, while the vertex data stay in machine mm. What is known
about the CL is in the scene's ``extras["fusioncut"]``.

The HTML page inlines three.js (module, OrbitControls, GLTFLoader) as ``data:`` URLs of an import
map and the GLB as base64, so it opens from disk with no network and no server. three.js is read
at run time from the front end's npm packages (``frontend/node_modules/three``, or the folder named
by the environment variable ``FUSIONCUT_THREE_DIR``); it is not part of this repository.
"""
from __future__ import annotations

import base64
import html
import json
import os
import posixpath
import re
import struct
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

import fusioncut
from fusioncut.errors import FusionCutError, InputError

if TYPE_CHECKING:  # the scene is plain arrays; the kernel is needed only by who builds it
    from fusioncut.engines.brep.export import CLScene

ROOT_NODE = "machine_frame"

# name -> (label in the legend, RGBA 0..1); also the order of the legend
LAYERS: dict[str, tuple[str, tuple[float, float, float, float]]] = {
    "ipw": ("Workpiece (IPW)", (0.62, 0.64, 0.67, 1.0)),
    "tool": ("Tool at the CL", (0.90, 0.70, 0.15, 0.40)),
    "contact_faces": ("Contact faces", (0.85, 0.08, 0.08, 1.0)),
    "entry_lines": ("Entry (tooth enters)", (0.10, 0.85, 0.25, 1.0)),
    "exit_lines": ("Exit (tooth leaves)", (0.20, 0.45, 1.00, 1.0)),
    "engaged_arcs": ("Engaged arcs per slice", (1.00, 0.55, 0.00, 1.0)),
}
LINE_LAYERS = ("entry_lines", "exit_lines", "engaged_arcs")
BACKGROUND = "#2b3038"

# the machine frame (mm, Z up) in glTF's frame (m, Y up): x -> x, y -> -z, z -> y, scaled by 1/1000
MACHINE_TO_GLTF = np.array([[1e-3, 0, 0, 0], [0, 0, 1e-3, 0], [0, -1e-3, 0, 0], [0, 0, 0, 1.0]])

THREE_ENV = "FUSIONCUT_THREE_DIR"
# bare specifiers of the page's import map -> files in the three.js package
THREE_ENTRIES = {
    "three": "build/three.module.min.js",
    "three/addons/controls/OrbitControls.js": "examples/jsm/controls/OrbitControls.js",
    "three/addons/loaders/GLTFLoader.js": "examples/jsm/loaders/GLTFLoader.js",
    "three/addons/lines/LineSegments2.js": "examples/jsm/lines/LineSegments2.js",
    "three/addons/lines/LineSegmentsGeometry.js": "examples/jsm/lines/LineSegmentsGeometry.js",
    "three/addons/lines/LineMaterial.js": "examples/jsm/lines/LineMaterial.js",
}
# widths (CSS pixels) of the line layers in the page: WebGL's own lines are always one pixel wide
LINE_WIDTHS = {"entry_lines": 3.0, "exit_lines": 3.0, "engaged_arcs": 1.5}


# -- GLB --------------------------------------------------------------------------------------------


def _linear(rgba: tuple[float, ...]) -> list[float]:
    """sRGB colour (what the legend shows) -> glTF's linear baseColorFactor; alpha unchanged."""
    lin = [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in rgba[:3]]
    return [*lin, rgba[3]]


def _material(name: str):
    from trimesh.visual.material import PBRMaterial

    rgba = LAYERS[name][1]
    return PBRMaterial(name=name, baseColorFactor=_linear(rgba), metallicFactor=0.0,
                       roughnessFactor=0.65, alphaMode="BLEND" if rgba[3] < 1 else "OPAQUE", doubleSided=False)


def _trimesh(name: str, mesh):
    import trimesh
    from trimesh.visual import TextureVisuals

    kwargs = {"vertex_normals": mesh.normals} if mesh.normals is not None else {}
    # process=False: keep each B-Rep face's own vertices so the exact normals give sharp edges
    tm = trimesh.Trimesh(mesh.vertices, mesh.triangles, process=False, **kwargs)
    tm.visual = TextureVisuals(material=_material(name))
    return tm


def _path(segments: np.ndarray):
    from trimesh.path import Path3D
    from trimesh.path.entities import Line

    verts = np.asarray(segments, dtype=float).reshape(-1, 3)
    return Path3D(entities=[Line([2 * k, 2 * k + 1]) for k in range(len(segments))], vertices=verts, process=False)


def scene_extras(scene: CLScene) -> dict[str, Any]:
    """What the GLB stores about the CL (``extras["fusioncut"]``): the CL info and the suggested view."""
    center, radius = scene.focus
    return {**scene.info, "focus_center_mm": list(center), "focus_radius_mm": radius,
            "view_direction": list(scene.view_direction),
            "layers": {k: {"label": v[0], "rgba": list(v[1])} for k, v in LAYERS.items()}}


def _set_line_materials(tree: dict) -> None:
    """trimesh writes every line set with one white material: give each its legend colour."""
    materials = tree.setdefault("materials", [])
    for mesh in tree.get("meshes", []):
        name = mesh.get("name")
        if name not in LINE_LAYERS:
            continue
        materials.append({"name": name, "pbrMetallicRoughness": {
            "baseColorFactor": _linear(LAYERS[name][1]), "metallicFactor": 0.0, "roughnessFactor": 1.0}})
        for prim in mesh["primitives"]:
            prim["material"] = len(materials) - 1


def scene_glb(scene: CLScene) -> bytes:
    """The GLB bytes of ``scene`` (see the module docstring for nodes, colours and frames)."""
    import trimesh
    from trimesh.exchange.gltf import export_glb

    ts = trimesh.Scene()
    ts.graph.update(frame_from=ts.graph.base_frame, frame_to=ROOT_NODE, matrix=MACHINE_TO_GLTF)
    parts: list[tuple[str, Any]] = []
    for name, mesh in (("ipw", scene.ipw), ("contact_faces", scene.contact), ("tool", scene.tool)):
        if not mesh.is_empty:
            parts.append((name, _trimesh(name, mesh)))
    for name, segs in zip(LINE_LAYERS, (scene.lines.entry, scene.lines.exit, scene.lines.arcs)):
        if len(segs):
            parts.append((name, _path(segs)))
    for name, geom in parts:
        ts.add_geometry(geom, node_name=name, geom_name=name, parent_node_name=ROOT_NODE)
    ts.metadata["fusioncut"] = scene_extras(scene)
    return export_glb(ts, include_normals=True, tree_postprocessor=_set_line_materials)


def write_glb(scene: CLScene, path: str | Path) -> Path:
    path = Path(path)
    path.write_bytes(scene_glb(scene))
    return path


def glb_json(glb: bytes) -> dict:
    """The JSON chunk of a GLB file (its header: nodes, meshes, materials, extras)."""
    if len(glb) < 20 or glb[:4] != b"glTF":
        raise InputError("not a glTF binary (GLB) file")
    (length,) = struct.unpack_from("<I", glb, 12)
    if glb[16:20] != b"JSON":
        raise InputError("GLB file without a JSON chunk")
    return json.loads(glb[20:20 + length])


# -- three.js for the page --------------------------------------------------------------------------


def three_dir() -> Path:
    """The three.js package folder: ``$FUSIONCUT_THREE_DIR`` or ``frontend/node_modules/three``."""
    env = os.environ.get(THREE_ENV)
    folder = Path(env) if env else Path(fusioncut.__file__).resolve().parents[1] / "frontend" / "node_modules" / "three"
    missing = [rel for rel in THREE_ENTRIES.values() if not (folder / rel).is_file()]
    if missing:
        how = (f"{THREE_ENV} names a folder without it" if env else
               "install the front end's packages: run `npm ci` in frontend/ "
               f"(or set {THREE_ENV} to a three.js package folder)")
        raise FusionCutError(f"three.js not found ({folder / missing[0]} is missing): {how}")
    return folder


# a static import or re-export with a relative specifier: `from "./x.js"`, `import "../y.js"`
_RELATIVE_IMPORT = re.compile(r"""(\bfrom\s*|\bimport\s*)(['"])(\.{1,2}/[^'"\s]+)\2""")
# the specifier of an import statement in readable (not minified) source: it ends a line that starts
# the statement (`import ... from "x";`) or closes its braces (`} from "x";`)
_IMPORT_LINE = re.compile(r"""^(?:import|export|\})[^\n]*?(?:\bfrom\s*|^import\s*)(['"])([^'"\s]+)\1\s*;?\s*$""",
                          re.MULTILINE)


@lru_cache(maxsize=4)
def _import_map(folder: str) -> dict[str, str]:
    """Import map of the page: bare specifier -> ``data:`` URL of the module's source.

    Relative imports inside the modules are rewritten to bare specifiers (a ``data:`` URL cannot be
    the base of a relative URL), pulling in the files they name, recursively.
    """
    root = Path(folder)
    keys = {rel: spec for spec, rel in THREE_ENTRIES.items()}
    sources: dict[str, str] = {}
    todo = list(THREE_ENTRIES.values())
    while todo:
        rel = todo.pop()
        if rel in sources:
            continue
        text = (root / rel).read_text(encoding="utf-8")

        def rewrite(m: re.Match, rel: str = rel) -> str:
            target = posixpath.normpath(posixpath.join(posixpath.dirname(rel), m.group(3)))
            if not (root / target).is_file():
                return m.group(0)  # not a module of the package (text in a comment): leave it
            keys.setdefault(target, f"fusioncut-three/{target}")
            todo.append(target)
            return f"{m.group(1)}{m.group(2)}{keys[target]}{m.group(2)}"

        sources[rel] = _RELATIVE_IMPORT.sub(rewrite, text)
    out = {}
    for rel, text in sources.items():
        for m in _IMPORT_LINE.finditer(text):
            if m.group(2) not in keys.values():
                raise FusionCutError(f"three.js module {rel} imports {m.group(2)!r}, which the page cannot inline")
        out[keys[rel]] = "data:text/javascript;base64," + base64.b64encode(text.encode("utf-8")).decode("ascii")
    return out


# -- the page ---------------------------------------------------------------------------------------


def _fmt(value: Any, unit: str = "", digits: int = 3) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.{digits}f}{unit}"
    if isinstance(value, (list, tuple)):
        return "(" + ", ".join(_fmt(v, "", digits) for v in value) + ")" + unit
    return f"{value}{unit}"


def _info_rows(info: dict) -> list[tuple[str, str]]:
    rows = [
        ("CL", _fmt(info.get("cl_index"))),
        ("source", _fmt(info.get("source"))),
        ("operation", _fmt(info.get("operation") or "–")),
        ("status", _fmt(info.get("status"))),
        ("tool", f"{info.get('tool', '–')} ({info.get('tool_kind', '?')}, Ø{_fmt(info.get('tool_diameter_mm'))} mm, "
                 f"{info.get('spindle', '?')})"),
        ("position", _fmt(info.get("position_mm"), " mm")),
        ("feed", _fmt(info.get("feed_mm_per_min"), " mm/min", 0)),
        ("feed angle", _fmt(info.get("feed_angle_deg"), "°", 1)),
        ("ae / ap", f"{_fmt(info.get('ae_mm'))} / {_fmt(info.get('ap_mm'))} mm"),
        ("engaged slices", _fmt(info.get("engaged_slices"))),
        ("removed", _fmt(info.get("removed_volume_mm3"), " mm³")),
        ("contact area", _fmt(info.get("contact_area_mm2"), " mm²")),
        ("IPW volume", _fmt(info.get("ipw_volume_mm3"), " mm³", 1)),
        ("mesh deflection", _fmt(info.get("mesh_deflection_mm"), " mm", 4)),
    ]
    if info.get("reason"):
        rows.append(("reason", str(info["reason"])))
    for w in info.get("warnings", []):
        rows.append(("warning", str(w)))
    return rows


def _json_script(obj: Any) -> str:
    # inside <script>, "</" would end the element: escape it (and keep the JSON valid)
    return json.dumps(obj, ensure_ascii=False).replace("</", "<\\/")


_PAGE = """<!doctype html>
<html lang="en" data-fusioncut-rendered="0">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="FusionCut">
<title>{title}</title>
<style>
html, body {{ margin: 0; height: 100%; overflow: hidden; background: {background};
  font: 13px/1.35 system-ui, -apple-system, "Segoe UI", sans-serif; color: #e9ecef; }}
#view {{ position: fixed; inset: 0; }}
.panel {{ position: fixed; background: rgba(18, 20, 24, 0.82); border-radius: 6px; padding: 8px 10px; }}
.panel h2 {{ font-size: 13px; margin: 0 0 4px; }}
#legend {{ left: 10px; top: 10px; }}
#legend label {{ display: block; white-space: nowrap; cursor: pointer; }}
.swatch {{ display: inline-block; width: 14px; height: 10px; margin: 0 6px 0 2px; border-radius: 2px;
  vertical-align: middle; }}
#info {{ right: 10px; top: 10px; max-width: 360px; font-size: 12px; }}
#info summary {{ font-weight: bold; cursor: pointer; }}
#info td {{ padding: 0 4px; vertical-align: top; }}
#info td:first-child {{ color: #9aa4ae; white-space: nowrap; }}
#help {{ left: 10px; bottom: 10px; color: #c3c9cf; }}
#help button {{ margin-left: 6px; }}
#error {{ left: 50%; top: 40%; transform: translateX(-50%); display: none; color: #ffb4b4; max-width: 60%; }}
body.bare .panel:not(#error) {{ display: none; }}
</style>
<script type="importmap">{import_map}</script>
</head>
<body>
<div id="view"></div>
<div id="legend" class="panel"><h2>{title}</h2>{legend}</div>
<details id="info" class="panel" open><summary>CL {cl}</summary><table>{rows}</table></details>
<div id="help" class="panel">drag: orbit · right-drag: pan · wheel: zoom
<button id="focus-cl" type="button">Focus CL</button><button id="fit-all" type="button">Fit all</button></div>
<div id="error" class="panel"></div>
<script type="application/json" id="fusioncut-layers">{layers}</script>
<script type="application/octet-stream" id="fusioncut-glb">{glb}</script>
<script type="module">
import * as THREE from 'three';
import {{ OrbitControls }} from 'three/addons/controls/OrbitControls.js';
import {{ GLTFLoader }} from 'three/addons/loaders/GLTFLoader.js';
import {{ LineSegments2 }} from 'three/addons/lines/LineSegments2.js';
import {{ LineSegmentsGeometry }} from 'three/addons/lines/LineSegmentsGeometry.js';
import {{ LineMaterial }} from 'three/addons/lines/LineMaterial.js';

const html = document.documentElement;
function fail(message) {{
  html.dataset.fusioncutError = message;
  const box = document.getElementById('error');
  box.textContent = 'Cannot show the 3D scene: ' + message;
  box.style.display = 'block';
}}
window.addEventListener('error', (e) => fail(String(e.message)));

function glbBytes() {{
  const text = atob(document.getElementById('fusioncut-glb').textContent.replace(/\\s+/g, ''));
  const bytes = new Uint8Array(text.length);
  for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
  return bytes.buffer;
}}

const layers = JSON.parse(document.getElementById('fusioncut-layers').textContent);
let renderer;
try {{
  renderer = new THREE.WebGLRenderer({{ antialias: true }});
}} catch (e) {{
  fail('WebGL is not available in this browser (' + (e.message || e) + ')');
}}
if (renderer) {{
  renderer.setPixelRatio(window.devicePixelRatio);
  renderer.setSize(window.innerWidth, window.innerHeight);
  document.getElementById('view').appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color('{background}');
  const camera = new THREE.PerspectiveCamera(40, window.innerWidth / window.innerHeight, 1e-4, 100);
  scene.add(camera);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x50555c, 1.6));
  // a light riding on the camera, a little above and to the left of it: every view is lit
  const head = new THREE.DirectionalLight(0xffffff, 2.2);
  head.position.set(-0.4, 0.6, 0);
  head.target.position.set(0, 0, -1);
  camera.add(head, head.target);
  const controls = new OrbitControls(camera, renderer.domElement);
  const render = () => renderer.render(scene, camera);
  controls.addEventListener('change', render);

  new GLTFLoader().parse(glbBytes(), '', (gltf) => {{
    const model = gltf.scene;
    scene.add(model);
    model.updateMatrixWorld(true);
    const info = model.userData.fusioncut || {{}};
    const frame = model.getObjectByName('{root}') || model;
    const byName = {{}};
    model.traverse((o) => {{ if (layers[o.name] && !byName[o.name]) byName[o.name] = o; }});
    for (const [name, obj] of Object.entries(byName)) {{
      const rgba = layers[name].rgba;
      const color = new THREE.Color().setRGB(rgba[0], rgba[1], rgba[2], THREE.SRGBColorSpace);
      if (obj.isLineSegments) {{
        // the lines lie on the exact tool surface, where the contact faces' facets are chords a
        // little outside it (seen from the axis): pull them towards the axis by twice the mesh
        // deflection so that they show in front of those faces, and the material still hides them
        const tip = info.position_mm, pull = 2 * (info.mesh_deflection_mm || 0.01) + 0.005;
        const xyz = obj.geometry.attributes.position.array;  // machine mm (the node's own frame)
        for (let i = 0; tip && i < xyz.length; i += 3) {{
          const dx = xyz[i] - tip[0], dy = xyz[i + 1] - tip[1], r = Math.hypot(dx, dy);
          if (r > pull) {{ xyz[i] = tip[0] + dx * (r - pull) / r; xyz[i + 1] = tip[1] + dy * (r - pull) / r; }}
        }}
        const material = new LineMaterial({{ color, linewidth: layers[name].width || 2, depthTest: false }});
        const wide = new LineSegments2(new LineSegmentsGeometry().fromLineSegments(obj), material);
        wide.name = name;
        wide.renderOrder = 10;
        wide.matrix.copy(obj.matrix);
        wide.matrix.decompose(wide.position, wide.quaternion, wide.scale);
        obj.parent.add(wide);
        obj.parent.remove(obj);
        byName[name] = wide;
        continue;
      }}
      obj.traverse((o) => {{
        if (!o.material) return;
        o.material.color.copy(color);
        if (name === 'tool') {{
          o.material.depthWrite = false;  // the contact faces stay visible through the tool
          o.renderOrder = 5;
        }} else if (name === 'contact_faces') {{
          o.material.emissive = new THREE.Color(0x400000);
        }}
      }});
    }}
    model.updateMatrixWorld(true);
    const xray = document.getElementById('xray');
    xray.addEventListener('change', () => {{
      for (const name of {line_layers}) {{
        if (byName[name]) byName[name].material.depthTest = !xray.checked;
      }}
      render();
    }});
    for (const input of document.querySelectorAll('#legend input[data-layer]')) {{
      const obj = byName[input.dataset.layer];
      if (!obj) {{ input.disabled = true; input.checked = false; continue; }}
      input.addEventListener('change', () => {{ obj.visible = input.checked; render(); }});
    }}
    const scale = frame.matrixWorld.getMaxScaleOnAxis();
    const toWorld = (p) => new THREE.Vector3(p[0], p[1], p[2]).applyMatrix4(frame.matrixWorld);
    const whole = new THREE.Box3().setFromObject(model).getBoundingSphere(new THREE.Sphere());
    const focusCl = () => {{
      const center = info.focus_center_mm ? toWorld(info.focus_center_mm) : whole.center.clone();
      const radius = info.focus_radius_mm ? info.focus_radius_mm * scale : whole.radius;
      look(center, radius);
    }};
    const look = (center, radius) => {{
      const d = info.view_direction || [1, -1, 1];
      const dir = new THREE.Vector3(d[0], d[1], d[2]).transformDirection(frame.matrixWorld).normalize();
      const dist = radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2));
      camera.position.copy(center).addScaledVector(dir, dist);
      camera.near = dist / 200;
      camera.far = dist + 4 * (whole.radius + radius);
      camera.updateProjectionMatrix();
      controls.target.copy(center);
      controls.update();
      render();
    }};
    document.getElementById('focus-cl').addEventListener('click', focusCl);
    document.getElementById('fit-all').addEventListener('click', () => look(whole.center, whole.radius));
    focusCl();
    // the flag tells tests (and scripts) that a frame with the scene has been drawn
    requestAnimationFrame(() => {{ html.dataset.fusioncutRendered = '1'; }});
  }}, (err) => fail('the embedded GLB could not be read: ' + (err.message || err)));

  window.addEventListener('resize', () => {{
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(window.innerWidth, window.innerHeight);
    render();
  }});
}}
</script>
</body>
</html>
"""


def _hex(rgba: tuple[float, ...]) -> str:
    return "#" + "".join(f"{round(255 * c):02x}" for c in rgba[:3])


def write_view_html(glb: bytes | str | Path, html_path: str | Path, title: str | None = None) -> Path:
    """Write a self-contained HTML page showing the GLB ``glb`` (bytes or a file) with orbit controls.

    The page embeds three.js and the GLB: it needs no network and no server. It shows a legend (with
    switches per layer) and the CL's info from the GLB's ``extras["fusioncut"]``, sets
    ``data-fusioncut-rendered="1"`` on ``<html>`` once the first frame with the scene is drawn, and
    ``data-fusioncut-error`` with a message (also shown on the page) when it cannot draw.
    """
    data = glb if isinstance(glb, bytes) else Path(glb).read_bytes()
    extras = ((glb_json(data).get("scenes") or [{}])[0].get("extras") or {}).get("fusioncut", {})
    import_map = {"imports": _import_map(str(three_dir()))}
    cl = extras.get("cl_index", "?")
    title = title or f"FusionCut — CL {cl}"
    legend = "".join(
        f'<label><input type="checkbox" checked data-layer="{name}">'
        f'<span class="swatch" style="background:{_hex(rgba)};opacity:{max(rgba[3], 0.6):.2f}"></span>'
        f"{html.escape(label)}</label>"
        for name, (label, rgba) in LAYERS.items())
    # on by default: the entry and exit lines often run along a corner the material hides
    legend += ('<label><input type="checkbox" id="xray" checked><span class="swatch"></span>'
               'lines through material</label>')
    rows = "".join(f"<tr><td>{html.escape(k)}</td><td>{html.escape(v)}</td></tr>" for k, v in _info_rows(extras))
    layers = {name: {"label": label, "rgba": list(rgba), "width": LINE_WIDTHS.get(name)}
              for name, (label, rgba) in LAYERS.items()}
    page = _PAGE.format(
        title=html.escape(title), background=BACKGROUND, import_map=_json_script(import_map), legend=legend,
        cl=html.escape(str(cl)), rows=rows, layers=_json_script(layers), root=ROOT_NODE,
        line_layers=json.dumps(list(LINE_LAYERS)),
        glb=base64.b64encode(data).decode("ascii"),
    )
    html_path = Path(html_path)
    html_path.write_text(page, encoding="utf-8")
    return html_path


__all__ = ["LAYERS", "ROOT_NODE", "glb_json", "scene_extras", "scene_glb", "three_dir", "write_glb",
           "write_view_html"]
