"""A flat end mill's arcs and helices in polar coordinates (.polar): closed forms of helical bores, and
each CL against the adaptive integral (.volume)."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

import fusioncut.engines.analytic.engine as analytic
from fusioncut.model import ArcMove, BallEndMill, BoxStock, FlatEndMill, LinearMove
from tests.engines.analytic.test_engine import VOLUME_REL, assert_maps_agree, run

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))


def _bore(rho: float, turns: int, pitch: float, decimals: int | None = None, z0: float = 1.0) -> list:
    """A helical bore about (1, 2): from a rapid above, ``turns`` counter-clockwise turns of radius ``rho``
    going down ``pitch`` mm a turn from ``z0``, then a level circle at the bottom and out; coordinates
    rounded to ``decimals`` as a post writes them (None: not)."""
    def q(v: float) -> float:
        return v if decimals is None else round(v, decimals)

    c = (1.0, 2.0)
    p = (q(c[0] + rho), q(c[1]), z0)
    moves = [LinearMove((p[0], p[1], 5.0), p, rapid=True, tool=1)]
    z = z0
    for _ in range(turns):
        for half in (math.pi, 0.0):  # half turns, as posts write helices
            end = (q(c[0] + rho * math.cos(half)), q(c[1] + rho * math.sin(half)), q(z - pitch / 2))
            moves.append(ArcMove(p, end, feed=600.0, tool=1, center=(c[0], c[1], p[2])))
            p, z = end, z - pitch / 2
    moves.append(ArcMove(p, p, feed=600.0, tool=1, center=(c[0], c[1], p[2])))
    moves.append(LinearMove(p, (p[0], p[1], 5.0), rapid=True, tool=1))
    return moves


def _spied(monkeypatch) -> list:
    calls = []
    polar = analytic.polar_volume
    monkeypatch.setattr(analytic, "polar_volume", lambda *a: calls.append(1) or polar(*a))
    return calls


@pytest.mark.parametrize("rho", [1.2, 4.0])
def test_a_helical_bore_removes_its_cylinder(monkeypatch, rho):
    """A flat end mill (R = 3) going down a helix from above the stock, then round once at the bottom,
    leaves a hole of radius rho + R, depth D (rho < R), or an annulus round a core of radius rho - R
    (rho > R): its CLs' volumes add up to pi (rho + R)^2 D, or 4 pi rho R D."""
    calls = _spied(monkeypatch)
    depth = 4.0
    _, maps = run(_bore(rho, turns=5, pitch=1.0), {1: FlatEndMill(6, 20)}, BoxStock((-12, -12, -10), (12, 12, 0)),
                  slice_height=1.0)
    R = 3.0
    expected = math.pi * (rho + R) ** 2 * depth if rho < R else 4 * math.pi * rho * R * depth
    assert sum(m.removed_volume for m in maps) == pytest.approx(expected, rel=1e-7)
    assert all(m.engine == "analytic" for m in maps)
    assert len(calls) > 50  # cells integrated in polar coordinates


def test_a_wider_helix_down_a_bored_hole_removes_the_ring_between(monkeypatch):
    """As fusion-posted/1110_wall's Bore1: a helix of radius 0.275, then one of 0.375 down the same hole
    (R = 1.325, 0.5 mm a turn, 4 mm deep): the second removes the ring between radii 1.6 and 1.7 all
    the way down, pi (1.7^2 - 1.6^2) D, CL by CL as the adaptive integral finds it; inside 1.6 each
    of its cells is proven to remove nothing (the first helix's lowest turn holds it) and skipped."""
    R, depth = 1.325, 4.0
    first = _bore(0.275, turns=8, pitch=0.5, z0=0.0)
    moves = first + _bore(0.375, turns=8, pitch=0.5, z0=0.0)
    tools, stock = {1: FlatEndMill(2 * R, 15)}, BoxStock((-6, -6, -6), (8, 8, 0))
    _, alone = run(first, tools, stock)
    calls = _spied(monkeypatch)
    _, maps = run(moves, tools, stock)
    assert sum(m.removed_volume for m in alone) == pytest.approx(math.pi * 1.6 ** 2 * depth, rel=1e-7)
    second = sum(m.removed_volume for m in maps[len(alone):])
    assert second == pytest.approx(math.pi * (1.7 ** 2 - 1.6 ** 2) * depth, rel=1e-7)
    assert len(calls) > 50
    monkeypatch.setattr(analytic, "POLAR_FORMS", False)
    _, adaptive = run(moves, tools, stock)
    for a, b in zip(maps, adaptive, strict=True):
        assert a.removed_volume == pytest.approx(b.removed_volume, rel=VOLUME_REL, abs=1e-9), a.cl_index


