"""The removed volume's adaptive integral keeps its error within what it allows itself, cell by cell,
on a real program's ball-end finishing (differential: the same cells at a far tighter tolerance)."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from fusioncut.engines.analytic import engine as analytic
from fusioncut.engines.base import EngineOptions

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))


def test_each_cell_of_a_ball_finishing_pass_is_within_its_tolerance(monkeypatch):
    """bear's CLs 8802-8804 (a 3.175 mm ball's raster beside its last pass: thin crescents, kinks where
    the pass before last and the last meet): each cell's volume at the engine's tolerance against the
    same integral at 1e-15 mm per mm² and 1e-13 of itself. The engine asks of each cell max(volume_tol
    x its area, volume_rel x its volume), a tenth of the 1e-7 the volume must keep, because that bound
    is QUADPACK's error estimate, not a proof: a kink no probe located can make a cell end beyond it.
    Each cell must keep the 1e-7 (ten times its own bound); a crescent stepped over (5e-6 mm³) would
    not."""
    import real_programs
    from shared_data import DATA

    if not (DATA / "camotics-examples" / "bear" / "bear.nc").is_file():
        pytest.skip("shared data missing")
    toolpath, stock, default = real_programs.load(next(p for p in real_programs.PROGRAMS if p.name == "bear"))
    cells = []
    integral = analytic.removed_volume

    def kept(*args):
        cells.append(args)
        return integral(*args)

    monkeypatch.setattr(analytic, "removed_volume", kept)
    engine = analytic.AnalyticEngine(EngineOptions(slice_height=1.0))
    engine.start(stock)
    maps = engine.process(toolpath, default, start_at=8802)
    assert sum(next(maps).removed_volume for _ in range(3)) > 5
    cut = 0
    for args in cells:
        xs, ylo, yhi, tol, rel = args[0], args[1], args[2], args[15], args[16]
        value = integral(*args)[0]
        exact = integral(*args[:15], 1e-15, 1e-13, args[17])[0]
        assert abs(value - exact) <= 10 * max(tol * (xs[-1] - xs[0]) * (yhi - ylo), rel * abs(exact))
        cut += exact > 1e-6
    assert cut >= 4
