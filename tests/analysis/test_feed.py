"""Feed advice against closed forms: the feed at which a straight-tooth slot reaches a force, chip,
power or MRR limit is known by hand; with edge forces and helix the advised feed must put the peak
force exactly on the limit. Smoothing is checked for its promises (never raises a feed, keeps dips,
no short stretches) over random sequences."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusioncut.analysis.feed import FeedAdvice, FeedLimit, advise_feeds, largest_feasible, merge_short_runs
from fusioncut.analysis.forces import (
    CuttingCoefficients,
    compute_cl_forces,
    engagement_maps_from_results,
    peak_chip_thickness,
)
from fusioncut.analysis.materials import AL7075_T6_CARBIDE as K
from fusioncut.errors import InputError, SourceLocation
from fusioncut.model.options import EngineOptions
from fusioncut.io.results import ResultWriter, load_results
from fusioncut.model import (
    AngleInterval,
    BallEndMill,
    CLStatus,
    EngagementMap,
    FlatEndMill,
    SliceEngagement,
)

RPM = 6000.0
N = 2
A = 3.0  # axial depth, mm
R = 5.0
NO_EDGE = CuttingCoefficients(ktc=800.0, krc=300.0, kac=120.0, kte=0.0, kre=0.0, kae=0.0)
STRAIGHT = FlatEndMill(diameter=2 * R, flute_length=20.0, flutes=N, helix_angle=0.0)
HELICAL = FlatEndMill(diameter=2 * R, flute_length=20.0, flutes=N, helix_angle=30.0)


def cl(i: int, intervals=((0.0, 180.0),), *, feed: float | None = 1000.0, status=CLStatus.ENGAGED,
       depth: float = A, n: int = 6, dx: float = 1.0, dz_move: float = 0.0, line: int | None = None,
       removed: float = 1.0) -> EngagementMap:
    """A CL moving +x by ``dx`` (and ``dz_move`` in z) with the same arcs on ``n`` equal bands over ``depth``."""
    h = depth / n
    ivs = tuple(AngleInterval(a, b) for a, b in intervals)
    slices = tuple(SliceEngagement(z=(k + 0.5) * h, z_machine=(k + 0.5) * h, radius=R, intervals=ivs) for k in range(n))
    engaged = status == CLStatus.ENGAGED and intervals
    return EngagementMap(
        cl_index=i, position=(i * dx, 0.0, dz_move), start=((i - 1) * dx, 0.0, 0.0), tool="T1",
        spindle=STRAIGHT.spindle, feed_angle=0.0, status=status, feed=feed,
        source=SourceLocation("p.nc", 10 + i if line is None else line), slices=slices if engaged else (),
        axial_range=(0.0, depth) if engaged else (0.0, 0.0), removed_volume=removed if engaged else 0.0,
    )


def advise(maps, limit, tool=STRAIGHT, coeffs=NO_EDGE, **kw) -> FeedAdvice:
    kw.setdefault("quantum", 0.0)
    kw.setdefault("min_run_length", 0.0)
    return advise_feeds(maps, tool, coeffs, limit, rpm=RPM, **kw)


def feed_from_c(c: float) -> float:
    return c * RPM * N


# --------------------------------------------------------------------------------------------------
# exact limits


def test_largest_feasible_closed_forms():
    # |2c + 1| <= 5  ->  c <= 2
    assert largest_feasible(np.array([[2.0]]), np.array([[1.0]]), 5.0) == pytest.approx(2.0)
    # |(3c, 4c)| <= 10 -> c <= 2; with a sample where nothing cuts and the edge part is 0
    a = np.array([[3.0, 4.0], [0.0, 0.0]])
    assert largest_feasible(a, np.zeros((2, 2)), 10.0) == pytest.approx(2.0)
    # the edge part alone is over the limit where the tooth does not cut: unreachable
    assert math.isnan(largest_feasible(a, np.array([[0.0, 0.0], [11.0, 0.0]]), 10.0))
    # nothing depends on c and nothing exceeds: unbounded
    assert largest_feasible(np.zeros((3, 2)), np.ones((3, 2)), 10.0) == math.inf
    # e opposes a: |c - 3| <= 1 holds for c in [2, 4]: the largest is 4
    assert largest_feasible(np.array([[1.0]]), np.array([[-3.0]]), 1.0) == pytest.approx(4.0)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.5, 50.0))
def test_largest_feasible_puts_the_peak_on_the_limit(seed, limit):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(40, 3))
    e = rng.normal(size=(40, 3)) * 0.1
    c = largest_feasible(a, e, limit)
    peak = lambda x: np.linalg.norm(x * a + e, axis=1).max()  # noqa: E731
    if math.isnan(c):
        assert peak(0.0) > limit
    else:
        assert peak(c) == pytest.approx(limit, rel=1e-9)
        assert peak(c * (1 + 1e-6) + 1e-12) > limit


def test_force_limit_straight_slot_closed_form():
    # one tooth in the cut at a time; at phi = 90 deg |F| = a c sqrt(Ktc² + Krc² + Kac²)
    limit = 900.0
    c = limit / (A * math.sqrt(NO_EDGE.ktc ** 2 + NO_EDGE.krc ** 2 + NO_EDGE.kac ** 2))
    adv = advise([cl(1)], FeedLimit(max_force=limit, max_feed=1e6))
    row = adv.table.iloc[0]
    assert row["advised_feed_mm_min"] == pytest.approx(feed_from_c(c), rel=1e-9)
    assert row["reason"] == "force" and row["limiting_quantity"] == "force"
    assert row["limiting_ratio"] == pytest.approx(1.0, rel=1e-9)
    assert row["force_peak_advised_N"] == pytest.approx(limit, rel=1e-9)
    assert row["force_peak_programmed_N"] == pytest.approx(limit * 1000.0 / feed_from_c(c), rel=1e-9)


def test_force_limit_with_edge_forces_and_helix_is_exact():
    limit = 700.0
    maps = [cl(1), cl(2, ((0.0, 70.0),)), cl(3, ((120.0, 180.0),))]
    adv = advise(maps, FeedLimit(max_force=limit, max_feed=1e6), tool=HELICAL, coeffs=K)
    for m, row in zip(maps, adv.table.itertuples()):
        c = row.advised_feed_mm_min / (RPM * N)
        f = compute_cl_forces(m, HELICAL, K, rpm=RPM, feed_per_tooth=c)
        assert f.resultant_peak == pytest.approx(limit, rel=1e-9)
        f_more = compute_cl_forces(m, HELICAL, K, rpm=RPM, feed_per_tooth=c * 1.0001)
        assert f_more.resultant_peak > limit
    # less engagement, more feed
    feeds = adv.table["advised_feed_mm_min"].to_numpy()
    assert feeds[1] > feeds[0] and feeds[2] > feeds[0]


@pytest.mark.parametrize("arc,thinning", [((0.0, 180.0), 1.0), ((0.0, 60.0), math.sin(math.radians(60))),
                                          ((150.0, 180.0), 0.5), ((200.0, 250.0), 0.0)])
def test_chip_limit_and_chip_thinning(arc, thinning):
    h = 0.05
    adv = advise([cl(1, (arc,))], FeedLimit(max_chip_thickness=h, max_feed=1e6))
    row = adv.table.iloc[0]
    if thinning == 0.0:  # behind the tool (sin < 0): no chip, nothing limits the feed
        assert row["limit_feed_mm_min"] == math.inf and row["reason"] == "max_feed"
        return
    assert row["advised_feed_mm_min"] == pytest.approx(feed_from_c(h / thinning), rel=1e-9)
    assert row["chip_peak_advised_mm"] == pytest.approx(h, rel=1e-9)


def test_chip_thickness_of_a_ball_end_mill():
    # a ball end mill's edge leans: h = c sin(phi) sin(kappa); near the tip kappa -> 0
    ball = BallEndMill(diameter=10.0, flute_length=20.0)
    m = cl(1, depth=1.0, n=4)
    got = peak_chip_thickness(m, ball, 0.1)
    # the top band [0.75, 1] has the largest kappa: sin k = dz / chord over the band
    r0, r1 = ball.profile().radius_at(0.75), ball.profile().radius_at(1.0)
    assert got == pytest.approx(0.1 * 0.25 / math.hypot(0.25, r1 - r0), rel=1e-12)


def test_power_and_mrr_limits():
    # straight tooth, no edge force: peak torque = Ktc a c r (one tooth at phi = 90)
    p = 400.0
    omega = RPM * 2 * math.pi / 60
    c = p / (omega * NO_EDGE.ktc * A * R * 1e-3)
    adv = advise([cl(1)], FeedLimit(max_power=p, max_feed=1e6))
    assert adv.table["advised_feed_mm_min"].iloc[0] == pytest.approx(feed_from_c(c), rel=1e-9)
    # MRR = V * feed / L: 2 mm³ over 0.5 mm at 3000 mm³/min -> 750 mm/min
    m = cl(1, dx=0.5, removed=2.0)
    adv = advise([m], FeedLimit(max_mrr=3000.0, max_feed=1e6))
    assert adv.table["advised_feed_mm_min"].iloc[0] == pytest.approx(750.0)
    assert adv.table["mrr_advised_mm3_min"].iloc[0] == pytest.approx(3000.0)


def test_the_smallest_limit_wins():
    lim = FeedLimit(max_force=900.0, max_chip_thickness=0.01, max_mrr=1e9, max_feed=1e6)
    row = advise([cl(1)], lim).table.iloc[0]
    assert row["reason"] == "chip" and row["advised_feed_mm_min"] == pytest.approx(feed_from_c(0.01))
    assert row["force_peak_advised_N"] < 900.0 and row["limiting_quantity"] == "chip"


# --------------------------------------------------------------------------------------------------
# clamps, steps, special CLs


def test_clamps_and_unreachable():
    adv = advise([cl(1)], FeedLimit(max_force=900.0, max_feed=2000.0))
    assert adv.table["advised_feed_mm_min"].iloc[0] == 2000.0 and adv.table["reason"].iloc[0] == "max_feed"
    adv = advise([cl(1)], FeedLimit(max_force=900.0, min_feed=1e5, max_feed=1e6))
    assert adv.table["advised_feed_mm_min"].iloc[0] == 1e5 and adv.table["reason"].iloc[0] == "min_feed"
    # the edge forces alone (Kte a, Kre a ~ 180 N) exceed 50 N: no feed meets the limit
    adv = advise([cl(1)], FeedLimit(max_force=50.0, min_feed=100.0, max_feed=1e6), tool=HELICAL, coeffs=K)
    row = adv.table.iloc[0]
    assert row["advised_feed_mm_min"] == 100.0 and "unreachable" in row["note"] and row["limit_feed_mm_min"] == 0
    assert row["limiting_ratio"] > 1


def test_default_feed_range_comes_from_the_program():
    maps = [cl(1, feed=800.0), cl(2, feed=1200.0)]
    adv = advise(maps, FeedLimit(max_force=1e6))
    assert (adv.limit.min_feed, adv.limit.max_feed) == (80.0, 1200.0)
    assert list(adv.table["advised_feed_mm_min"]) == [1200.0, 1200.0]


def test_quantum_rounds_down_in_steps_of_the_programmed_feed():
    limit = 900.0
    exact = advise([cl(1)], FeedLimit(max_force=limit, max_feed=1e6)).table["advised_feed_mm_min"].iloc[0]
    got = advise([cl(1)], FeedLimit(max_force=limit, max_feed=1e6), quantum=0.05).table["advised_feed_mm_min"].iloc[0]
    assert got == pytest.approx(math.floor(exact / 1000.0 / 0.05) * 50.0)
    assert exact - 50.0 < got <= exact


def test_special_cls():
    maps = [
        cl(0, status=CLStatus.RAPID, feed=None),
        cl(1, status=CLStatus.AIR),
        cl(2, status=CLStatus.FAILED),
        cl(3, dz_move=-0.5),  # a ramp: never raised above the programmed feed
        cl(4, dx=0.0, dz_move=-0.5, intervals=((0.0, 360.0),)),  # a plunge
        cl(5, feed=None, status=CLStatus.AIR),  # a feed move without a feed
    ]
    lim = FeedLimit(max_force=1e5, max_feed=5000.0)
    t = advise(maps, lim).table.set_index("cl")
    assert math.isnan(t.at[0, "advised_feed_mm_min"]) and t.at[0, "reason"] == "rapid"
    assert t.at[1, "advised_feed_mm_min"] == 1000.0
    assert t.at[2, "advised_feed_mm_min"] == 1000.0 and t.at[2, "note"] == "failed"
    assert t.at[3, "advised_feed_mm_min"] == 1000.0 and t.at[3, "note"] == "ramp"
    assert t.at[4, "advised_feed_mm_min"] == 1000.0 and t.at[4, "note"] == "plunge"
    assert math.isnan(t.at[5, "advised_feed_mm_min"]) and t.at[5, "note"] == "no-feed"
    t = advise(maps, FeedLimit(max_force=1e5, max_feed=5000.0, air_feed=True, raise_ramps=True)).table.set_index("cl")
    assert t.at[1, "advised_feed_mm_min"] == 5000.0 and t.at[1, "reason"] == "air_feed"
    assert t.at[3, "advised_feed_mm_min"] == 5000.0
    # a ramp is still slowed when a limit needs it
    t = advise([cl(3, dz_move=-0.5)], FeedLimit(max_force=100.0, max_feed=5000.0)).table
    assert t["advised_feed_mm_min"].iloc[0] < 1000.0 and t["reason"].iloc[0] == "force"


def test_no_rpm_and_no_contact_at_the_end():
    m_no_contact = EngagementMap(cl_index=1, position=(1.0, 0.0, 0.0), start=(0.0, 0.0, 0.0), tool="T1",
                                 spindle=STRAIGHT.spindle, feed_angle=0.0, status=CLStatus.ENGAGED, feed=1000.0,
                                 removed_volume=2.0)
    adv = advise_feeds([cl(0), m_no_contact], STRAIGHT, NO_EDGE, FeedLimit(max_force=1e5, max_feed=5000.0),
                       rpm=[None, RPM], quantum=0, min_run_length=0)
    t = adv.table
    assert t["note"].iloc[0] == "no-rpm" and t["advised_feed_mm_min"].iloc[0] == 1000.0
    assert t["note"].iloc[1] == "no-contact-at-end" and t["advised_feed_mm_min"].iloc[1] == 1000.0


@pytest.mark.parametrize("kw,msg", [({}, "at least one limit"), ({"max_force": -1.0}, "max_force"),
                                    ({"max_force": 1.0, "min_feed": 500.0, "max_feed": 100.0}, "above max_feed")])
def test_bad_limits(kw, msg):
    with pytest.raises(InputError, match=msg):
        FeedLimit(**kw)


def test_bad_arguments():
    with pytest.raises(InputError, match="spindle speeds"):
        advise_feeds([cl(1)], STRAIGHT, K, FeedLimit(max_force=1.0), rpm=[RPM, RPM])
    with pytest.raises(InputError, match="quantum"):
        advise_feeds([cl(1)], STRAIGHT, K, FeedLimit(max_force=1.0), rpm=RPM, quantum=1.5)


# --------------------------------------------------------------------------------------------------
# smoothing


def test_merge_short_runs_examples():
    L = np.ones
    # a staircase of short steps down into a long run becomes one step
    v = np.array([1000, 1000, 1000, 950, 700, 550, 450, 450, 450, 450], dtype=float)
    got = merge_short_runs(v, np.array([2, 2, 2, .1, .1, .1, 2, 2, 2, 2]), 1.0)
    assert list(got) == [1000, 1000, 1000, 450, 450, 450, 450, 450, 450, 450]
    # a short peak goes, a short dip stays
    v = np.array([500, 500, 600, 500, 500, 400, 500, 500], dtype=float)
    assert list(merge_short_runs(v, L(8), 2.0)) == [500, 500, 500, 500, 500, 400, 500, 500]
    # nested short peaks fold down level by level
    v = np.array([500, 500, 600, 550, 600, 500, 500], dtype=float)
    assert list(merge_short_runs(v, L(7), 3.5)) == [500] * 7
    # no width: unchanged
    assert list(merge_short_runs(v, L(7), 0.0)) == list(v)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([300.0, 400.0, 450.0, 500.0, 800.0]), st.floats(0.01, 3.0)),
                min_size=1, max_size=40),
       st.floats(0.0, 6.0))
def test_merge_short_runs_promises(pairs, width):
    v = np.array([p[0] for p in pairs])
    lengths = np.array([p[1] for p in pairs])
    out = merge_short_runs(v, lengths, width)
    assert np.all(out <= v)  # never raises a feed
    assert np.all(np.isin(out, v))  # only levels that were there
    # every run is long enough, or lower than each neighbouring run
    starts = [0] + [k for k in range(1, len(out)) if out[k] != out[k - 1]] + [len(out)]
    for a, b in zip(starts, starts[1:]):
        if lengths[a:b].sum() >= width:
            continue
        neighbours = ([out[a - 1]] if a > 0 else []) + ([out[b]] if b < len(out) else [])
        assert all(out[a] < x for x in neighbours)
    # the lowest feed of the input is kept where it was
    assert np.all(out[v == v.min()] == v.min())


def test_smoothing_in_advice_only_lowers_and_stops_at_rapids():
    arcs = [((0.0, 180.0),), ((0.0, 30.0),), ((0.0, 180.0),), ((0.0, 30.0),), ((0.0, 30.0),)]
    maps = [cl(i + 1, a, dx=0.2) for i, a in enumerate(arcs)]
    lim = FeedLimit(max_force=900.0, max_feed=1e6)
    raw = advise(maps, lim).table["advised_feed_mm_min"].to_numpy()
    sm = advise(maps, lim, min_run_length=0.5).table
    got = sm["advised_feed_mm_min"].to_numpy()
    # the slot CLs are dips (kept); the short stretches of lighter cuts between and after them are
    # lowered to the slot's feed: 0.2 mm and 0.4 mm are shorter than 0.5 mm
    assert raw[1] > raw[0] and raw[3] > raw[0]
    assert np.all(got == raw[0]) and list(sm["reason"]) == ["force", "smoothing", "force", "smoothing", "smoothing"]
    # a rapid between two CLs splits the stretches: the short high one after it stays
    maps2 = [cl(1, dx=0.2), cl(2, status=CLStatus.RAPID, feed=None), cl(3, ((0.0, 30.0),), dx=0.2)]
    got2 = advise(maps2, lim, min_run_length=0.5).table["advised_feed_mm_min"].to_numpy()
    assert got2[2] > got2[0]


# --------------------------------------------------------------------------------------------------
# per line, times, and advice from saved results


def test_line_feeds_take_the_smallest_per_line_and_filter_by_file():
    maps = [cl(1, line=5), cl(2, ((0.0, 30.0),), line=5), cl(3, ((0.0, 30.0),), line=6)]
    adv = advise(maps, FeedLimit(max_force=900.0, max_feed=1e6))
    feeds = adv.table["advised_feed_mm_min"].to_numpy()
    assert adv.line_feeds() == {5: pytest.approx(min(feeds[:2])), 6: pytest.approx(feeds[2])}
    assert adv.line_feeds("/some/where/p.nc") == adv.line_feeds()
    assert adv.line_feeds("other.nc") == {}
    assert adv.cycle_time_s("programmed") == pytest.approx(3 * 1.0 / 1000.0 * 60)
    assert adv.cycle_time_s() == pytest.approx(sum(60.0 / feeds))
    assert adv.feed_changes() == 1 and adv.feed_changes("programmed") == 0


def test_advice_from_saved_results_equals_advice_from_maps(tmp_path):
    # engine-style slices: cells of dz = 1 mm, the top one clipped to the contact (ap = 2.5 mm)
    def engine_cl(i: int, arc) -> EngagementMap:
        zs = [0.5, 1.5, 2.25]
        slices = tuple(SliceEngagement(z=z, z_machine=z - 10, radius=R, intervals=(AngleInterval(*arc),)) for z in zs)
        return EngagementMap(cl_index=i, position=(float(i), 0.0, -10.0), start=(i - 1.0, 0.0, -10.0), tool="T1",
                             spindle=STRAIGHT.spindle, feed_angle=0.0, status=CLStatus.ENGAGED, feed=1000.0,
                             source=SourceLocation("p.nc", 3 + i), slices=slices, axial_range=(0.0, 2.5),
                             removed_volume=1.0)

    maps = [engine_cl(i, arc) for i, arc in enumerate([(0.0, 180.0), (20.0, 180.0), (90.0, 180.0)], start=1)]
    with ResultWriter(tmp_path, options=EngineOptions(slice_height=1.0)) as w:
        for m in maps:
            w.add(m)
    results = load_results(tmp_path)
    assert results.slice_height == 1.0
    rebuilt = engagement_maps_from_results(results)
    assert [m.axial_range for m in rebuilt] == [pytest.approx((0.0, 2.5))] * 3
    lim = FeedLimit(max_force=600.0, max_feed=1e6)
    a = advise_feeds(results, HELICAL, K, lim, rpm=RPM, quantum=0, min_run_length=0)
    b = advise_feeds(maps, HELICAL, K, lim, rpm=RPM, dz=1.0, quantum=0, min_run_length=0)
    np.testing.assert_allclose(a.table["advised_feed_mm_min"], b.table["advised_feed_mm_min"], rtol=1e-12)
    assert a.slice_height == 1.0


def test_advice_from_results_uses_their_recorded_speeds_and_slice_height(tmp_path):
    """A folder recording each CL's spindle speed and the slice height needs neither: the advice equals
    the advice of the maps with those speeds; a slice height that disagrees is refused."""

    maps = [cl(i, (arc,)) for i, arc in enumerate([(0.0, 180.0), (20.0, 180.0), (90.0, 180.0)], start=1)]
    speeds = [6000.0, 9000.0, None]
    with ResultWriter(tmp_path, tools={"T1": HELICAL}, options=EngineOptions(slice_height=A / 6)) as w:
        for m, n in zip(maps, speeds):
            w.add(m, length_mm=1.0, spindle_rpm=n)
    results = load_results(tmp_path)
    lim = FeedLimit(max_force=600.0, max_feed=1e6)
    a = advise_feeds(results, HELICAL, K, lim, quantum=0, min_run_length=0)
    b = advise_feeds(maps, HELICAL, K, lim, rpm=speeds, dz=A / 6, lengths=[1.0] * 3, quantum=0, min_run_length=0)
    np.testing.assert_allclose(a.table["advised_feed_mm_min"], b.table["advised_feed_mm_min"], rtol=1e-12)
    assert a.slice_height == pytest.approx(A / 6)
    assert a.table["advised_feed_mm_min"].iloc[0] != a.table["advised_feed_mm_min"].iloc[1]
    with pytest.raises(InputError, match="slice height"):
        advise_feeds(results, HELICAL, K, lim, dz=1.0)


def test_a_plunge_over_the_limit_keeps_its_feed():
    # a plunge (no horizontal feed) with edge forces over the limit: no feed helps, none is imposed
    plunge = cl(4, dx=0.0, dz_move=-0.5, intervals=((0.0, 90.0),))
    row = advise([plunge], FeedLimit(max_force=20.0, min_feed=100.0, max_feed=5000.0), tool=HELICAL,
                 coeffs=K).table.iloc[0]
    assert row["force_peak_programmed_N"] > 20.0
    assert row["advised_feed_mm_min"] == 1000.0 and row["note"] == "unreachable plunge"
    assert row["force_peak_advised_N"] == row["force_peak_programmed_N"]
