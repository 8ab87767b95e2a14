"""The 3D scene of one CL: the GLB reads back with its named nodes, colours and true size; the HTML page
is self-contained; and a headless Chromium (WebGL on SwiftShader) really draws the workpiece and the
tool."""
from __future__ import annotations

import base64
import os
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
import trimesh

import fusioncut
from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.export import cl_scene, replay
from fusioncut.errors import FusionCutError
from fusioncut.engines.segments import segments_for
from fusioncut.model import BoxStock, FlatEndMill, LinearMove, Toolpath
from fusioncut.viz import scene as viz
from fusioncut.viz.scene import BACKGROUND, LAYERS, MACHINE_TO_GLTF, glb_json, scene_glb, write_view_html

TOOL = FlatEndMill(6.0, 15.0, number=1)
STOCK = BoxStock((0.0, 0.0, -10.0), (30.0, 20.0, 0.0))
TIP = (20.0, 12.0, -3.0)
NODES = {"ipw", "contact_faces", "tool", "entry_lines", "exit_lines", "engaged_arcs"}
CHROMIUM = "/usr/bin/chromium"


@pytest.fixture(scope="module")
def cl_state():
    # a side pass, a ramp, then a full slot along +X that stops inside the block: the last CL
    pts = [(-5.0, 5.0, -2.0), (12.0, 5.0, -2.0), (-5.0, 12.0, -3.0), TIP]
    tp = Toolpath(tuple(LinearMove(a, b, feed=600.0, tool=1) for a, b in zip(pts, pts[1:])), {1: TOOL})
    options = EngineOptions(slice_height=0.5)
    return replay(tp, STOCK, len(segments_for(tp.moves, options)) - 1, options)


@pytest.fixture(scope="module")
def glb(cl_state) -> bytes:
    return scene_glb(cl_scene(cl_state.engine, TOOL, cl_state.map, slice_height=0.5))


def three_or_skip() -> None:
    """The page needs three.js from `npm ci` in frontend/: skip without it, unless CI requires it."""
    try:
        viz.three_dir()
    except FusionCutError as exc:
        if os.environ.get("FUSIONCUT_REQUIRE_BROWSER") == "1":
            pytest.fail(str(exc))
        pytest.skip(str(exc))


@pytest.fixture(scope="module")
def page(glb, tmp_path_factory) -> Path:
    three_or_skip()
    return write_view_html(glb, tmp_path_factory.mktemp("page") / "scene.html", title="slot <end>")


# -- GLB --------------------------------------------------------------------------------------------


def write_glb_bytes(data: bytes, path: Path) -> Path:
    path.write_bytes(data)
    return path


def test_glb_reads_back_with_named_nodes(glb, tmp_path):
    path = write_glb_bytes(glb, tmp_path / "scene.glb")
    scene = trimesh.load(path)
    assert isinstance(scene, trimesh.Scene)
    assert set(scene.graph.nodes_geometry) == NODES
    assert isinstance(scene.geometry["ipw"], trimesh.Trimesh)
    assert isinstance(scene.geometry["entry_lines"], trimesh.path.Path3D)
    # every node hangs under the machine frame: mm -> m and Z up -> Y up
    for name in NODES:
        matrix, _ = scene.graph.get(name)
        assert np.allclose(matrix, MACHINE_TO_GLTF)


def test_glb_bounds_are_the_parts(glb, tmp_path, cl_state):
    scene = trimesh.load(write_glb_bytes(glb, tmp_path / "scene.glb"))
    # the workpiece (its faces in two nodes) spans the stock: the machining left its corners
    both = np.vstack([scene.geometry["ipw"].bounds, scene.geometry["contact_faces"].bounds])
    assert np.allclose(both.min(axis=0), STOCK.minimum, atol=1e-4)
    assert np.allclose(both.max(axis=0), STOCK.maximum, atol=1e-4)
    lo, hi = scene.geometry["tool"].bounds
    assert np.allclose(lo, (TIP[0] - 3, TIP[1] - 3, TIP[2]), atol=0.05)
    assert np.allclose(hi, (TIP[0] + 3, TIP[1] + 3, TIP[2] + TOOL.length), atol=0.05)
    # in the glTF world (metres, Y up): X is the block's 30 mm, Y the height from the block's bottom
    # (z = -10) to the top of the tool (z = -3 + 27), Z the block's 20 mm
    ext = scene.bounds[1] - scene.bounds[0]
    height = TIP[2] + TOOL.length - STOCK.minimum[2]
    assert np.allclose(ext, (0.030, height * 1e-3, 0.020), atol=1e-4)
    # the contact faces lie on the tool's cylinder at the CL
    v = scene.geometry["contact_faces"].vertices
    assert np.allclose(np.hypot(v[:, 0] - TIP[0], v[:, 1] - TIP[1]), 3.0, atol=1e-5)