def test_a_bore_under_a_contours_floor_meets_only_its_own_turns(monkeypatch):
    """As fusion-posted/1110_wall's Bore1 under the wall's contour (R = 1.325, rho = 1.475, 0.5 mm a turn,
    posted in 3 decimals): level passes at z = -0.5 cross the hole's top before the bore goes down from
    there. Below its first turn each CL's cells reach beyond the helix's footprint (a disc's box), but
    the helix's earlier turns cap h over the CL's whole footprint below the level passes, which are left
    out of them (.cells.footprint_ceiling); each CL going down dz then removes its closed form,
    pi ((rho + R)^2 - (rho - R)^2) dz."""
    R, rho, pitch = 1.325, 1.475, 0.5
    passes = [LinearMove((0.75, -4.0, 5.0), (0.75, -4.0, -0.5), rapid=True, tool=1),
              LinearMove((0.75, -4.0, -0.5), (0.75, 8.0, -0.5), feed=600.0, tool=1),
              LinearMove((0.75, 8.0, -0.5), (1.5, 8.0, -0.5), feed=600.0, tool=1),
              LinearMove((1.5, 8.0, -0.5), (1.5, -4.0, -0.5), feed=600.0, tool=1)]
    bore = _bore(rho, turns=6, pitch=pitch, decimals=3, z0=-0.5)
    rows = []
    polar = analytic.polar_volume
    monkeypatch.setattr(analytic, "polar_volume", lambda *a: rows.append(a[9]) or polar(*a))
    _, maps = run(passes + bore, {1: FlatEndMill(2 * R, 15)}, BoxStock((-6, -6, -6), (8, 10, 0)))
    assert all(m.engine == "analytic" for m in maps)
    deep = [m for m in maps if m.start[2] <= -0.5 - 2 * pitch and m.position[2] < m.start[2]]
    assert len(deep) >= 20
    for m in deep:
        dz = m.start[2] - m.position[2]
        assert m.removed_volume == pytest.approx(math.pi * ((rho + R) ** 2 - (rho - R) ** 2) * dz, rel=1e-7), m.cl_index
    rows.clear()
    _, maps = run(passes + bore[:8], {1: FlatEndMill(2 * R, 15)}, BoxStock((-6, -6, -6), (8, 10, 0)))
    assert rows and all((r[:, 0] == 1.0).all() for r in rows[-3:])  # the last CLs' cells: the helix's arcs only


@pytest.mark.parametrize("rho,decimals", [(0.375, None), (0.375, 3), (1.475, 3), (2.5, 4)])
def test_helices_in_polar_coordinates_as_the_adaptive_integral(monkeypatch, rho, decimals):
    """Helical bores of a flat end mill (R = 1.325, as fusion-posted/1110_wall's Bore1), exact and rounded
    as posts write them, entering a stock faced 0.5 mm lower on one side by an earlier level pass (a
    level sweep off the axis): each CL's volume, contact areas and rubbing slices as the adaptive
    integral finds them (to its own tolerance)."""
    face = [LinearMove((-4.0, -4.0, 5.0), (-4.0, -4.0, -0.5), rapid=True, tool=1),
            LinearMove((-4.0, -4.0, -0.5), (-4.0, 8.0, -0.5), feed=600.0, tool=1),
            LinearMove((-4.0, 8.0, -0.5), (-4.0, 8.0, 5.0), rapid=True, tool=1)]
    moves = face + _bore(rho, turns=3, pitch=0.5, decimals=decimals, z0=0.2)
    tools, stock = {1: FlatEndMill(2.65, 15)}, BoxStock((-8, -6, -6), (8, 10, 0))
    calls = _spied(monkeypatch)
    _, polar = run(moves, tools, stock, slice_height=0.5)
    assert len(calls) > 20
    monkeypatch.setattr(analytic, "POLAR_FORMS", False)
    _, adaptive = run(moves, tools, stock, slice_height=0.5)
    assert sum(m.removed_volume for m in polar) > 10
    assert_maps_agree(polar, adaptive)


