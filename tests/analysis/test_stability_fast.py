"""The compiled and reduced stability computations equal the reference ones they replace in the table and
the lobes: the ZOA limit and nearest stable speed of many CLs in one pass against ``zoa_a_lim`` and
``nearest_stable_rpm`` (vectorised NumPy, one CL at a time)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fusioncut.analysis.dynamics import Mode, ToolDynamics
from fusioncut.analysis.stability import (chatter_grid, nearest_stable_rpm, zoa_a_lim, zoa_a_lim_many,
                                          zoa_limit_and_nearest_many)
from fusioncut.errors import InputError

KTC = 600.0
BENCH = ToolDynamics((Mode(922.0, 0.011, 0.03993 * (2 * math.pi * 922.0) ** 2),), ())
EXAMPLE = ToolDynamics((Mode(600.0, 0.035, 5.6e6), Mode(1450.0, 0.02, 1.4e7)), (Mode(660.0, 0.03, 5.7e6),))


@pytest.mark.parametrize("dyn, flutes", [(BENCH, 2), (EXAMPLE, 3)])
def test_compiled_limits_and_nearest_speeds_equal_the_reference(dyn, flutes) -> None:
    """Random directional matrices, speeds and depths (about half of them unstable by ZOA, so that the
    nearest-speed search runs): limits to 1e-12, nearest speeds to 1e-9 (both NaN where no speed in the
    range is stable), the CL's own speed where it is stable."""
    rng = np.random.default_rng(11)
    grid = chatter_grid(dyn)
    count = 60
    alphas = rng.normal(0.0, 1.5, (count, 2, 2))
    speeds = rng.uniform(3000.0, 25000.0, count)
    lim_ref = np.array([zoa_a_lim(a, grid, KTC, flutes, n)[0] for a, n in zip(alphas, speeds)])
    depth = np.where(np.isfinite(lim_ref), lim_ref, 1.0) * rng.uniform(0.5, 3.0, count)
    lo, hi = 0.6 * speeds, 1.4 * speeds
    lim, near = zoa_limit_and_nearest_many(alphas, grid, KTC, flutes, speeds, depth, lo, hi)
    np.testing.assert_allclose(lim, lim_ref, rtol=1e-12)
    np.testing.assert_allclose(zoa_a_lim_many(alphas, grid, KTC, flutes, speeds), lim_ref, rtol=1e-12)
    ref = np.array([nearest_stable_rpm(a, grid, KTC, flutes, n, d, l, h)
                    for a, n, d, l, h in zip(alphas, speeds, depth, lo, hi)])
    unstable = ~(lim_ref > depth)
    assert 15 < unstable.sum() < count - 5 and np.isfinite(ref[unstable]).sum() > 10
    np.testing.assert_allclose(near, ref, rtol=1e-9, equal_nan=True)
    assert np.all(near[~unstable] == speeds[~unstable])


def test_compiled_nearest_speed_refuses_a_range_of_too_many_lobes() -> None:
    grid = chatter_grid(BENCH)
    slot = np.array([[[-math.pi / 3, -math.pi], [math.pi, -math.pi / 3]]])
    with pytest.raises(InputError, match="lobes; narrow it"):
        zoa_limit_and_nearest_many(slot, grid, KTC, 2, 300.0, 50.0, 1.0, 600.0)
    with pytest.raises(InputError, match="lobes; narrow it"):
        nearest_stable_rpm(slot[0], grid, KTC, 2, 300.0, 50.0, 1.0, 600.0)
