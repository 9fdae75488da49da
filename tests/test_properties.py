"""Invariances of the answer (hypothesis, deterministic profile): a rigid transform
applied to both motions, swapping the boxes, and a linear change of time. Each
example's first answer is also judged against the oracle (a real first contact,
or a real miss), so a solver that is consistently wrong fails here too."""

from __future__ import annotations

import numpy as np
from cases import FAMILIES, make_case, pose
from hypothesis import given
from hypothesis import strategies as st

from bullet_boxccd import Box, QuadraticMotion, time_of_impact
from bullet_boxccd.motion import rotation_matrix
from bullet_boxccd.testing import check_answer, mp_gap

cases = st.builds(make_case, st.integers(0, 10**6), st.sampled_from(FAMILIES))


def solve(case, m_a=None, m_b=None, swap=False, t_range=None):
    a, b = Box(case.lo_a, case.hi_a), Box(case.lo_b, case.hi_b)
    m_a = m_a or QuadraticMotion(case.coeffs_a)
    m_b = m_b or QuadraticMotion(case.coeffs_b)
    t_range = t_range or (case.t0, case.t1)
    return time_of_impact(b, m_b, a, m_a, t_range) if swap else time_of_impact(a, m_a, b, m_b, t_range)


def same_answer(case, c1, c2, t_map=lambda t: t):
    """Both miss, or both hit at the same time to 1e-9 of the range; where they
    differ, the pair is within the touching tolerance (a shallow case)."""
    span = case.t1 - case.t0
    if c1 is None and c2 is None:
        return
    if c1 is not None and c2 is not None and abs(c1.t - t_map(c2.t)) <= 1e-9 * span:
        return
    for c, f in ((c1, lambda t: t), (c2, t_map)):
        if c is not None:
            assert mp_gap(case, f(c.t)) <= 1e-9 * case.size(), (c1, c2, case.repro())


@given(cases, st.floats(-np.pi, np.pi), st.tuples(*[st.floats(-1e3, 1e3)] * 3))
def test_invariant_under_a_shared_rigid_transform(case, angle, shift):
    T = pose(rotation_matrix((0.3, -0.5, 0.8), angle), np.array(shift) * case.size())
    c1 = solve(case)
    check_answer(case, c1)
    c2 = solve(case, QuadraticMotion(case.coeffs_a).transformed(T), QuadraticMotion(case.coeffs_b).transformed(T))
    same_answer(case, c1, c2)
    if c1 is not None and c2 is not None and abs(c1.t - c2.t) <= 1e-9 * (case.t1 - case.t0) \
            and c1.feature == c2.feature:
        np.testing.assert_allclose(T[:3, :3] @ c1.normal, c2.normal, atol=1e-6)


@given(cases)
def test_swapping_the_boxes_flips_the_normal(case):
    c1, c2 = solve(case), solve(case, swap=True)
    check_answer(case, c1)
    same_answer(case, c1, c2)
    if c1 is not None and c2 is not None and c1.t == c2.t and not c1.initial:
        swapped = {"OV": "VO", "VO": "OV", "EE": "EE"}[c1.feature.kind]
        if c2.feature == (swapped, c1.feature.b, c1.feature.a):
            np.testing.assert_allclose(c1.normal, -c2.normal, atol=1e-9)


@given(cases, st.floats(0.01, 100.0), st.floats(-50.0, 50.0))
def test_linear_change_of_time(case, scale, offset):
    # u = (t - offset) / scale runs over the new range; M'(u) = M(scale u + offset).
    m_a = QuadraticMotion(case.coeffs_a).reparametrized(scale, offset)
    m_b = QuadraticMotion(case.coeffs_b).reparametrized(scale, offset)
    u_range = ((case.t0 - offset) / scale, (case.t1 - offset) / scale)
    c1 = solve(case)
    check_answer(case, c1)
    c2 = solve(case, m_a, m_b, t_range=u_range)
    same_answer(case, c1, c2, t_map=lambda u: scale * u + offset)
