"""The solver against the independent oracle (bullet_boxccd.testing) on seeded random
pairs: per family, 200 pairs (1200 in all), each judged by ``check_answer`` (clear hits
agree to 1e-9 of the range and mpmath brackets them, clear misses are None, shallow hits
are within 1e-9 box sizes of touching and never late)."""

from __future__ import annotations

import numpy as np
import pytest
from cases import FAMILIES, make_case

from bullet_boxccd import Box, QuadraticMotion, time_of_impact
from bullet_boxccd.testing import check_answer

N_PER_FAMILY = 200


def solve(case):
    return time_of_impact(Box(case.lo_a, case.hi_a), QuadraticMotion(case.coeffs_a),
                          Box(case.lo_b, case.hi_b), QuadraticMotion(case.coeffs_b), (case.t0, case.t1))


def check_case(case):
    """Returns "hit", "miss" or "shallow"; raises AssertionError with a repro on disagreement."""
    return check_answer(case, solve(case))


@pytest.mark.parametrize("family", FAMILIES)
def test_agrees_with_oracle(family):
    outcomes = [check_case(make_case(seed, family)) for seed in range(N_PER_FAMILY)]
    counts = {k: outcomes.count(k) for k in ("hit", "miss", "shallow")}
    # The comparison must be decisive: shallow cases are the exception.
    assert counts["shallow"] <= 0.05 * N_PER_FAMILY, counts
    assert counts["hit"] >= 0.15 * N_PER_FAMILY and counts["miss"] >= 0.15 * N_PER_FAMILY, counts


def test_contact_point_and_normal_are_consistent_with_the_oracle():
    """At a clear hit the reported point lies on both boxes' surfaces (to 1e-9 of
    their size) and the normal separates them just before the contact."""
    checked = 0
    for seed in range(60):
        case = make_case(seed, "rotating")
        got = solve(case)
        if got is None or got.initial:
            continue
        L = case.size()
        from bullet_boxccd.testing import world_vertices
        for coeffs, lo, hi in ((case.coeffs_a, case.lo_a, case.hi_a), (case.coeffs_b, case.lo_b, case.hi_b)):
            M = coeffs[0] + got.t * (coeffs[1] + got.t * coeffs[2])
            p_local = np.linalg.solve(M[:3, :3], got.point - M[:3, 3])
            outside = np.maximum(lo - p_local, p_local - hi)
            assert np.all(outside <= 1e-9 * np.max(hi - lo)), (seed, outside)
        t_before = got.t - 1e-6 * (case.t1 - case.t0)
        VA = world_vertices(case.coeffs_a, case.lo_a, case.hi_a, t_before)
        VB = world_vertices(case.coeffs_b, case.lo_b, case.hi_b, t_before)
        assert (VB @ got.normal).min() - (VA @ got.normal).max() >= -1e-6 * L, seed
        assert abs(np.linalg.norm(got.normal) - 1.0) < 1e-12
        checked += 1
    assert checked >= 20