def test_another_tool_or_an_arc_off_the_axis_stays_adaptive(monkeypatch):
    """A ball end mill's helix, and a flat one's helix beside an earlier arc about another centre: the
    cells they shape are not integrated in polar coordinates (the lower surfaces are not linear in the
    angle there), and their volumes stay those of the adaptive integral."""
    calls = _spied(monkeypatch)
    run(_bore(1.0, turns=2, pitch=1.0), {1: BallEndMill(6, 20)}, BoxStock((-8, -8, -6), (8, 8, 0)))
    assert not calls
    off = [LinearMove((-2.0, 2.0, 5.0), (-2.0, 2.0, -1.5), rapid=True, tool=1),
           ArcMove((-2.0, 2.0, -1.5), (-2.0, 2.0, -2.5), feed=600.0, tool=1, center=(-0.5, 2.0, -1.5)),
           LinearMove((-2.0, 2.0, -2.5), (-2.0, 2.0, 5.0), rapid=True, tool=1)]
    moves = off + _bore(1.0, turns=2, pitch=1.0)
    tools, stock = {1: FlatEndMill(6, 20)}, BoxStock((-8, -8, -6), (8, 8, 0))
    _, maps = run(moves, tools, stock)
    monkeypatch.setattr(analytic, "POLAR_FORMS", False)
    _, adaptive = run(moves, tools, stock)
    for a, b in zip(maps, adaptive, strict=True):
        assert a.removed_volume == pytest.approx(b.removed_volume, rel=VOLUME_REL, abs=1e-9), a.cl_index


def test_real_helical_bores_in_polar_coordinates_as_the_adaptive_integral(monkeypatch):
    """fusion-posted/1110_wall_265bit.nc, Bore1's CLs 2495-2544 (its lead-in and first helix turns, rho
    1.475) and 4100-4129 (a helix of rho 0.375 over one of 0.275 down the same hole): each CL's volume
    as the adaptive integral finds it."""
    import real_programs
    from shared_data import DATA

    if not (DATA / "fusion-posted" / "1110_wall_265bit.nc").is_file():
        pytest.skip("shared data missing")
    toolpath, stock, default = real_programs.load(next(p for p in real_programs.PROGRAMS if p.name == "1110_wall"))

    def window(start: int, n: int) -> list:
        engine = analytic.AnalyticEngine(analytic.EngineOptions())
        engine.start(stock)
        maps = engine.process(toolpath, default, start_at=start)
        return [next(maps) for _ in range(n)]

    calls = _spied(monkeypatch)
    polar = window(2495, 50) + window(4100, 30)
    assert len(calls) >= 60  # most CLs hold a polar cell (often one: the earlier turns cap h over the rest)
    monkeypatch.setattr(analytic, "POLAR_FORMS", False)
    adaptive = window(2495, 50) + window(4100, 30)
    assert sum(m.removed_volume for m in polar) > 10
    for a, b in zip(polar, adaptive, strict=True):
        assert a.cl_index == b.cl_index
        assert a.removed_volume == pytest.approx(b.removed_volume, rel=VOLUME_REL, abs=1e-9), a.cl_index


def test_polar_cells_as_horizontal_slices_find_them(monkeypatch):
    """Each cell of a helical bore's CLs entering a faced stock (the case whose kink, where the helix's
    tip crosses the stock's top at an end of a window, once cost 1e-7 of a CL), integrated tightly in
    polar coordinates and as the integral over heights of exact cross-sections (tests' sliced_oracle,
    a third way): the same volume to 1e-12 mm³."""
    from tests.engines.analytic.sliced_oracle import sliced_volume

    cells = []
    polar = analytic.polar_volume
    monkeypatch.setattr(analytic, "polar_volume", lambda *a: cells.append(a) or polar(*a))
    face = [LinearMove((-4.0, -4.0, 5.0), (-4.0, -4.0, -0.5), rapid=True, tool=1),
            LinearMove((-4.0, -4.0, -0.5), (-4.0, 8.0, -0.5), feed=600.0, tool=1),
            LinearMove((-4.0, 8.0, -0.5), (-4.0, 8.0, 5.0), rapid=True, tool=1)]
    run(face + _bore(0.375, turns=1, pitch=0.5, z0=0.2), {1: FlatEndMill(2.65, 15)},
        BoxStock((-8, -6, -6), (8, 10, 0)), slice_height=0.5)
    assert len(cells) > 20
    for a in cells[::3]:
        x0, x1, y0, y1, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt, _, _, edges = a
        exact = polar(*a[:16], 1e-14, 1e-14, edges)[0]
        sliced = sliced_volume(x0, x1, y0, y1, S, P, R, C, CB, PP, NPC, RR, zb, zt, 1e-14, 1e-14, edges)[0]
        assert exact == pytest.approx(sliced, rel=1e-10, abs=1e-12)


