"""Hostile input to every public entry point (hypothesis, deterministic profile): the
answer is a typed InvalidInputError or a correct-looking result, never another
exception and never a crash; results are bit-identical across runs. Every test that
queries the solver ends by checking two pairs whose answers are known
(cases.assert_known_answers): hostile input must leave the solver exact."""

from __future__ import annotations

import numpy as np
from cases import FAMILIES, assert_known_answers, batch_rows, make_case
from hypothesis import example, given, settings
from hypothesis import strategies as st

from bullet_boxccd import (
    Box,
    InvalidInputError,
    QuadraticMotion,
    bms_planes,
    sections,
    time_of_impact,
    time_of_impact_batch,
)

HOSTILE = st.sampled_from([0.0, -0.0, 1.0, -1.0, 5e-324, 2.2e-308, 1e-300, 1e300, 1.7e308, -1.7e308, np.nan, np.inf,
                           -np.inf, 0.5, 3.0, 1e-9])
FLOATS = st.one_of(HOSTILE, st.floats(allow_nan=True, allow_infinity=True, width=64))
CUBE = Box.centered((0.5, 0.5, 0.5))
STATIC = QuadraticMotion.static()


def valid_or_typed(fn, *args, **kw):
    try:
        return fn(*args, **kw)
    except InvalidInputError:
        return None


@given(st.lists(FLOATS, min_size=3, max_size=3), st.lists(FLOATS, min_size=3, max_size=3))
def test_box_construction(lo, hi):
    b = valid_or_typed(Box, lo, hi)
    if b is not None:
        assert np.all(np.isfinite(b.lo)) and np.all(b.lo < b.hi)


@given(st.one_of(st.none(), st.text(max_size=3), st.lists(FLOATS, max_size=5), st.integers()))
def test_box_wrong_types(x):
    valid_or_typed(Box, x, (1.0, 1.0, 1.0))


@given(st.lists(st.one_of(st.integers(), st.sampled_from([10**400, -(10**309), 2**1024])), min_size=2, max_size=3))
@example([0, 10**400])
def test_integers_of_any_size(values):
    """Python ints beyond float64 (10**400) are a typed error wherever a float is read."""
    valid_or_typed(Box, values, (1.0, 1.0, 1.0))
    valid_or_typed(QuadraticMotion.ballistic, values, (1.0, 0.0, 0.0))
    valid_or_typed(time_of_impact, CUBE, STATIC, CUBE, STATIC, tuple(values))
    assert_known_answers()


def motion_coeffs(draw_entries):
    c = np.zeros((3, 4, 4))
    c[0] = np.eye(4)
    for (k, i, j), v in draw_entries:
        c[k, i, j] = v
    return c


ENTRY = st.tuples(st.tuples(st.integers(0, 2), st.integers(0, 3), st.integers(0, 3)), FLOATS)


@given(st.lists(ENTRY, max_size=6))
def test_motion_construction(entries):
    m = valid_or_typed(QuadraticMotion, motion_coeffs(entries))
    if m is not None:
        assert np.all(np.isfinite(m.coeffs))


@given(st.lists(ENTRY, max_size=4), st.lists(ENTRY, max_size=4), st.lists(FLOATS, min_size=2, max_size=2),
       st.sampled_from([(0.5, 0.5, 0.5), (1e-300, 1e-300, 1e-300), (1e300, 1.0, 1.0), (5e-324, 1.0, 1.0)]))
def test_time_of_impact_with_extreme_values(ea, eb, t_range, half):
    # Keep the 3x3 parts regular so that most draws reach the solver.
    ma = valid_or_typed(QuadraticMotion, motion_coeffs([e for e in ea if e[0][1] == 3 or e[0][0] == 0]))
    mb = valid_or_typed(QuadraticMotion, motion_coeffs(eb))
    box = valid_or_typed(Box.centered, half)
    if ma is None or mb is None or box is None:
        return
    c = valid_or_typed(time_of_impact, box, ma, box, mb, tuple(t_range))
    if c is not None:
        lo, hi = t_range
        assert lo <= c.t <= hi and np.all(np.isfinite(c.point)) and abs(np.linalg.norm(c.normal) - 1) < 1e-9
    valid_or_typed(sections, box, ma, box, mb, tuple(t_range))
    valid_or_typed(bms_planes, box, ma, box, mb, t_range[0], tuple(t_range))
    assert_known_answers()


