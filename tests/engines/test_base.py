"""The engine options, sweep methods and the Engine protocol (fusioncut.engines.base)."""
from __future__ import annotations

import dataclasses
import doctest
import inspect
import json

import pytest

from fusioncut.engines import cl_maps
from fusioncut.engines.base import LOWER_BOUNDS, Engine, EngineKind, EngineOptions, SweepMethod
from fusioncut.errors import FusionCutError, InputError


def test_every_option_has_its_own_help_and_a_default():
    for f in dataclasses.fields(EngineOptions):
        assert f.default is not dataclasses.MISSING, f.name
        assert len(f.metadata.get("help", "")) > 30, f.name
    # the lengths say their unit
    for name in ("slice_height", "max_segment_length", "chord_tolerance", "ramp_step", "cell_size",
                 "ceiling_pixel", "min_chip_thickness", "fuzzy"):
        assert "(mm)" in next(f for f in dataclasses.fields(EngineOptions) if f.name == name).metadata["help"], name


def test_sweep_takes_the_strings_of_results_and_job_files():
    options = EngineOptions(sweep="sampled")
    assert options.sweep is SweepMethod.SAMPLED and options.sweep == "sampled" and not options.exact
    assert EngineOptions().sweep is SweepMethod.EXACT and EngineOptions().exact
    assert json.dumps(dataclasses.asdict(options), default=str).count('"sweep": "sampled"') == 1
    assert f"{SweepMethod.STEP}" == "step"  # the value, as the results' sweep_method column holds it


@pytest.mark.parametrize("sweep", ["step", "oblique", ""])
def test_a_sweep_one_cannot_ask_for_is_refused(sweep):
    with pytest.raises(InputError, match="options.sweep"):
        EngineOptions(sweep=sweep)


def test_lower_bounds_are_checked_when_the_options_are_made():
    for name, low in LOWER_BOUNDS.items():
        EngineOptions(**{name: low})
        with pytest.raises(FusionCutError, match=f"options.{name}"):
            EngineOptions(**{name: low / 2})


def _protocol_members() -> set[str]:
    names = {n for n in vars(Engine) if not n.startswith("_")}
    return names | set(inspect.get_annotations(Engine))


def test_both_engines_implement_the_protocol():
    from fusioncut.engines.brep.engine import BRepEngine
    from fusioncut.engines.brep.parallel import ParallelBRepEngine

    members = _protocol_members()
    assert {"start", "process", "save_checkpoint", "load_checkpoint", "ipw", "ipw_volume", "close",
            "shares_cells", "kind", "options", "stock_volume", "removed_total"} <= members
    for cls, kind, shares in ((BRepEngine, EngineKind.BREP, False), (ParallelBRepEngine, EngineKind.PARALLEL_BREP, True)):
        fields = {f.name for f in dataclasses.fields(cls)}
        missing = [m for m in members if not hasattr(cls, m) and m not in fields]
        assert not missing, (cls.__name__, missing)
        for name in ("process", "save_checkpoint", "load_checkpoint", "start"):
            assert list(inspect.signature(getattr(cls, name)).parameters) == \
                list(inspect.signature(getattr(Engine, name)).parameters), (cls.__name__, name)
        engine = cls(EngineOptions())  # the parallel one opens no cluster until asked
        assert engine.kind is kind and engine.shares_cells is shares


def test_the_analytic_engine_implements_the_protocol(tmp_path):
    from fusioncut.engines.analytic.engine import AnalyticEngine
    from fusioncut.model import BoxStock

    members = _protocol_members()
    fields = {f.name for f in dataclasses.fields(AnalyticEngine)}
    assert not [m for m in members if not hasattr(AnalyticEngine, m) and m not in fields]
    for name in ("process", "save_checkpoint", "load_checkpoint", "start"):
        assert list(inspect.signature(getattr(AnalyticEngine, name)).parameters) == \
            list(inspect.signature(getattr(Engine, name)).parameters), name
    engine = AnalyticEngine(EngineOptions(engine="analytic"))
    assert engine.kind is EngineKind.ANALYTIC and engine.shares_cells is False
    assert engine.load_checkpoint(tmp_path) is None  # nothing saved yet
    engine.start(BoxStock((0, 0, -10), (30, 20, 0)))
    engine.removed_total = 12.5
    assert engine.ipw is None and engine.ipw_volume == 6000 - 12.5
    engine.save_checkpoint(tmp_path, 3)
    again = AnalyticEngine(EngineOptions(engine="analytic"))
    assert again.load_checkpoint(tmp_path) == 3
    assert again.stock == engine.stock and again.removed_total == 12.5
    assert json.loads((tmp_path / "state.json").read_text())["next_cl"] == 3
    engine.close()


def test_the_cl_maps_doctests_hold():
    failed, attempted = doctest.testmod(cl_maps)
    assert attempted > 0 and failed == 0


def test_the_kernel_free_modules_import_no_kernel():
    import subprocess
    import sys

    code = ("import sys, fusioncut.engines.cl_maps, fusioncut.engines.base; "
            "print(any(m == 'OCP' or m.startswith('OCP.') for m in sys.modules))")
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip() == "False"
