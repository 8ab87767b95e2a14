"""The removed volume's adaptive integral keeps its error within what it allows itself, cell by cell,
on a real program's ball-end finishing (differential: the same cells at a far tighter tolerance); a
line's inner integral converges to that line's integral where a helix's surface bends beside a break
point (:func:`.volume.inner_integral`)."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from numba import njit

from fusioncut.engines.analytic import engine as analytic
from fusioncut.engines.analytic.breaks import sweep_curves
from fusioncut.engines.analytic.profile import lower_profile
from fusioncut.engines.analytic.sweeps import arc_row
from fusioncut.engines.analytic.volume import _workspace, height_and_cause, inner_integral
from fusioncut.engines.base import EngineOptions
from fusioncut.model import BullNoseEndMill

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


RHO, OUTER = 10.206207261596575, 12.5


def _arc(rho, a0, sw, z0, z1):
    """The sweep row (:func:`.sweeps.arc_row`) of an arc or helix about the origin."""
    start = (rho * math.cos(a0), rho * math.sin(a0), z0)
    return arc_row(start, (rho * math.cos(a0 + sw), rho * math.sin(a0 + sw), z1), (0.0, 0.0), rho, a0, sw, 0)


@njit(cache=True)
def _midpoint(x, lo, hi, n, S, P, R, C, CB, PP, NPC, RR, zb, zt):
    h = (hi - lo) / n
    total = 0.0
    for i in range(n):
        total += height_and_cause(x, lo + (i + 0.5) * h, S, P, R, C, CB, PP, NPC, RR, zb, zt)[0]
    return total * h


def test_a_helix_continuing_a_level_circle_meets_the_lines_integral():
    """gen_waterline_bull's CL 101: a bull-nose (R 3, corner 1) descends a helix of radius 10.206 from -7.15
    to -7.2 mm, after the helix down to -7.15 and the level circle at -7 it continues, and a waterline's
    circle at 12.5 (stock from -15 to 0). Along x = -7.815 its lowest tool leaves the end of its window along
    the path 0.008 mm beyond the end tool's flat-to-corner joint circle (d = 2). That bend is not a break
    point; one at the joint circle beside it (a tangential joint taken as a break radius) made both
    Gauss-Kronrod rules of the part miss the same sliver: 1e-7 mm² off with an estimate of 2e-15. At a tight
    budget the line's integral meets a midpoint rule of 1e6 nodes (converged: 1.6e7 give the same 12
    digits) to 1e-10 mm²."""
    pieces = lower_profile(BullNoseEndMill(6, 20, corner_radius=1)).pieces
    S = _arc(RHO, 0.6 * math.pi, 0.2 * math.pi, -7.15, -7.2)
    C = np.array([_arc(RHO, 0.0, 0.6 * math.pi, -7.0, -7.15), _arc(RHO, math.pi, 3 * math.pi, -7.0, -7.0),
                  _arc(OUTER, 0.0, math.pi, -6.5, -6.75), _arc(OUTER, math.pi, 3 * math.pi, -6.5, -6.5)])
    CB = np.array([[-6.153891492946338, -3.000000001, 13.206207262596575, 13.206207262596577],
                   [-13.206207262596575, -13.206207262596575, 13.206207262596575, 13.206207262596575],
                   [-15.500000001, -3.000000001, 15.500000001, 15.500000001],
                   [-15.500000001, -15.500000001, 15.500000001, 15.500000001]])
    PP, NPC, RR = pieces[None, :, :], np.array([pieces.shape[0]]), np.array([3.0])
    zb, zt, ylo, yhi, x = -15.0, 0.0, 7.852869016503577, 10.27977447015196, -7.815032998
    circles, segments = sweep_curves(np.vstack([S[None, :], C]), PP, NPC, zb, zt)
    edges = np.empty(0)
    line = inner_integral(x, ylo, yhi, circles, segments, S, pieces, 3.0, C, CB, PP, NPC, RR, zb, zt, 1e-15, 1e-13,
                          edges, _workspace(0))[0]
    reference = _midpoint(x, ylo, yhi, 1_000_000, S, pieces, 3.0, C, CB, PP, NPC, RR, zb, zt)
    assert reference > 0.4
    assert abs(line - reference) <= 1e-10
