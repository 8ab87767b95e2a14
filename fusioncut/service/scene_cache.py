"""The workpiece after CL N of a service job, as a 3D scene (GLB), built on a Dask worker and cached.

:func:`build_scene` replays the job's own toolpath (the job file in its ``input/``, read the way the
runner reads it, so CL indices are the run's) on a fresh engine up to CL N and writes the scene of
that CL (:func:`fusioncut.engines.brep.export.cl_scene`: workpiece, contact faces, tool, entry/exit
lines and engaged arcs) as ``<job>/scenes/clNNNNNNN.glb``. The job's own run is never touched: its
checkpoint folder holds only its latest state.

What bounds the work:

* **Replays start from saved engine states.** On the way to N the replay saves the engine state
  (:meth:`BRepEngine.save_checkpoint`: exact, a resumed engine gives the same results bit for bit)
  every :func:`state_spacing` CLs (100, or more on a long job, so that a job has at most
  :data:`MAX_SPACED_STATES`), and after N itself (the last :data:`MAX_RECENT_STATES` of those are
  kept). A later request starts from the nearest state at or before its CL, so after the first
  replay a request costs at most one spacing of CLs, and stepping the slider forward only the CLs
  stepped over. The first replay is at most the job's own length, which the service's CL limit
  bounded when the job was admitted.
* **A superseded request stops.** The route hands each task a want-file
  (``scenes/.want-clNNNNNNN``) and removes it when a newer CL of the same job is asked for; the
  task checks it after every CL and stops (the states it saved on the way stay useful).
* **Meshes are bounded.** The scene is meshed at the display deflection of the tool
  (:func:`~fusioncut.engines.brep.export.default_deflection`); while it holds more than
  ``max_triangles`` triangles the deflection and the angular deflection are doubled, up to
  :data:`COARSENINGS` times; a scene still larger is refused with a message (never written).

Everything is written through a temporary name and ``os.replace``, so two tasks of one job on two
workers, or a reader during a write, never see half a file.
"""
from __future__ import annotations

import math
import os
import shutil
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from fusioncut.errors import FusionCutError
from fusioncut.service.files import INPUT_DIR, JOB_FILE
from fusioncut.service.portable import job_folders, portable_text

SCENES_DIR = "scenes"  # in the job folder, beside input/ and results/: a cache, not a result file
STATES_DIR = "states"
FAILURES_DIR = "failures"
MAX_SPACED_STATES = 64
MIN_STATE_SPACING = 100  # CLs; a demo state is ~70 kB and takes ~10 ms to save
MAX_RECENT_STATES = 4
MAX_SCENES = 64  # cached GLBs per job; the least recently written go first
DEFAULT_MAX_TRIANGLES = 300_000  # ~22 MB of GLB (positions and normals per face, unwelded)
COARSENINGS = 5  # deflection doubled at most this often: x32


class SceneSuperseded(Exception):
    """A newer CL of the same job was asked for: this replay is no longer wanted. A signal, not an
    error: :func:`build_scene` answers it with ``{"state": "superseded"}``, so no user sees it."""


def scene_name(cl: int) -> str:
    return f"cl{cl:07d}.glb"


def want_name(cl: int) -> str:
    return f".want-cl{cl:07d}"


def state_spacing(total: int) -> int:
    """CLs between the saved engine states of a job of ``total`` CLs."""
    return max(MIN_STATE_SPACING, math.ceil(total / MAX_SPACED_STATES))


def _state_dir(states: Path, next_cl: int, recent: bool) -> Path:
    return states / f"{'recent' if recent else 'next'}{next_cl:07d}"


def _saved_states(states: Path) -> list[tuple[int, Path]]:
    """(next CL, folder) of every complete saved state, in CL order."""
    out = []
    for d in states.glob("*0*") if states.is_dir() else []:
        digits = d.name.removeprefix("next").removeprefix("recent")
        if d.is_dir() and digits.isdigit() and (d / "state.json").is_file():
            out.append((int(digits), d))
    return sorted(out)


def _save_state(engine: Any, states: Path, next_cl: int, recent: bool) -> None:
    target = _state_dir(states, next_cl, recent)
    if target.exists():
        return
    tmp = states / f".tmp-{next_cl}-{os.getpid()}-{threading.get_ident()}"
    shutil.rmtree(tmp, ignore_errors=True)
    engine.save_checkpoint(tmp, next_cl)
    try:
        os.replace(tmp, target)
    except OSError:  # another task saved the same state first
        shutil.rmtree(tmp, ignore_errors=True)
    if recent:
        for _, old in [s for s in _saved_states(states) if s[1].name.startswith("recent")][:-MAX_RECENT_STATES]:
            shutil.rmtree(old, ignore_errors=True)


def _prune_scenes(folder: Path) -> None:
    scenes = sorted(folder.glob("cl*.glb"), key=lambda p: p.stat().st_mtime)
    for old in scenes[:-MAX_SCENES]:
        old.unlink(missing_ok=True)


