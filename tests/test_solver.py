"""Closed-form cases, the batch entry point and bad input."""

from __future__ import annotations

import copy
import inspect
import pickle
import weakref
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from cases import FAMILIES, assert_known_answers, batch_rows, make_case, pose

from bullet_boxccd import (
    Box,
    Contact,
    Feature,
    InvalidBoxError,
    InvalidInputError,
    InvalidMotionError,
    InvalidShapeError,
    InvalidTimeRangeError,
    InvalidToleranceError,
    NonFiniteInputError,
    Outcome,
    QuadraticMotion,
    SingularMotionError,
    Tolerances,
    _core,
    time_of_impact,
    time_of_impact_batch,
)
from bullet_boxccd.motion import rotation_matrix
from bullet_boxccd.testing import Case, reference

CUBE = Box.centered((0.5, 0.5, 0.5))
STATIC = QuadraticMotion.static()


def ballistic(R, p, v):
    return QuadraticMotion.ballistic(p, v, rotation=R)


# ----------------------------------------------------------------- closed form
def test_pure_translation_contact_time_by_hand():
    # B (half 0.25) starts at x = 3 and moves at -2: its face X reaches A's X' at
    # 3 - 2t - 0.25 = 0.5, t = 1.125.
    b = Box.centered((0.25, 0.25, 0.25))
    c = time_of_impact(CUBE, STATIC, b, QuadraticMotion.ballistic((3, 0.1, -0.2), (-2, 0, 0)), (0, 2))
    assert c is not None and not c.initial
    assert abs(c.t - 1.125) < 1e-11
    np.testing.assert_allclose(c.normal, (1, 0, 0), atol=1e-12)
    assert c.feature.kind in ("OV", "VO") and abs(c.point[0] - 0.5) < 1e-11


def test_accelerating_translation():
    # x(t) = 4 - t^2 (acceleration -2): B's face at 4 - t^2 - 0.5 = 0.5 -> t = sqrt(3).
    c = time_of_impact(CUBE, STATIC, CUBE, QuadraticMotion.ballistic((4, 0, 0), (0, 0, 0), (-2, 0, 0)), (0, 3))
    assert abs(c.t - np.sqrt(3.0)) < 1e-11


def test_face_to_face_with_both_moving():
    # A moves +x at 1, B moves -x at 3 from x = 5: gap 4 closes at 4 t = 4.
    c = time_of_impact(CUBE, QuadraticMotion.ballistic((0, 0, 0), (1, 0, 0)), CUBE,
                       QuadraticMotion.ballistic((5, 0, 0), (-3, 0, 0)), (0, 2))
    assert abs(c.t - 1.0) < 1e-11
    np.testing.assert_allclose(c.normal, (1, 0, 0), atol=1e-12)


def test_edge_to_edge():
    # A turned 45 deg about z presents a vertical edge at x = sqrt(2)/2; B turned
    # 45 deg about y presents a horizontal edge (along y) at x0 - sqrt(2)/2.
    r = np.sqrt(0.5)
    m_a = QuadraticMotion.static(pose(rotation_matrix((0, 0, 1), np.pi / 4), (0, 0, 0)))
    m_b = ballistic(rotation_matrix((0, 1, 0), np.pi / 4), (3, 0, 0), (-2, 0, 0))
    c = time_of_impact(CUBE, m_a, CUBE, m_b)
    assert abs(c.t - (3 - 2 * r) / 2) < 1e-11
    assert c.feature.kind == "EE"
    assert [len(name.replace("'", "")) for name in c.feature[1:]] == [2, 2]  # an edge of each box
    np.testing.assert_allclose(c.point, (r, 0, 0), atol=1e-9)
    np.testing.assert_allclose(c.normal, (1, 0, 0), atol=1e-9)


def test_vertex_to_face():
    # B turned so that its vertex (-,-,-) leads along -x: it sits sqrt(3)/2 from B's centre.
    R = rotation_matrix(np.cross((-1, -1, -1), (-1, 0, 0)), np.arccos(1 / np.sqrt(3)))
    np.testing.assert_allclose(R @ np.array([-1, -1, -1]) / np.sqrt(3), (-1, 0, 0), atol=1e-12)
    c = time_of_impact(CUBE, STATIC, CUBE, ballistic(R, (3, 0.05, 0.05), (-4, 0, 0)))
    assert abs(c.t - (3 - np.sqrt(3) / 2 - 0.5) / 4) < 1e-11
    assert c.feature == ("OV", "X'", "XYZ")
    np.testing.assert_allclose(c.point, (0.5, 0.05, 0.05), atol=1e-9)


def test_face_of_b_against_vertex_of_a():
    R = rotation_matrix(np.cross((1, 1, 1), (1, 0, 0)), np.arccos(1 / np.sqrt(3)))
    c = time_of_impact(CUBE, QuadraticMotion.static(pose(R, (0, 0, 0))), CUBE,
                       QuadraticMotion.ballistic((3, 0, 0), (-4, 0, 0)))
    assert abs(c.t - (3 - np.sqrt(3) / 2 - 0.5) / 4) < 1e-11
    assert c.feature == ("VO", "X'Y'Z'", "X")


