"""The solver against the independent oracle (tests/oracle.py) on seeded random pairs.

Per family, 200 pairs (1200 in all). For every pair:

* clear hit (the oracle's gap goes at least 1e-8 box sizes below zero within
  1e-6 of the range after the crossing): the solver's t agrees with the
  oracle's to 1e-9 of the range, and mpmath brackets it: apart at t - 1e-9,
  intersecting at t + 1e-9 (range units);
* clear miss (advancement reaches the end and never sees the gap below 2e-7
  box sizes, so the distance stays above 1e-7): the solver returns None;
* otherwise (shallow): if the solver reports a hit, mpmath puts its gap within
  1e-9 box sizes of touching, and it is not later than the oracle's crossing.
"""

from __future__ import annotations

import numpy as np
import pytest
from cases import FAMILIES, make_case
from oracle import mp_gap, reference

from bullet_boxccd import Box, QuadraticMotion, time_of_impact

N_PER_FAMILY = 200
TIME_TOL = 1e-9  # of the range
GAP_TOL = 1e-9  # of the smaller box's size


def solve(case):
    return time_of_impact(Box(case.lo_a, case.hi_a), QuadraticMotion(case.coeffs_a),
                          Box(case.lo_b, case.hi_b), QuadraticMotion(case.coeffs_b), (case.t0, case.t1))


def check_case(case):
    """Returns "hit", "miss" or "shallow"; raises AssertionError with a repro on disagreement."""
    ref = reference(case)
    got = solve(case)
    L, span = case.size(), case.t1 - case.t0
    ctx = f"\noracle: {ref}\nsolver: {got}\n{case.repro()}"
    if ref.outcome == "hit" and ref.depth_after <= -1e-8 * L:
        assert got is not None, "missed a clear hit" + ctx
        assert abs(got.t - ref.t_hit) <= TIME_TOL * span, "contact time disagrees" + ctx
        if got.t > case.t0:
            assert mp_gap(case, got.t - TIME_TOL * span) > 0, "late by more than 1e-9 (mpmath)" + ctx
        assert mp_gap(case, min(case.t1, got.t + TIME_TOL * span)) <= 0, "early by more than 1e-9 (mpmath)" + ctx
        assert got.initial == (ref.t_hit == case.t0), ctx
        return "hit"
    if ref.outcome == "miss" and ref.min_gap > 2e-7 * L:
        assert got is None, "false hit on a clear miss" + ctx
        return "miss"
    if got is not None:
        assert mp_gap(case, got.t) <= GAP_TOL * L, "shallow hit reported where the boxes are apart" + ctx
        if ref.outcome == "hit":
            assert got.t <= ref.t_hit + TIME_TOL * span, "shallow hit reported late" + ctx
    else:
        assert ref.outcome != "hit" or ref.depth_after > -1e-8 * L, ctx
    return "shallow"


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
        from oracle import world_vertices
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