def test_glb_colours_and_extras(glb, cl_state):
    tree = glb_json(glb)
    mats = {m["name"]: m for m in tree["materials"] if "name" in m}
    mesh_mat = {m["name"]: mats_by_index(tree, m) for m in tree["meshes"]}
    rgba = {name: np.array(mesh_mat[name]["pbrMetallicRoughness"]["baseColorFactor"]) for name in NODES}
    r, g, b, a = rgba["ipw"]
    assert max(r, g, b) - min(r, g, b) < 0.1 and a == 1  # grey, opaque
    assert rgba["tool"][0] > rgba["tool"][2] + 0.3 and rgba["tool"][3] < 0.8  # gold, see-through
    assert mesh_mat["tool"]["alphaMode"] == "BLEND" and mats["ipw"]["alphaMode"] == "OPAQUE"
    assert rgba["contact_faces"][0] > 0.5 > rgba["contact_faces"][1] + 0.3  # red
    assert rgba["entry_lines"][1] > rgba["entry_lines"][0] + 0.4  # green
    assert rgba["exit_lines"][2] > rgba["exit_lines"][0] + 0.4  # blue
    extras = tree["scenes"][0]["extras"]["fusioncut"]
    assert extras["cl_index"] == cl_state.map.cl_index and extras["status"] == "engaged" and extras["units"] == "mm"
    assert extras["position_mm"] == list(TIP) and len(extras["view_direction"]) == 3


def mats_by_index(tree: dict, mesh: dict) -> dict:
    return tree["materials"][mesh["primitives"][0]["material"]]


def test_entry_and_exit_lines_run_over_the_engine_bands(cl_state):
    """The slot CL's entry and exit lines cover the slices' bands by the engine's slice rule, the ones
    the results record (z_lo_mm .. z_hi_mm); without the slice height the bands are unknown and only
    the arcs are drawn, no spacing guessed."""
    from fusioncut.engines.brep.export import engagement_lines
    from fusioncut.io.results import slice_rows

    m = cl_state.map
    lines = engagement_lines(m, TOOL, slice_height=0.5)
    rows = slice_rows(m, 0.5)
    bottom, top = min(r["z_lo_mm"] for r in rows), max(r["z_hi_mm"] for r in rows)
    zs = lines.entry[..., 2] - TIP[2]
    assert zs.min() == pytest.approx(bottom, abs=1e-12) and zs.max() == pytest.approx(top, abs=1e-12)
    assert top - bottom == pytest.approx(m.ap, abs=1e-9)  # the bands tile the axial contact
    bare = engagement_lines(m, TOOL)
    assert len(bare.entry) == len(bare.exit) == 0 and len(bare.arcs) == len(lines.arcs) > 0


def test_glb_of_an_air_cl_has_no_contact_or_lines(cl_state):
    from dataclasses import replace

    from fusioncut.model import CLStatus

    air = replace(cl_state.map, status=CLStatus.AIR, slices=(), position=(50.0, 50.0, 5.0))
    names = {n["name"] for n in glb_json(scene_glb(cl_scene(cl_state.engine, TOOL, air))).get("nodes", [])}
    assert names == {"machine_frame", "ipw", "tool"}


# -- the page ---------------------------------------------------------------------------------------