def test_touching_at_range_start_is_initial():
    # M(2) puts B at x = 1: face to face with A, then moving away (apart from then on).
    m_b = QuadraticMotion.ballistic((-1.0, 0, 0), (1, 0, 0))
    c = time_of_impact(CUBE, STATIC, CUBE, m_b, (2.0, 3.0))
    assert c.initial and c.t == 2.0
    assert time_of_impact(CUBE, STATIC, CUBE, m_b, (2.001, 3.0)) is None


def test_overlapping_at_start_is_initial_with_least_penetration_normal():
    c = time_of_impact(CUBE, STATIC, CUBE, QuadraticMotion.ballistic((0.9, 0.2, 0.0), (0, 0, 0)), (0, 1))
    assert c.initial and c.t == 0.0
    np.testing.assert_allclose(c.normal, (1, 0, 0), atol=1e-12)
    # A hair further out (0.1 of a box apart), the same pair never touches.
    assert time_of_impact(CUBE, STATIC, CUBE, QuadraticMotion.ballistic((1.1, 0.2, 0.0), (0, 0, 0)), (0, 1)) is None


# A cube riding on a teleported paddle, starting against a resting cube it presses into
# (the plugin's push of a row of cubes): both motions as the plugin fits them, whose
# rounding makes the pair a turning one.
_RIDING = [[[0.9999999986006824, 4.821523934907577e-06, -5.268195160670035e-05, 1.8108339474480646],
            [-4.824757278181727e-06, 0.9999999981049261, -6.137482688690347e-05, -0.08161769595958239],
            [5.268165558666732e-05, 6.137508097865003e-05, 0.9999999967288713, 0.024973752223847956],
            [0.0, 0.0, 0.0, 1.0]],
           [[0.0, 8.470329472543003e-22, 6.776263578034403e-21, 0.1013596162835333],
            [-8.470329472543003e-22, 0.0, 1.3552527156068805e-20, -1.3877787807814457e-17],
            [-6.776263578034403e-21, -1.3552527156068805e-20, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]],
           [[0.0, 0.0, 0.0, -4.440892098500626e-16], [0.0] * 4, [0.0] * 4, [0.0] * 4]]
_RESTING = [[[0.9999999984920621, 5.68250716538782e-06, -5.462220172340539e-05, 1.8608339754562124],
             [-5.685988466525672e-06, 0.9999999979528085, -6.373423419551489e-05, -0.08897150046731737],
             [5.4621839441340784e-05, 6.373454468061663e-05, 0.9999999964771812, 0.024979018365604455],
             [0.0, 0.0, 0.0, 1.0]],
            [[1.1102230246251565e-16, -8.470329472543003e-22, 0.0, -2.220446049250313e-16],
             [-8.470329472543003e-22, -2.220446049250313e-16, 0.0, -1.3877787807814457e-17],
             [1.3552527156068805e-20, 0.0, -1.1102230246251565e-16, 0.0], [0.0] * 4],
            [[0.0] * 4] * 4]


def test_boxes_touching_at_the_start_within_rounding_meet():
    """The riding cube, grown across the separating margin in steps of 5e-19 m, against
    the resting one: a contact at the oracle's crossing (within 1e-9 of the start)
    every time, and at 0.099 from 1 cm further back. Where the most separating axis at
    the start clears the margin by less than the advancement's bound on it rounds, that
    bound is not positive at the start, and the advancement must stay there rather than
    take the whole range as apart."""
    hb = np.full(3, 0.025000000000043304)
    back = np.array(_RIDING)
    back[0, 0, 3] -= 0.01  # the riding cube 1 cm further back: it meets the other at t = 0.099
    cases = [(np.array(_RIDING), grow) for grow in np.linspace(1.830e-13, 1.831e-13, 201)] + [(back, 1.8305e-13)]
    for riding, grow in cases:
        ha = np.full(3, 0.025 + grow)
        case = Case(-ha, ha, riding, -hb, hb, np.array(_RESTING), 0.0, 1.0)
        got = time_of_impact(Box(-ha, ha), QuadraticMotion(case.coeffs_a), Box(-hb, hb),
                             QuadraticMotion(case.coeffs_b), (0.0, 1.0))
        ref = reference(case)
        assert ref.outcome == "hit", (grow, ref)
        assert got is not None and abs(got.t - ref.t_hit) <= 1e-9, (grow, got, ref)
    assert 0.09 < ref.t_hit < 0.11


def test_touching_at_range_end():
    # Contact exactly at t = 1: B's face reaches x = 0.5 at t = 1.
    c = time_of_impact(CUBE, STATIC, CUBE, QuadraticMotion.ballistic((3.0, 0, 0), (-2.0, 0, 0)), (0, 1))
    assert c is not None and not c.initial and abs(c.t - 1.0) < 1e-11
    assert time_of_impact(CUBE, STATIC, CUBE, QuadraticMotion.ballistic((3.0, 0, 0), (-2.0, 0, 0)), (0, 0.999)) \
        is None


def parabola(gap):
    """B above A on a parabola whose lowest point (t = 0.5) leaves ``gap`` above A's top face."""
    return QuadraticMotion.ballistic((0.3, 1.0 + gap + 0.25, 0.1), (0, -1.0, 0), (0, 2.0, 0))


