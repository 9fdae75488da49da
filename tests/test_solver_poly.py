"""The root queries of the core's polynomials (_core/solver/poly.hpp), directly: simple
crossings, double roots (grazing), clustered roots, roots exactly at a split
point of the subdivision, and the caps. Polynomials are given by coefficients,
constant first, on s in [0, 1]."""

from __future__ import annotations

import numpy as np
import pytest

from bullet_boxccd import _core

P = np.polynomial.polynomial
WIDTH = _core.kRootWidth


def value(coeffs, s):
    return P.polyval(s, np.asarray(coeffs, dtype=float))


def from_roots(*roots, scale=1.0):
    """scale * prod (s - r), as coefficients."""
    return scale * P.polyfromroots(roots)


# ----------------------------------------------------------- first_nonpositive
@pytest.mark.parametrize("root", [0.1, 1 / 3, 0.5, 0.7, 0.999])
def test_a_simple_crossing_is_found_to_the_root_width_never_after_it(root):
    coeffs = from_roots(root, scale=-1.0)  # positive before the root
    s, clustered = _core.first_nonpositive(coeffs, 0.0, 1.0)
    assert not clustered and root - 2 * WIDTH <= s and value(coeffs, s) <= 0.0
    assert value(coeffs, np.nextafter(s, 0.0) - WIDTH) > 0.0 or s - WIDTH <= 0.0


def test_the_first_of_several_crossings_is_found():
    # Positive, then negative on (0.25, 0.5), positive, negative again after 0.75.
    coeffs = from_roots(0.25, 0.5, 0.75, scale=-1.0)
    s, clustered = _core.first_nonpositive(coeffs, 0.0, 1.0)
    assert not clustered and abs(s - 0.25) <= WIDTH
    s, _ = _core.first_nonpositive(coeffs, 0.6, 1.0)  # from inside the positive stretch
    assert abs(s - 0.75) <= WIDTH


def test_no_root_and_a_start_already_touching():
    assert np.isnan(_core.first_nonpositive(np.array([1.0, -1.0, 0.5]), 0.0, 1.0)[0])  # 1 - s + s^2/2 > 0
    assert _core.first_nonpositive(np.array([0.0, 1.0]), 0.0, 1.0)[0] == 0.0  # p(lo) = 0: touching at lo
    assert _core.first_nonpositive(np.array([-0.3, 1.0]), 0.2, 1.0)[0] == 0.2


def test_a_double_root_at_a_dyadic_point_is_exact():
    """(s - 1/2)^2 touches zero at 1/2, a split point of the subdivision: the root is
    there exactly (no half sees a sign variation, so the end value decides)."""
    assert _core.first_nonpositive(from_roots(0.5, 0.5), 0.0, 1.0) == (0.5, False)
    # A simple root at a split point of a deeper subdivision, after a positive stretch: found,
    # never late; the evaluation's rounding (a few eps of the terms, which cancel here) may
    # put the first nonpositive value an ulp or two before it, within the root width.
    s, clustered = _core.first_nonpositive(from_roots(0.5, 0.75, 0.875, scale=-1.0), 0.0, 1.0)
    assert not clustered and 0.5 - WIDTH <= s <= 0.5


@pytest.mark.parametrize("coeffs, root", [([1.0, -6.0, 9.0], 1 / 3), ([4.0, -20.0, 25.0], 0.4)])
def test_a_double_root_no_double_represents_is_a_cluster_answered_early(coeffs, root):
    """(3s - 1)^2 and (5s - 2)^2, exact coefficients: the two roots meet at a point
    between two doubles, which halving cannot separate. The answer is the
    cluster's start (never after the root) and says so."""
    s, clustered = _core.first_nonpositive(np.array(coeffs), 0.0, 1.0)
    assert clustered and s <= root and root - s < 1e-15


def test_a_positive_polynomial_near_zero_is_not_a_root():
    # 1/100 + (s - 0.3)^2 stays above 1e-2: no root, however close the control points come.
    assert np.isnan(_core.first_nonpositive(from_roots(0.3, 0.3) + np.array([1e-2, 0, 0]), 0.0, 1.0)[0])


# ----------------------------------------------------------- first_sign_change
def test_sign_changes_are_crossings_not_touches():
    s, clustered = _core.first_sign_change(from_roots(0.3, 0.6), 0.0, 1.0)
    assert not clustered and abs(s - 0.3) <= WIDTH
    assert np.isnan(_core.first_sign_change(from_roots(0.4, 0.4), 0.0, 1.0)[0])  # a touch: no switch
    assert np.isnan(_core.first_sign_change(np.array([2.0, 1.0]), 0.0, 1.0)[0])


def test_a_triple_root_at_a_split_point_is_a_sign_change():
    """(s - 1/2)^3 changes sign at 1/2 exactly, where the halving splits: neither half
    sees a variation; the split point itself is the switch."""
    assert _core.first_sign_change(from_roots(0.5, 0.5, 0.5), 0.0, 1.0)[0] == 0.5


def test_an_even_cluster_is_no_switch():
    """(3s - 1)^2 touches zero at 1/3 (exact coefficients, a root no double
    represents): no sign change, though halving cannot tell where the roots are;
    (3s - 1)^2 (s - 1/2), exact too, changes sign at 1/2 beyond it."""
    s, clustered = _core.first_sign_change(np.array([1.0, -6.0, 9.0]), 0.0, 1.0)
    assert np.isnan(s) and clustered
    assert _core.first_sign_change(np.array([-0.5, 4.0, -10.5, 9.0]), 0.0, 1.0)[0] == 0.5


# ------------------------------------------------------------------------- caps
@pytest.mark.parametrize("max_secant", [0, 1, 3, 40])
def test_the_crossing_is_converged_whatever_the_secant_cap(max_secant):
    """Illinois steps up to the cap, then bisection: any cap gives a point within the
    root width after the last positive one (0: pure bisection)."""
    coeffs = np.array([1.0, -3.0])  # 1 - 3 s: root 1/3
    s = _core.refine_crossing(coeffs, 0.0, 1.0, max_secant)
    assert value(coeffs, s) <= 0.0 and s - 1 / 3 <= WIDTH
    assert _core.refine_crossing(from_roots(0.7, scale=-1.0), 0.0, 1.0, max_secant) == pytest.approx(0.7, abs=WIDTH)


def test_the_subdivision_depth_cap_stays_early():
    """Near s = 0 doubles are dense, so the halving reaches its depth cap (2^-60 of the
    range) before running out of doubles: (3 2^40 s - 1)^2, exact coefficients, a
    double root at 1 / (3 2^40) ~ 3e-13. The query stops at the cap and answers the
    cluster's start, never after the root."""
    root = 1.0 / (3.0 * 2.0**40)
    coeffs = np.array([1.0, -6.0 * 2.0**40, 9.0 * 2.0**80])
    s, clustered = _core.first_nonpositive(coeffs, 0.0, 1.0)
    assert clustered and s <= root and root - s <= 2.0**-60


@pytest.mark.parametrize("lo, hi", [(0.5, 0.5), (-0.1, 1.0), (0.0, 1.5)])
def test_bad_intervals_are_refused(lo, hi):
    with pytest.raises(ValueError, match="0 <= lo < hi <= 1"):
        _core.first_nonpositive(np.array([1.0, -1.0]), lo, hi)