def _entry_and_slot(rho: float, length: float, decimals: int | None = None) -> tuple[list, float]:
    """A helical entry (R = 3, 3 turns of radius ``rho`` about (1, 2), 1 mm a turn, from 0.5 mm above the
    stock down to -2.5) whose last turn leaves a ramped ledge, a level slot out along +x from the
    helix's end ``length`` mm and back in moves of 0.5 mm (as a trochoid's chords), then a level circle
    about the axis at the bottom; and the depth of the level cuts (mm)."""
    bore = _bore(rho, turns=3, pitch=1.0, decimals=decimals, z0=0.5)
    end = bore[-3].end
    xs = [end[0] + 0.5 * i for i in range(int(length / 0.5) + 1)]
    xs = xs + xs[-2::-1]
    slot = [LinearMove((a, end[1], end[2]), (b, end[1], end[2]), feed=600.0, tool=1) for a, b in zip(xs, xs[1:])]
    return bore[:-2] + slot + bore[-2:], -end[2]


def _polar_cells_of_level_cls(monkeypatch) -> list:
    cells = []
    polar = analytic.polar_volume
    monkeypatch.setattr(analytic, "polar_volume",
                        lambda *a: (a[6][0] == 0.0 and a[6][3] == a[6][6] and cells.append(a)) or polar(*a))
    return cells


def test_a_slot_out_of_a_helical_entrys_ledge_removes_the_union_of_disk_and_slot(monkeypatch):
    """A flat end mill (R = 3) enters down a helix of radius rho = 1.2 to depth D = 2.5, cuts a level slot
    from the helix's end out along +x and back, then goes round once at the bottom: the slot's CLs
    meet the ramped ledge the helix's last turn left, in cells integrated about the helix's axis
    (.polar with a level CL), and all CLs together remove the disk of radius a = rho + R united with
    the slot's stadium, times D. Both are symmetric about the slot's line, so the union's width at x is
    the larger of theirs; beyond the disk's x = b = sqrt(a^2 - R^2) the slot is wider:
    pi a^2 + 2 (R (x1 - b) - (pi a^2 / 4 - b R / 2 - a^2 asin(b / a) / 2)) + pi R^2 / 2 per mm of depth,
    with ``x1`` the slot's far end (from the axis)."""
    R, rho, length = 3.0, 1.2, 8.0
    moves, depth = _entry_and_slot(rho, length)
    cells = _polar_cells_of_level_cls(monkeypatch)
    _, maps = run(moves, {1: FlatEndMill(2 * R, 20)}, BoxStock((-12, -12, -10), (16, 12, 0)), slice_height=1.0)
    a, x1 = rho + R, rho + length
    b = math.sqrt(a * a - R * R)
    beyond = R * (a - b) - (math.pi * a * a / 4 - b * R / 2 - a * a * math.asin(b / a) / 2)
    area = math.pi * a * a + 2 * (beyond + R * (x1 - a)) + math.pi * R * R / 2
    assert sum(m.removed_volume for m in maps) == pytest.approx(area * depth, rel=1e-7)
    assert all(m.engine == "analytic" for m in maps)
    assert len(cells) > 10  # the slot's CLs: level, about the helix's axis