def test_grazing_at_zero_gap_is_a_hit():
    c = time_of_impact(CUBE, STATIC, CUBE, parabola(0.0))
    assert c is not None
    # A double root: t is ill-conditioned, the gap is not. Check the gap at c.t.
    y = parabola(0.0).at(c.t)[1, 3]
    assert 0 <= y - 1.0 <= 1e-11
    assert abs(c.t - 0.5) < 1e-5
    np.testing.assert_allclose(c.normal, (0, 1, 0), atol=1e-9)


def test_grazing_at_1e9_gap_is_a_miss():
    assert time_of_impact(CUBE, STATIC, CUBE, parabola(1e-9)) is None
    # 1e-9 lower, the apex dips into A: a hit at the crossing just before t = 0.5.
    c = time_of_impact(CUBE, STATIC, CUBE, parabola(-1e-9))
    assert c is not None and 0.49996 < c.t < 0.5


def test_sliding_face_on_face_contact_is_found_when_faces_meet():
    # B slides along A's top face at exactly zero gap, coming from the left.
    m_b = QuadraticMotion.ballistic((-3.0, 1.0, 0.0), (6.0, 0.0, 0.0))
    c = time_of_impact(CUBE, STATIC, CUBE, m_b)
    assert abs(c.t - 2.0 / 6.0) < 1e-11


def test_rotating_plank_sweeps_the_cube():
    # A plank spinning a quarter turn about z sweeps a cube at radius 3: first
    # contact when the plank's far edge rotates into the cube's near face.
    plank = Box.centered((5.0, 0.1, 0.5))
    m = QuadraticMotion.screw(np.eye(4), (0, 0, 0), (0, 0, np.pi / 2))
    c = time_of_impact(plank, m, CUBE, QuadraticMotion.static(pose(np.eye(3), (0.0, 3.0, 0.0))))
    assert c is not None and 0 < c.t < 1


# ------------------------------------------------------------------------ batch
def test_batch_agrees_with_single_queries_bit_for_bit():
    cases = [make_case(seed, fam) for fam in FAMILIES for seed in range(30)]
    lo_a = np.array([c.lo_a for c in cases])
    hi_a = np.array([c.hi_a for c in cases])
    lo_b = np.array([c.lo_b for c in cases])
    hi_b = np.array([c.hi_b for c in cases])
    # Reparametrise every motion onto [0, 1] so one t_range serves all rows.
    ca = np.array([QuadraticMotion(c.coeffs_a).reparametrized(c.t1 - c.t0, c.t0).coeffs for c in cases])
    cb = np.array([QuadraticMotion(c.coeffs_b).reparametrized(c.t1 - c.t0, c.t0).coeffs for c in cases])
    batch = time_of_impact_batch(lo_a, hi_a, ca, lo_b, hi_b, cb)
    assert batch.shape == (len(cases),) and batch.dtype == np.float64
    hits = 0
    for i in range(len(cases)):
        single = time_of_impact(Box(lo_a[i], hi_a[i]), QuadraticMotion(ca[i]), Box(lo_b[i], hi_b[i]),
                                QuadraticMotion(cb[i]))
        if single is None:
            assert np.isnan(batch[i]), i
        else:
            assert batch[i] == single.t, i
            hits += 1
    assert 0 < hits < len(cases)


def test_batch_is_deterministic_across_batch_sizes():
    cases = [make_case(seed, "both_moving") for seed in range(50)]
    args = [np.array([getattr(c, f) for c in cases]) for f in ("lo_a", "hi_a")]
    ca = np.array([QuadraticMotion(c.coeffs_a).reparametrized(c.t1 - c.t0, c.t0).coeffs for c in cases])
    cb = np.array([QuadraticMotion(c.coeffs_b).reparametrized(c.t1 - c.t0, c.t0).coeffs for c in cases])
    lo_b = np.array([c.lo_b for c in cases])
    hi_b = np.array([c.hi_b for c in cases])
    whole = time_of_impact_batch(*args, ca, lo_b, hi_b, cb)
    parts = np.concatenate([time_of_impact_batch(args[0][i:i + 7], args[1][i:i + 7], ca[i:i + 7], lo_b[i:i + 7],
                                                 hi_b[i:i + 7], cb[i:i + 7]) for i in range(0, 50, 7)])
    np.testing.assert_array_equal(whole, parts)
    assert 0 < np.isnan(whole).sum() < len(whole)  # hits and misses both
    assert np.all(whole[~np.isnan(whole)] > 0.0)  # no pair of the family starts in contact


def test_batches_from_several_threads_agree_with_one():
    """The batch entry point runs without the GIL: calls from several threads at once
    must give exactly the answers of one call."""
    cases = [make_case(seed, fam) for fam in ("rotating", "both_moving") for seed in range(40)]
    ca = np.array([QuadraticMotion(c.coeffs_a).reparametrized(c.t1 - c.t0, c.t0).coeffs for c in cases])
    cb = np.array([QuadraticMotion(c.coeffs_b).reparametrized(c.t1 - c.t0, c.t0).coeffs for c in cases])
    rows = [np.array([getattr(c, f) for c in cases]) for f in ("lo_a", "hi_a")] + [ca] + \
        [np.array([getattr(c, f) for c in cases]) for f in ("lo_b", "hi_b")] + [cb]
    rows = [np.tile(r, (25,) + (1,) * (r.ndim - 1)) for r in rows]  # 2000 rows: calls overlap in time
    whole = time_of_impact_batch(*rows)
    with ThreadPoolExecutor(4) as pool:
        outs = list(pool.map(lambda _: time_of_impact_batch(*rows), range(8)))
    for out in outs:
        np.testing.assert_array_equal(out, whole)
    assert 0 < np.isnan(whole).sum() < len(whole)