@settings(max_examples=30)
@given(st.integers(0, 20), st.sampled_from(["float32", "int64", "complex128", "object", "bool"]),
       st.booleans())
def test_batch_with_other_dtypes_and_layouts(n, dtype, fortran):
    arrays = batch_rows(n, gap_x=3.0)
    arrays[0] = np.asfortranarray(arrays[0]).astype(dtype) if fortran else arrays[0].astype(dtype)
    out = valid_or_typed(time_of_impact_batch, *arrays)
    if out is not None:
        assert out.shape == (n,)
    assert_known_answers()


@settings(max_examples=40)
@given(st.integers(0, 8), st.lists(st.tuples(st.integers(0, 7), st.integers(0, 5), FLOATS), max_size=5))
def test_batch_with_hostile_rows(n, pokes):
    arrays = batch_rows(n, gap_x=2.0)
    for row, which, v in pokes:
        if row < n:
            arrays[which].reshape(n, -1)[row, 0] = v
    out = valid_or_typed(time_of_impact_batch, *arrays)
    if out is not None:
        assert out.shape == (n,)
    assert_known_answers()


def test_large_batch_and_empty_batch():
    n = 100_000
    lo, hi, c, _, _, cb = batch_rows(n)
    cb[:, 0, 0, 3] = np.linspace(1.0, 5.0, n)
    cb[:, 1, 0, 3] = -2.0
    out = time_of_impact_batch(lo, hi, c, lo, hi, cb)
    x0 = cb[:, 0, 0, 3]  # B's face meets A's when x0 - 2 t = 2
    want = np.where(x0 <= 4.0, np.maximum(0.0, (x0 - 2.0) / 2.0), np.nan)
    np.testing.assert_allclose(out, want, atol=1e-11)
    assert time_of_impact_batch(lo[:0], hi[:0], c[:0], lo[:0], hi[:0], cb[:0]).shape == (0,)


def test_results_are_deterministic_across_runs_and_batch_sizes():
    cases = [make_case(seed, fam) for fam in FAMILIES for seed in range(40)]
    ca = np.array([QuadraticMotion(k.coeffs_a).reparametrized(k.t1 - k.t0, k.t0).coeffs for k in cases])
    cb = np.array([QuadraticMotion(k.coeffs_b).reparametrized(k.t1 - k.t0, k.t0).coeffs for k in cases])
    args = [np.array([k.lo_a for k in cases]), np.array([k.hi_a for k in cases]), ca,
            np.array([k.lo_b for k in cases]), np.array([k.hi_b for k in cases]), cb]
    first = time_of_impact_batch(*args)
    again = time_of_impact_batch(*args)
    ones = np.array([time_of_impact_batch(*[a[i:i + 1] for a in args])[0] for i in range(len(cases))])
    assert first.tobytes() == again.tobytes() == ones.tobytes()
    assert_known_answers()


@given(st.lists(FLOATS, min_size=3, max_size=3), st.lists(FLOATS, min_size=3, max_size=3),
       st.lists(FLOATS, min_size=3, max_size=3))
def test_motion_constructors(p, v, w):
    for make in (lambda: QuadraticMotion.ballistic(p, v, w), lambda: QuadraticMotion.screw(np.eye(4), v, w),
                 lambda: QuadraticMotion.static(np.diag([*p, 1.0]))):
        m = valid_or_typed(make)
        if m is not None:
            assert np.all(np.isfinite(m.coeffs))


@given(FLOATS, FLOATS, st.integers(-5, 5))
def test_tolerances(gap_rel, rounding, max_steps):
    from bullet_boxccd import Tolerances

    tol = valid_or_typed(Tolerances, gap_rel, rounding, max_steps)
    if tol is not None:
        c = time_of_impact(Box.centered((0.5, 0.5, 0.5)), QuadraticMotion.static(), Box.centered((0.5, 0.5, 0.5)),
                           QuadraticMotion.ballistic((3.0, 0, 0), (-4.0, 0, 0)), (0.0, 1.0), tol)
        # Faces meet at t = 0.5: never late, whatever the tolerances, and early by at most
        # the touching tolerance (gap_rel <= 0.1 of a size 3 at closing speed 4).
        assert c is not None and 0.5 - 0.1 * 3.0 / 4.0 - 1e-9 <= c.t <= 0.5 + 1e-12, c