def _triangles(scene: Any) -> int:
    return sum(len(m.triangles) for m in (scene.ipw, scene.contact, scene.tool))


def _portable_info(info: dict[str, Any], folder: Path) -> None:
    """The CL info the GLB carries (its ``extras``) without server paths: the source ``file:line``, the
    reason of a failed CL and the warnings name files the way the user named them."""
    folders = job_folders(folder)
    for key in ("source", "reason"):
        if isinstance(info.get(key), str):
            info[key] = portable_text(info[key], *folders)
    info["warnings"] = [portable_text(str(w), *folders) for w in info.get("warnings", [])]


def build_scene(job_dir: str, cl: int, max_triangles: int = DEFAULT_MAX_TRIANGLES) -> dict[str, Any]:
    """Write the scene of CL ``cl`` of the job in ``job_dir`` (see the module docstring) and return
    ``{"state": "ready", "cl", "triangles", "deflection_mm", "replayed": CLs run, "from": first CL
    run, "seconds"}``, or ``{"state": "superseded", ...}`` when its want-file went away, or
    ``{"state": "failed", "message"}`` for a problem of the job's input or geometry (one line, no
    server paths)."""
    t0 = time.perf_counter()
    folder = Path(job_dir)
    scenes = folder / SCENES_DIR
    out = scenes / scene_name(cl)
    if out.is_file():
        return {"state": "ready", "cl": cl, "replayed": 0, "from": cl, "seconds": 0.0}
    try:
        return _build(folder, scenes, out, cl, max_triangles, t0)
    except SceneSuperseded:
        return {"state": "superseded", "cl": cl, "seconds": time.perf_counter() - t0}
    except FusionCutError as exc:
        return {"state": "failed", "cl": cl, "message": portable_text(str(exc), *job_folders(folder))}


def _build(folder: Path, scenes: Path, out: Path, cl: int, max_triangles: int, t0: float) -> dict[str, Any]:
    from fusioncut.engines.brep.engine import BRepEngine
    from fusioncut.engines.brep.export import DEFAULT_ANGLE, check_cl_index, cl_scene, default_deflection
    from fusioncut.io.job import Job
    from fusioncut.runner import prepare_job
    from fusioncut.service.worker import single_process
    from fusioncut.viz.scene import scene_glb

    want = scenes / want_name(cl)
    states = scenes / STATES_DIR
    states.mkdir(parents=True, exist_ok=True)
    job = single_process(Job.model_validate_json((folder / INPUT_DIR / JOB_FILE).read_text(encoding="utf-8")))
    p = prepare_job(job, folder / INPUT_DIR)
    # a CL that failed in the run fails again here: its shapes go beside the scenes (the engine's
    # default is a folder in the worker's working directory)
    options = replace(p.options, failure_dir=scenes / FAILURES_DIR)
    segments = check_cl_index(p.toolpath, cl, options)
    spacing = state_spacing(len(segments))

    engine = BRepEngine(options)
    start_at = 0
    for next_cl, d in reversed(_saved_states(states)):
        if next_cl <= cl and engine.load_checkpoint(d) == next_cl:
            start_at = next_cl
            break
    else:
        engine.start(p.stock)
    watched = want.exists()  # the route's tasks are watched; a direct call is not
    em = None
    for m in engine.process(p.toolpath, p.default_tool, start_at=start_at):
        if watched and not want.exists():
            raise SceneSuperseded()
        if m.cl_index == cl:
            em = m
            break
        if (m.cl_index + 1) % spacing == 0:
            _save_state(engine, states, m.cl_index + 1, recent=False)
    assert em is not None and em.cl_index == cl
    _save_state(engine, states, cl + 1, recent=(cl + 1) % spacing != 0)

    move = segments[cl]
    tool = (p.toolpath.tools.get(move.tool) if move.tool is not None else None) or p.default_tool
    assert tool is not None  # process() raised already for a move without a tool
    deflection, angle = default_deflection(tool), DEFAULT_ANGLE
    ipw = engine.ipw
    for _ in range(COARSENINGS + 1):
        scene = cl_scene(ipw, tool, em, slice_height=options.slice_height, deflection=deflection, angle=angle)
        if _triangles(scene) <= max_triangles:
            break
        deflection, angle = 2 * deflection, min(2 * angle, 1.0)
    else:
        raise FusionCutError(f"CL {cl}: the workpiece's mesh needs more than {max_triangles} triangles even at "
                             f"{deflection / 2:g} mm deflection; download the workpiece instead")
    _portable_info(scene.info, folder)
    data = scene_glb(scene)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, out)
    _prune_scenes(scenes)
    return {"state": "ready", "cl": cl, "triangles": _triangles(scene), "deflection_mm": scene.deflection,
            "bytes": len(data), "replayed": cl + 1 - start_at, "from": start_at,
            "seconds": time.perf_counter() - t0}