def test_empty_batch():
    out = time_of_impact_batch(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3, 4, 4)), np.zeros((0, 3)),
                               np.zeros((0, 3)), np.zeros((0, 3, 4, 4)))
    assert out.shape == (0,)
    assert_known_answers()  # and the next (non-empty) calls are answered as ever


def test_batch_names_every_bad_row():
    rows = batch_rows(10)
    rows[0][3, 1] = 2.0  # lo >= hi
    rows[2][7, 1, 0, 0] = np.nan
    with pytest.raises(InvalidBoxError) as e:
        time_of_impact_batch(*rows)
    msg = str(e.value)
    assert msg.startswith("row 3: lo_a/hi_a: lo[1] = 2 >= hi[1] = 1"), msg
    assert "[2 bad row(s): 3, 7]" in msg, msg


def test_batch_reports_a_singular_row():
    rows = batch_rows(4)
    rows[5][2, 1, 0, 0] = -2.0  # B's x axis scales by 1 - 2t: collapses at t = 0.5
    with pytest.raises(SingularMotionError) as e:
        time_of_impact_batch(*rows)
    assert "row 2: coeffs_b" in str(e.value) and abs(e.value.t - 0.5) < 1e-9


def test_batch_shapes():
    rows = batch_rows(3)
    rows[4] = np.ones((2, 3))
    with pytest.raises(InvalidShapeError, match="disagree on N"):
        time_of_impact_batch(*rows)
    rows = batch_rows(3)
    rows[2] = np.zeros((3, 4, 4))
    with pytest.raises(InvalidShapeError, match=r"coeffs_a: expected shape \(N, 3, 4, 4\), got \(3, 4, 4\)"):
        time_of_impact_batch(*rows)


def test_batch_accepts_non_contiguous_and_other_dtypes():
    rows = batch_rows(6)
    rows[5][:3, 1, 0, 3] = -4.0  # three of them thrown at A: faces meet at 5 - 4 t = 2
    want = time_of_impact_batch(*rows)
    assert np.all(np.abs(want[:3] - 0.75) < 1e-11) and np.all(np.isnan(want[3:]))
    rows[0] = np.asfortranarray(rows[0]).astype(np.float32)
    rows[2] = np.concatenate([rows[2], rows[2]])[::2]
    np.testing.assert_array_equal(time_of_impact_batch(*rows), want)


# ------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "make, error, text",
    [
        (lambda: Box((0, 0, np.nan), (1, 1, 1)), NonFiniteInputError, r"Box.lo\[2\] is nan"),
        (lambda: Box((0, 0, 0), (1, np.inf, 1)), NonFiniteInputError, r"Box.hi\[1\] is inf"),
        (lambda: Box((0, 2, 0), (1, 1, 1)), InvalidBoxError, r"lo\[1\] = 2 >= hi\[1\] = 1"),
        (lambda: Box((0, 1, 0), (1, 1, 1)), InvalidBoxError, "y axis"),
        (lambda: Box((0, 0), (1, 1)), InvalidShapeError, r"lo: expected shape \(3,\), got \(2,\)"),
        (lambda: Box("abc", (1, 1, 1)), InvalidShapeError, "lo: cannot be read"),
        (lambda: QuadraticMotion(np.zeros((3, 4, 4))), InvalidMotionError, r"coeffs\[0, 3, 3\] is 0; expected 1"),
        (lambda: QuadraticMotion(np.zeros((2, 4, 4))), InvalidShapeError, r"expected shape \(3, 4, 4\)"),
    ],
)
def test_bad_construction(make, error, text):
    with pytest.raises(error, match=text):
        make()


def test_non_affine_velocity_row():
    c = QuadraticMotion.static().coeffs.copy()
    c[1, 3, 0] = 1e-3
    with pytest.raises(InvalidMotionError, match=r"coeffs\[1, 3, 0\] is 0.001"):
        QuadraticMotion(c)


def test_nan_in_motion_names_the_entry():
    c = QuadraticMotion.static().coeffs.copy()
    c[2, 1, 3] = np.nan
    with pytest.raises(NonFiniteInputError, match=r"coeffs\[2, 1, 3\] is nan"):
        QuadraticMotion(c)


@pytest.mark.parametrize("t_range", [(1.0, 1.0), (1.0, 0.0), (0.0, np.inf), (np.nan, 1.0), (-1e308, 1e308)])
def test_bad_time_range(t_range):
    with pytest.raises(InvalidTimeRangeError, match="t_range"):
        time_of_impact(CUBE, STATIC, CUBE, STATIC, t_range)


def test_singular_motion_names_the_time():
    c = QuadraticMotion.static().coeffs.copy()
    c[1, 2, 2] = -1.0  # z scale 1 - t: the box collapses to a square at t = 1
    with pytest.raises(SingularMotionError, match=r"m_b: .*singular at t = (1 |0\.99999999)") as e:
        time_of_impact(CUBE, STATIC, CUBE, QuadraticMotion(c), (0.0, 2.0))
    assert e.value.t == pytest.approx(1.0, abs=1e-12)  # early by the rounding allowance at most
    assert isinstance(e.value, InvalidMotionError) and isinstance(e.value, ValueError)
    # Outside the range it is fine.
    assert time_of_impact(CUBE, STATIC, CUBE, QuadraticMotion(c), (0.0, 0.5)) is not None