@pytest.mark.parametrize("rho,decimals", [(1.2, None), (1.475, 3), (4.0, 3)])
def test_level_cls_about_an_earlier_helixs_axis_as_the_adaptive_integral(monkeypatch, rho, decimals):
    """The slot out of a helical entry's ledge (above; rho < R and rho > R, exact and rounded as posts write
    them): each CL's volume, contact areas and rubbing slices as the adaptive integral finds them."""
    moves, _ = _entry_and_slot(rho, 8.0, decimals)
    tools, stock = {1: FlatEndMill(6.0, 20)}, BoxStock((-12, -12, -10), (16, 12, 0))
    cells = _polar_cells_of_level_cls(monkeypatch)
    _, polar = run(moves, tools, stock, slice_height=0.5)
    assert len(cells) > 10
    monkeypatch.setattr(analytic, "POLAR_FORMS", False)
    _, adaptive = run(moves, tools, stock, slice_height=0.5)
    assert_maps_agree(polar, adaptive)


def test_level_cls_polar_cells_as_horizontal_slices_find_them(monkeypatch):
    """Each cell of the slot's level CLs out of a helical entry's ledge, integrated tightly about the
    helix's axis and as the integral over heights of exact cross-sections (tests' sliced_oracle): the
    same volume to 1e-10."""
    from tests.engines.analytic.sliced_oracle import sliced_volume

    moves, _ = _entry_and_slot(1.475, 8.0, decimals=3)
    cells = _polar_cells_of_level_cls(monkeypatch)
    run(moves, {1: FlatEndMill(6.0, 20)}, BoxStock((-12, -12, -10), (16, 12, 0)), slice_height=0.5)
    assert len(cells) > 10
    from fusioncut.engines.analytic.polar import polar_volume
    removed = 0.0
    for a in cells[::2]:
        x0, x1, y0, y1, circles, segments, S, P, R, C, CB, PP, NPC, RR, zb, zt, _, _, edges = a
        exact = polar_volume(*a[:16], 1e-14, 1e-14, edges)[0]
        sliced = sliced_volume(x0, x1, y0, y1, S, P, R, C, CB, PP, NPC, RR, zb, zt, 1e-14, 1e-14, edges)[0]
        assert exact == pytest.approx(sliced, rel=1e-10, abs=1e-12)
        removed += exact
    assert removed > 1.0


def test_a_turn_of_an_earlier_helix_holds_its_annulus():
    """polar.held_annuli: an earlier helix on the CL's axis holds [max(rho - R, 0), rho + R] where the highest
    tip of its lowest turn is no higher than the CL's lowest tip; less than a turn, a higher turn, or
    another axis hold nothing."""
    import numpy as np

    from fusioncut.engines.analytic.polar import held_annuli
    from fusioncut.engines.analytic.sweeps import arc_row

    P = np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]])  # a flat end mill's lower profile (f = 0)
    PP, NPC, RR = P[None], np.array([1]), np.array([1.0])
    own = arc_row((2.5, 0, -3.0), (2.5, 0, -3.1), (0, 0), 2.5, 0.0, 0.5, 0)
    down = arc_row((0.5, 0, 0.0), (0.5, 0, -5.0), (0, 0), 0.5, 0.0, 4 * 2 * np.pi, 0)  # 4 turns, 1.25 mm a turn
    assert held_annuli(own, P, down[None], PP, NPC, RR).tolist() == [[0.0, 1.5]]  # its last turn tops at -3.75
    wide = arc_row((2.0, 0, 0.0), (2.0, 0, -5.0), (0, 0), 2.0, 0.0, 4 * 2 * np.pi, 0)
    assert held_annuli(own, P, wide[None], PP, NPC, RR).tolist() == [[1.0, 3.0]]
    shallow = arc_row((0.5, 0, 0.0), (0.5, 0, -4.0), (0, 0), 0.5, 0.0, 4 * 2 * np.pi, 0)  # tops at -3 > -3.1
    part = arc_row((0.5, 0, 0.0), (0.5, 0, -5.0), (0, 0), 0.5, 0.0, 6.0, 0)  # less than a turn
    aside = arc_row((0.5, 1e-6, 0.0), (0.5, 1e-6, -5.0), (0, 1e-6), 0.5, 0.0, 4 * 2 * np.pi, 0)
    for row in (shallow, part, aside):
        assert held_annuli(own, P, row[None], PP, NPC, RR).shape == (0, 2)