class _Scripts(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.scripts: list[tuple[dict, str]] = []
        self.urls: list[str] = []
        self._open: dict | None = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.urls += [v for k, v in attrs.items() if k in ("src", "href") and v]
        if tag == "script":
            self._open, self._text = attrs, []

    def handle_data(self, data):
        if self._open is not None:
            self._text.append(data)

    def handle_endtag(self, tag):
        if tag == "script" and self._open is not None:
            self.scripts.append((self._open, "".join(self._text)))
            self._open = None


IMPORT = re.compile(r"""^(?:import|export|\})[^\n]*?\bfrom\s*(['"])([^'"]+)\1""", re.MULTILINE)


def test_page_is_self_contained(page, glb):
    import json

    parser = _Scripts()
    text = page.read_text(encoding="utf-8")
    parser.feed(text)
    assert not parser.urls  # no script src, no stylesheet link: nothing is fetched
    kinds = [attrs.get("type") for attrs, _ in parser.scripts]
    assert kinds.count("importmap") == 1 and kinds.count("module") == 1
    imports = json.loads(next(body for attrs, body in parser.scripts if attrs.get("type") == "importmap"))["imports"]
    assert {"three", "three/addons/controls/OrbitControls.js", "three/addons/loaders/GLTFLoader.js"} <= set(imports)
    for spec, url in imports.items():
        assert url.startswith("data:text/javascript;base64,"), spec
        source = base64.b64decode(url.split(",", 1)[1]).decode("utf-8")
        # every static import of every inlined module is another entry of the map (no relative or
        # http(s) specifier is left to fetch)
        for m in IMPORT.finditer(source):
            assert m.group(2) in imports, (spec, m.group(2))
    module = next(body for attrs, body in parser.scripts if attrs.get("type") == "module")
    specs = [m.group(2) for m in IMPORT.finditer(module)]
    assert specs and all(s in imports for s in specs)
    assert not re.search(r"""(src|href)\s*=\s*["']?https?://""", text)
    # the GLB travels inside the page, byte for byte
    embedded = next(body for attrs, body in parser.scripts if attrs.get("id") == "fusioncut-glb")
    assert base64.b64decode("".join(embedded.split())) == glb
    # legend and CL info, with the title escaped
    for label, _ in LAYERS.values():
        assert label in text
    assert "<title>slot &lt;end&gt;</title>" in text
    assert "(20.000, 12.000, -3.000) mm" in text


def test_page_from_a_glb_file(glb, tmp_path, cl_state):
    three_or_skip()
    path = write_glb_bytes(glb, tmp_path / "s.glb")
    out = write_view_html(path, tmp_path / "s.html")
    assert f"<title>FusionCut — CL {cl_state.map.cl_index}</title>" in out.read_text(encoding="utf-8")


def test_missing_three_js_says_how_to_install(glb, tmp_path, monkeypatch):
    monkeypatch.delenv(viz.THREE_ENV, raising=False)
    monkeypatch.setattr(fusioncut, "__file__", str(tmp_path / "pkg" / "fusioncut" / "__init__.py"))
    with pytest.raises(FusionCutError, match=r"three\.js not found.*npm ci.*frontend"):
        write_view_html(glb, tmp_path / "x.html")
    monkeypatch.setenv(viz.THREE_ENV, str(tmp_path))
    with pytest.raises(FusionCutError, match=viz.THREE_ENV):
        write_view_html(glb, tmp_path / "x.html")
    assert not (tmp_path / "x.html").exists()


def test_three_dir_from_the_environment(tmp_path, monkeypatch):
    three_or_skip()
    real = viz.three_dir()
    copy = tmp_path / "three"
    for rel in viz.THREE_ENTRIES.values():
        (copy / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(real / rel, copy / rel)
    monkeypatch.setenv(viz.THREE_ENV, str(copy))
    assert viz.three_dir() == copy


# -- in a browser -----------------------------------------------------------------------------------


def _browser_or_skip():
    required = os.environ.get("FUSIONCUT_REQUIRE_BROWSER") == "1"
    if not Path(CHROMIUM).is_file():
        if required:
            pytest.fail(f"FUSIONCUT_REQUIRE_BROWSER=1 but {CHROMIUM} is missing")
        pytest.skip(f"{CHROMIUM} is not installed")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        if required:
            pytest.fail("FUSIONCUT_REQUIRE_BROWSER=1 but playwright is not installed")
        pytest.skip("playwright is not installed")
    return sync_playwright


def _classes(png: Path) -> dict[str, np.ndarray]:
    import matplotlib.image as mpimg

    im = mpimg.imread(png)[..., :3].astype(float)
    r, g, b = im[..., 0], im[..., 1], im[..., 2]
    bg = np.array([int(BACKGROUND[k:k + 2], 16) for k in (1, 3, 5)]) / 255
    scene = np.abs(im - bg).max(axis=2) > 0.06
    return {
        "scene": scene,
        "grey": scene & (im.max(axis=2) - im.min(axis=2) < 0.06),  # the workpiece
        "gold": (r - b > 0.12) & (g - b > 0.05) & (r - g < 0.2),  # the tool over anything
        "red": (r > 0.45) & (r - g > 0.3) & (r - b > 0.3),  # the contact faces
        "green": (g - r > 0.25) & (g - b > 0.2),
        "blue": (b - r > 0.3) & (b - g > 0.15),
        "image": im,
    }


def test_browser_draws_the_scene(page, tmp_path):
    sync_playwright = _browser_or_skip()
    shot = tmp_path / "scene.png"
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=[
            "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
            "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run"])
        try:
            tab = browser.new_page(viewport={"width": 800, "height": 600})
            errors: list[str] = []
            tab.on("pageerror", lambda e: errors.append(str(e)))
            requests: list[str] = []
            tab.on("request", lambda r: requests.append(r.url))
            tab.goto(page.as_uri())
            tab.wait_for_function("document.documentElement.dataset.fusioncutRendered === '1'"
                                  " || !!document.documentElement.dataset.fusioncutError", timeout=60_000)
            assert tab.evaluate("document.documentElement.dataset.fusioncutError || ''") == ""
            assert not errors
            # WebGL really runs (SwiftShader here), not a 2D fallback
            assert tab.evaluate("!!document.querySelector('#view canvas').getContext('webgl2')")
            assert tab.evaluate("document.querySelectorAll('#legend input').length") == len(LAYERS) + 1
            # the page fetched nothing but itself and its data: URLs
            assert all(u.startswith(("file:", "data:")) for u in requests), requests
            tab.evaluate("document.body.classList.add('bare')")  # legend swatches out of the picture
            tab.screenshot(path=str(shot))
        finally:
            browser.close()
    c = _classes(shot)
    n = c["scene"].size
    assert c["scene"].sum() > 0.3 * n  # the scene fills much of the view
    assert c["grey"].sum() > 0.1 * n  # the workpiece
    assert c["gold"].sum() > 0.03 * n  # the tool
    assert c["red"].sum() > 0.003 * n  # the contact faces, seen through the tool
    assert c["green"].sum() > 30 and c["blue"].sum() > 30  # entry and exit lines
    colours = np.unique((c["image"] * 15).round().reshape(-1, 3), axis=0)
    assert len(colours) > 30  # shaded surfaces, not flat fills


def test_import_map_follows_relative_imports(tmp_path):
    # three.js >= r171 splits its build: three.module.min.js imports "./three.core.min.js"; addons
    # import their siblings by relative paths. A data: URL cannot resolve those, so they become
    # entries of the map themselves.
    root = tmp_path / "three"
    files = {
        "build/three.module.min.js": 'export*from"./three.core.min.js";export const M=1;',
        "build/three.core.min.js": "export const C=2;",
        "examples/jsm/utils/Helper.js": "import { C } from 'three';\nexport const h = C;\n",
    }
    for rel in viz.THREE_ENTRIES.values():
        if rel.startswith("examples/"):
            files[rel] = ("import {\n\tM\n} from 'three';\nimport { h } from '../utils/Helper.js';\n"
                          "// not an import: from './nowhere.js'\nexport const x = M + h;\n")
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    imports = viz._import_map(str(root))

    def source(spec: str) -> str:
        return base64.b64decode(imports[spec].split(",", 1)[1]).decode()

    core = "fusioncut-three/build/three.core.min.js"
    helper = "fusioncut-three/examples/jsm/utils/Helper.js"
    assert set(imports) == set(viz.THREE_ENTRIES) | {core, helper}
    assert f'from"{core}"' in source("three") and source(core) == files["build/three.core.min.js"]
    loader = source("three/addons/loaders/GLTFLoader.js")
    assert f"from '{helper}'" in loader and "from './nowhere.js'" in loader  # a comment stays as it is
    # an import the page cannot satisfy is refused, not silently left to fail in the browser
    (root / "examples/jsm/utils/Helper.js").write_text("import { z } from 'https://cdn.example/z.js';\n")
    with pytest.raises(FusionCutError, match="cannot inline"):
        viz._import_map(str(root) + "/")  # another cache key