def test_overflowing_magnitudes_are_a_typed_error():
    big = Box.centered((1e300, 1e300, 1e300))
    with pytest.raises(NonFiniteInputError, match="overflow"):
        time_of_impact(big, QuadraticMotion.static(np.diag([1e300, 1e300, 1e300, 1.0])), CUBE, STATIC)


@pytest.mark.parametrize(
    "args, error, message",
    [
        (lambda: (CUBE, np.eye(4), CUBE, STATIC), InvalidInputError, "m_a: expected a QuadraticMotion"),
        (lambda: (STATIC, CUBE, CUBE, STATIC), InvalidInputError, "a: expected a Box, got QuadraticMotion"),
        (lambda: (CUBE, STATIC, CUBE, None), InvalidInputError, "m_b: expected a QuadraticMotion, got NoneType"),
        (lambda: (CUBE, STATIC, CUBE, STATIC, (0.0, 1.0, 2.0)), InvalidShapeError, r"t_range: expected shape \(2,\)"),
        (lambda: (CUBE, STATIC, CUBE, STATIC, "ab"), InvalidShapeError, "t_range: cannot be read"),
        (lambda: (CUBE, STATIC, CUBE, STATIC, b"\x00\x01"), InvalidShapeError, "t_range: cannot be read"),
        (lambda: (CUBE, STATIC, CUBE, STATIC, np.array([0, 1 + 5j])), InvalidShapeError, "t_range: expected real"),
        (lambda: (CUBE, STATIC, CUBE, STATIC, (np.complex128(0), np.complex128(1))), InvalidShapeError,
         "t_range: expected real"),
        (lambda: (CUBE, STATIC, CUBE, STATIC, (0.0, 1.0), "tight"), InvalidInputError, "tolerances: expected a"),
    ],
)
def test_wrong_argument_types(args, error, message):
    """The single query's fast path hands its arguments straight to the core; whatever
    the core rejects by type still gets the named error."""
    with pytest.raises(error, match=message):
        time_of_impact(*args())


def test_every_call_form_gives_the_python_functions_answer():
    """time_of_impact is a builtin that takes the common call straight to the core and
    hands every other form to its Python function: positional, keyword, mixed, None
    or explicit tolerances, other t_range types, and calls that must fail the same way."""
    from bullet_boxccd.solver import _time_of_impact

    m_b = QuadraticMotion.ballistic((5.0, 0.3, 0.2), (-10.0, 0.0, 0.0))
    tight = Tolerances(gap_rel=0.0)
    forms = [
        ((CUBE, STATIC, CUBE, m_b), {}),
        ((CUBE, STATIC, CUBE, m_b, (0.0, 0.5)), {}),
        ((CUBE, STATIC, CUBE, m_b, (0.0, 0.5), tight), {}),
        ((CUBE, STATIC, CUBE, m_b), dict(t_range=(0.0, 0.5))),
        ((CUBE, STATIC, CUBE, m_b), dict(tolerances=None)),
        ((CUBE, STATIC, CUBE, m_b), dict(tolerances=tight, t_range=(0.25, 1.0))),
        ((), dict(a=CUBE, m_a=STATIC, b=CUBE, m_b=m_b, t_range=[0, 1])),
        ((CUBE, STATIC), dict(m_b=m_b, b=CUBE)),
        ((CUBE, STATIC, CUBE, m_b, (0.0, 0.3)), {}),  # stays apart: None
    ]
    answers = set()
    for args, kwargs in forms:
        got, want = time_of_impact(*args, **kwargs), _time_of_impact(*args, **kwargs)
        assert (got is None) == (want is None), (args, kwargs)
        if got is not None:
            assert got.t == want.t and got.feature == want.feature and got.outcome == want.outcome
            assert np.array_equal(got.point, want.point) and np.array_equal(got.normal, want.normal)
        answers.add(None if got is None else got.t)
    assert None in answers and all(abs(t - 0.4) < 1e-11 for t in answers - {None})  # faces meet at 5 - 10 t = 1
    for args, kwargs, error in [
        ((CUBE, STATIC, CUBE), {}, TypeError),  # too few
        ((CUBE, STATIC, CUBE, m_b, (0.0, 1.0), None, None), {}, TypeError),  # too many
        ((CUBE, STATIC, CUBE, m_b), dict(a=CUBE), TypeError),  # a twice
        ((CUBE, STATIC, CUBE, m_b), dict(t_rnge=(0.0, 1.0)), TypeError),  # no such keyword
        ((CUBE, STATIC, CUBE, m_b, (1.0, 0.0)), {}, InvalidTimeRangeError),  # raised by the core, named by Python
    ]:
        with pytest.raises(error) as raised:
            time_of_impact(*args, **kwargs)
        with pytest.raises(error) as raised_by_python:
            _time_of_impact(*args, **kwargs)
        assert str(raised.value) == str(raised_by_python.value)
    assert str(inspect.signature(time_of_impact)) == "(a, m_a, b, m_b, t_range=(0.0, 1.0), tolerances=None)"
    assert time_of_impact.__module__ == "bullet_boxccd.solver" and "First time in" in time_of_impact.__doc__


def test_boxes_and_motions_pickle_and_subclass():
    """Boxes and motions travel by pickle (multiprocessing, Ray) and solve the same after;
    a subclass (whose core data time_of_impact fetches by name, as for the base class) too."""
    m_b = QuadraticMotion.ballistic((5.0, 0.3, 0.2), (-10.0, 0.0, 0.0))
    want = time_of_impact(CUBE, STATIC, CUBE, m_b)
    assert abs(want.t - 0.4) < 1e-11  # faces meet at 5 - 10 t = 1
    a, m_a, b, m_b2 = pickle.loads(pickle.dumps((CUBE, STATIC, CUBE, m_b)))
    assert np.array_equal(a.lo, CUBE.lo) and np.array_equal(m_b2.coeffs, m_b.coeffs)
    assert time_of_impact(a, m_a, b, m_b2).t == want.t

    class Crate(Box):
        pass

    class Throw(QuadraticMotion):
        pass

    crate, throw = Crate(CUBE.lo, CUBE.hi), Throw(m_b.coeffs)
    assert time_of_impact(crate, STATIC, crate, throw).t == want.t
    assert type(copy.deepcopy(crate)) is Crate and type(copy.copy(throw)) is Throw


def test_contacts_behave_like_their_named_tuples():
    """The core builds Contact and Feature itself (a Contact's arrays when first read):
    they must compare, hash, pickle, unpack and convert like the NamedTuples they were."""
    c = time_of_impact(CUBE, STATIC, CUBE, QuadraticMotion.ballistic((5.0, 0.3, 0.2), (-10.0, 0.0, 0.0)))
    assert abs(c.t - 0.4) < 1e-11 and c.feature == ("OV", "X'", "X")  # faces meet at 5 - 10 t = 1
    f = Feature(*c.feature)
    assert type(c) is Contact and type(c.feature) is Feature
    assert c.feature == f and hash(c.feature) == hash(f) and {f: 1}[c.feature] == 1
    assert c._asdict()["t"] == c.t and c._replace(t=0.0).t == 0.0 and repr(c).startswith("Contact(t=")
    back = pickle.loads(pickle.dumps(c))
    assert type(back) is Contact and back.t == c.t and back.feature == c.feature and np.array_equal(back.point, c.point)
    assert c.point.flags.owndata and c.point.shape == (3,) and c.normal.dtype == np.float64
    assert c.point is c.point and c.normal is c.normal  # made once, on first read
    t, point, normal, feature, initial, outcome = c
    assert (t, feature, initial, outcome) == (c.t, c.feature, c.initial, c.outcome) and point is c.point
    assert len(c) == 6 and c[0] == c.t and c[-1] is c.outcome and c[1:3] == (c.point, c.normal)
    assert c == tuple(c) and tuple(c) == c and c == Contact(*c) and c != c._replace(initial=True)
    assert Contact._fields == ("t", "point", "normal", "feature", "initial", "outcome")
    assert Contact._make(tuple(c)) == c and copy.deepcopy(c).t == c.t
    with pytest.raises(ValueError):
        c._replace(time=0.0)
    with pytest.raises(TypeError):
        hash(c)  # like the NamedTuple: its arrays are not hashable
    for name in Contact._fields + ("other",):
        with pytest.raises(AttributeError):
            setattr(c, name, 0.0)


def test_contacts_never_change_what_a_caller_holds():
    """Every call makes its own contact (the core keeps none to refill): whatever a caller
    still holds (a contact, one of its arrays, a weak reference) keeps its values, and an
    array changed in place changes no later contact."""

    def solve(x):  # faces meet at x - 10 t = 1; x < 1 overlaps at t = 0 (least along y)
        start = (x, 0.3, 0.2) if x > 1.0 else (x, 0.95, 0.2)
        return time_of_impact(CUBE, STATIC, CUBE, QuadraticMotion.ballistic(start, (-10.0, 0.0, 0.0)))

    def frozen(c):
        return c.t, tuple(c.point), tuple(c.normal), c.feature, c.initial, c.outcome

    xs = [5.0, 0.5, 3.0, 0.8, 2.0] * 4  # hits and overlaps, each several times
    held = [solve(x) for x in xs]
    want = {x: frozen(c) for x, c in zip(xs, held)}
    assert want[3.0][0] == pytest.approx(0.2, abs=1e-11) and want[3.0][5] is Outcome.HIT
    assert want[0.5][:1] + want[0.5][4:] == (0.0, True, Outcome.INITIAL) and want[0.5][3] != want[3.0][3]
    for _ in range(3):
        for x in xs:
            assert frozen(solve(x)) == want[x]  # later contacts carry their own answer, all of it
    assert [frozen(c) for c in held] == [want[x] for x in xs]  # held contacts did not change

    c = solve(5.0)
    point, normal = c.point, c.normal
    del c
    for x in xs:
        solve(x)
    assert (tuple(point), tuple(normal)) == want[5.0][1:3]  # arrays held without their contact neither

    def resize(a):  # in place (setting .shape is deprecated since numpy 2.5)
        a.resize(4, refcheck=False)

    def freeze(a):
        a.flags.writeable = False

    for change in (resize, freeze, weakref.ref):
        c = solve(5.0)
        kept = change(c.point)
        del c
        for x in xs:
            d = solve(x)
            assert d.point.shape == (3,) and d.point.flags.writeable and frozen(d) == want[x], change
        assert kept is None or kept() is None or tuple(kept()) == want[5.0][1]  # a weak reference: dead or unchanged


def test_time_range_forms_agree():
    """Ints, lists and arrays are valid time ranges and give the same answer."""
    m_b = QuadraticMotion.ballistic((5.0, 0.3, 0.2), (-10.0, 0.0, 0.0))
    ts = {time_of_impact(CUBE, STATIC, CUBE, m_b, r).t for r in [(0.0, 1.0), (0, 1), [0, 1], np.array([0.0, 1.0])]}
    assert len(ts) == 1 and abs(ts.pop() - 0.4) < 1e-11  # faces meet at 5 - 10 t = 1


def test_single_calls_decide_regularity_as_the_batch_does():
    """A QuadraticMotion bounds |det| of its 3x3 part on [0, 1] once, at construction;
    single calls on t_range (0, 1) skip their own check when that bound clears it, any
    other range checks. Both must decide as the batch (which always checks) does: here
    B's x axis scales by 1 - t / t_c, collapsing at t_c, for t_c on both sides of the
    range's end and far inside and outside it."""
    def raises(solve, *args):
        try:
            solve(*args)
        except SingularMotionError:
            return True
        return False

    seen = set()
    for t_c in [0.5, 0.999, 1.0 - 1e-12, 1.0, 1.0 + 1e-14, 1.0 + 1e-13, 1.0 + 1e-12, 1.001, 2.0, 10.0]:
        for t_range in [(0.0, 1.0), (0.0, 3.0), (0.5, 1.0)]:
            c = QuadraticMotion.static().coeffs.copy()
            c[1, 0, 0] = -1.0 / t_c
            rows = batch_rows(1)
            rows[5][0] = c
            single = raises(time_of_impact, CUBE, STATIC, CUBE, QuadraticMotion(c), t_range)
            batch = raises(time_of_impact_batch, *rows, t_range)
            assert single == batch, (t_c, t_range, single, batch)
            seen.add(single)
            if t_c <= 1.0 - 1e-12 and t_range[1] >= t_c or t_c >= 1.001 and t_range[1] < t_c:
                assert single == (t_range[1] >= t_c), (t_c, t_range)
    assert seen == {True, False}


def test_errors_are_value_errors():
    for e in (InvalidBoxError, InvalidMotionError, InvalidShapeError, InvalidTimeRangeError, NonFiniteInputError,
              SingularMotionError):
        assert issubclass(e, InvalidInputError) and issubclass(e, ValueError)


# -------------------------------------------------------------------- outcomes
def test_contacts_say_hit_or_initial():
    hit = time_of_impact(CUBE, STATIC, CUBE, QuadraticMotion.ballistic((3.0, 0.1, 0.2), (-4.0, 0, 0)))
    assert hit.outcome is Outcome.HIT and not hit.initial and hit.t == pytest.approx(0.5, abs=1e-11)
    start = time_of_impact(CUBE, STATIC, CUBE, QuadraticMotion.ballistic((0.9, 0.2, 0.0), (0, 0, 0)))
    assert start.outcome is Outcome.INITIAL and start.initial and start.t == 0.0


def test_step_cap_is_never_a_plain_hit():
    """A search stopped by Tolerances.max_steps answers early with STEP_CAP, not HIT."""
    m_b = QuadraticMotion.ballistic((3.0, 3.0, 0.0), (-4.0, -4.0, 0.0))  # corner first: 0.5 exactly
    capped = time_of_impact(CUBE, STATIC, CUBE, m_b, tolerances=Tolerances(max_steps=1))
    full = time_of_impact(CUBE, STATIC, CUBE, m_b)
    assert full.outcome is Outcome.HIT and full.t == pytest.approx(0.5, abs=1e-11)
    assert capped.outcome is Outcome.STEP_CAP and capped.t <= full.t


def test_an_exact_double_root_without_tolerance_is_clustered():
    """B's y(t) = 2 - 6t + 18t^2 / 2 touches A's top face at t = 1/3 exactly (a double
    root at a point no double represents). With gap_rel = rounding = 0 the two
    roots cannot be separated: CLUSTERED_ROOTS at the cluster's start, early."""
    m_b = QuadraticMotion.ballistic((0.3, 2.0, 0.1), (0.0, -6.0, 0.0), (0.0, 18.0, 0.0))
    c = time_of_impact(CUBE, STATIC, CUBE, m_b, tolerances=Tolerances(gap_rel=0.0, rounding=0.0))
    assert c.outcome is Outcome.CLUSTERED_ROOTS and c.t <= 1 / 3 and 1 / 3 - c.t < 1e-15
    # With the default tolerance the touch is a plain hit (the shift separates the roots).
    c = time_of_impact(CUBE, STATIC, CUBE, m_b)
    assert c.outcome is Outcome.HIT and 0 < 1 / 3 - c.t < 1e-5


def test_batch_states_name_each_rows_outcome():
    rows = batch_rows(3, gap_x=5.0)  # 2 m cubes, B static at x = 5: apart
    rows[5][0, 0, 0, 3] = 1.5  # overlapping at the start
    rows[5][1, 1, 0, 3] = -4.0  # from x = 5 at -4 per unit t: faces meet at 5 - 4 t = 2, t = 0.75
    t, states = time_of_impact_batch(*rows, states=True)
    assert states.dtype == np.int8 and states.shape == (3,)
    assert [Outcome(k) for k in states] == [Outcome.INITIAL, Outcome.HIT, Outcome.SEPARATED]
    assert t[0] == 0.0 and t[1] == pytest.approx(0.75, abs=1e-11) and np.isnan(t[2])
    np.testing.assert_array_equal(t, time_of_impact_batch(*rows))


def _path_row(position):
    """A step-path row (step_path.hpp): a unit cube at rest at `position`."""
    row = np.zeros(42)
    row[:16] = np.eye(4).ravel()
    row[3], row[7], row[11] = position
    row[23:39] = np.eye(4).ravel()
    row[39:42] = 0.5
    return row


def test_step_path_queries_say_a_row_is_not_finite():
    """A row with NaN is not "apart": first_touches says NON_FINITE, and a RowBoxPath
    refuses it; two finite rows touching at the start make an INITIAL window contact."""
    rows = np.array([_path_row((0.0, 0.0, 0.0)), _path_row((0.5, 0.0, 0.0)), _path_row((5.0, 0.0, 0.0))])
    rows[2, 3] = np.nan
    pairs = np.array([[0, 1], [0, 2]], dtype=np.int64)
    tau, states, solves = _core.first_touches(rows, pairs, 0.05, Tolerances()._core, states=True)
    # Pair 0 touches at the start: the depth test says so without a solve.
    assert [Outcome(k) for k in states] == [Outcome.INITIAL, Outcome.NON_FINITE] and solves == 0
    assert tau[0] == 0.0 and np.isnan(tau[1])
    with pytest.raises(ValueError, match="not finite"):
        _core.RowBoxPath(rows[2])
    c = _core.paths_window_contact(_core.RowBoxPath(rows[0]), _core.RowBoxPath(rows[1]), 0.0, 1.0,
                                   Tolerances()._core)
    assert c.outcome is Outcome.INITIAL and c.feature.kind in ("OV", "VO", "EE")


def test_link_path_contact_says_what_happened():
    """paths_contact (the first touch on any two box paths, with its contact) returns
    None only when the boxes stay apart; otherwise a Contact whose outcome says what
    happened: a slide into a cube is a HIT at the closed-form time, a pair touching at
    the start INITIAL (a row path with NaN is refused when it is built)."""
    tol = Tolerances()._core
    still = _core.RowBoxPath(_path_row((0.0, 0.0, 0.0)))
    moving = _path_row((0.5, 0.0, 0.0))
    moving[16] = -3.5  # from x = 4 to 0.5 over the step: the faces meet at x = 1, tau = 3 / 3.5
    t, _, c = _core.paths_contact(still, _core.RowBoxPath(moving), 0.05, tol)
    assert c.outcome is Outcome.HIT and c.feature.kind in ("OV", "VO", "EE")
    assert t == c.t and abs(t - 3 / 3.5) < 1e-9 and t <= 3 / 3.5
    assert _core.paths_first_touch(still, _core.RowBoxPath(moving), 0.05, tol, state=True)[:2] == (t, int(Outcome.HIT))
    t, _, c = _core.paths_contact(still, _core.RowBoxPath(_path_row((0.5, 0.0, 0.0))), 0.05, tol)
    assert t == 0.0 and c.outcome is Outcome.INITIAL and c.initial
    t, _, c = _core.paths_contact(still, _core.RowBoxPath(_path_row((5.0, 0.0, 0.0))), 0.05, tol)
    assert np.isnan(t) and c is None


# ------------------------------------------------------------------ tolerances
def test_tolerance_defaults_are_the_cores():
    core, py = _core.Tolerances(), Tolerances()
    assert (py.gap_rel, py.rounding, py.max_steps) == (core.gap_rel, core.rounding, core.max_steps)
    assert (py._core.gap_rel, py._core.rounding, py._core.max_steps) == (core.gap_rel, core.rounding, core.max_steps)


@pytest.mark.parametrize(
    "kwargs, text",
    [
        (dict(gap_rel=-5.0), r"gap_rel is -5; expected a number in \[0, 0.1\]"),
        (dict(gap_rel=0.2), "gap_rel is 0.2"),
        (dict(gap_rel=np.nan), "gap_rel is nan"),
        (dict(rounding=-1.0), "rounding is -1"),
        (dict(rounding=np.inf), "rounding is inf"),
        (dict(max_steps=0), r"max_steps is 0; expected an integer >= 1"),
    ],
)
def test_the_core_validates_tolerances(kwargs, text):
    """A negative gap would void "never late"; zero steps would answer nothing. The core
    refuses them, whoever builds the object."""
    with pytest.raises(InvalidToleranceError, match=text):
        _core.Tolerances(**kwargs)
    with pytest.raises(InvalidToleranceError, match=text):
        Tolerances(**kwargs)
    assert issubclass(InvalidToleranceError, InvalidInputError)


def test_core_tolerances_are_read_only():
    t = _core.Tolerances()
    with pytest.raises(AttributeError):
        t.gap_rel = 1.0
