"""The BMS algorithm's intermediate results: the 30 BMS planes equal the facets of the
convex hull of the 64 vertex differences (scipy), plane for plane and label for
label, and the section boundaries are where the topology changes."""

from __future__ import annotations

import numpy as np
import pytest
from cases import make_case
from scipy.spatial import ConvexHull

from bullet_boxccd import Box, QuadraticMotion, bms_planes, sections
from bullet_boxccd.geometry import feature_name
from bullet_boxccd.testing import SIGNS, motion_at, world_vertices


def hull_facets(VA, VB, L):
    """Unique facets (unit normal, offset, A vertex ids, B vertex ids) of hull(VA - VB)."""
    diff = (VA[:, None, :] - VB[None, :, :]).reshape(64, 3)
    hull = ConvexHull(diff)
    facets = []
    for eq in hull.equations:
        n, off = eq[:3], -eq[3]
        if any(np.dot(n, f[0]) > 1 - 1e-9 and abs(off - f[1]) < 1e-9 * L for f in facets):
            continue
        on = np.flatnonzero(np.abs(diff @ n - off) <= 1e-9 * L)
        facets.append((n, off, set(on // 8), set(on % 8)))
    return facets


def expected_feature(ids):
    """Common sign triple of a set of vertex ids (0 where they differ) -> the BMS algorithm's feature name."""
    s = SIGNS[sorted(ids)]
    return feature_name(np.where(np.all(s == s[0], axis=0), s[0], 0))


@pytest.mark.parametrize("family", ["rotating", "both_moving", "off_centre", "thin_plates"])
def test_planes_are_the_hull_facets(family):
    rng = np.random.default_rng(7)
    for seed in range(25):
        case = make_case(seed, family)
        a, b = Box(case.lo_a, case.hi_a), Box(case.lo_b, case.hi_b)
        m_a, m_b = QuadraticMotion(case.coeffs_a), QuadraticMotion(case.coeffs_b)
        t = rng.uniform(case.t0, case.t1)
        VA = world_vertices(case.coeffs_a, case.lo_a, case.hi_a, t)
        VB = world_vertices(case.coeffs_b, case.lo_b, case.hi_b, t)
        L = np.ptp(VA, axis=0).max() + np.ptp(VB, axis=0).max() + np.abs(VA - VB[0]).max()
        facets = hull_facets(VA, VB, L)
        planes = bms_planes(a, m_a, b, m_b, t, (case.t0, case.t1))
        assert len(planes) == 30 and len(facets) == 30, (seed, len(facets))
        for plane in planes:
            match = [f for f in facets if np.dot(plane.normal, f[0]) > 1 - 1e-9]
            assert len(match) == 1, (seed, plane)
            n, off, ids_a, ids_b = match[0]
            assert abs(plane.offset - off) <= 1e-9 * L, (seed, plane, off)
            kind = {(4, 1): "OV", (1, 4): "VO", (2, 2): "EE"}[(len(ids_a), len(ids_b))]
            assert plane.feature.kind == kind, (seed, plane)
            assert plane.feature.a == expected_feature(ids_a), (seed, plane, ids_a)
            assert plane.feature.b == expected_feature(ids_b), (seed, plane, ids_b)


def test_topology_is_constant_inside_sections_and_changes_across_them():
    """Inside a section the 30 labels do not change; across an interior boundary they do."""
    changed = 0
    for seed in range(30):
        case = make_case(seed, "rotating")
        args = (Box(case.lo_a, case.hi_a), QuadraticMotion(case.coeffs_a),
                Box(case.lo_b, case.hi_b), QuadraticMotion(case.coeffs_b))
        tr = (case.t0, case.t1)
        cuts = sections(*args, tr)
        assert cuts[0] == case.t0 and cuts[-1] == case.t1 and np.all(np.diff(cuts) > 0)

        def labels(t, args=args, tr=tr):
            return [p.feature for p in bms_planes(*args, t, tr)]

        for lo, hi in zip(cuts[:-1], cuts[1:]):
            inside = [labels(lo + f * (hi - lo)) for f in (0.1, 0.5, 0.9)]
            assert inside[0] == inside[1] == inside[2], (seed, lo, hi)
        for k in range(1, len(cuts) - 1):
            eps = 1e-7 * (cuts[k + 1] - cuts[k - 1])
            changed += labels(cuts[k] - eps) != labels(cuts[k] + eps)
    assert changed > 10


def test_aligned_translation_has_no_switches():
    """A normal component that stays zero is not a switch: aligned boxes sliding
    past each other have a single section."""
    a = Box.centered((1.0, 1.0, 1.0))
    args = (a, QuadraticMotion.static(), a, QuadraticMotion.ballistic((5.0, 0.5, 0.0), (-10.0, 0.0, 0.0)))
    assert list(sections(*args)) == [0.0, 1.0]


def _switch_values(ca, cb, ts):
    """The BMS algorithm's 18 octant-switch functions at times ts (n,), straight from the
    two motions' 3x3 parts: S[q][i][l] = (u_{i+1} x u_{i+2}) . v_l with (u, v) =
    (A's, B's) edge directions for q = 0 and (B's, A's) for q = 1. Returns the
    values (n, 18) and their scales |u_{i+1}| |u_{i+2}| |v_l| (n, 18)."""
    A, B = motion_at(ca, ts)[:, :3, :3], motion_at(cb, ts)[:, :3, :3]
    vals, scales = [], []
    for U, V in ((A, B), (B, A)):
        length = np.linalg.norm(U, axis=1)
        for i in range(3):
            n = np.cross(U[:, :, (i + 1) % 3], U[:, :, (i + 2) % 3])
            vals.append(np.einsum("nr,nrl->nl", n, V))
            scales.append((length[:, (i + 1) % 3] * length[:, (i + 2) % 3])[:, None] * np.linalg.norm(V, axis=1))
    return np.concatenate(vals, axis=1), np.concatenate(scales, axis=1)


@pytest.mark.parametrize("family", ["rotating", "both_moving"])
def test_short_ranges_miss_no_switch(family):
    """On short time ranges (down to 1e-6 of a case's range, placed across the
    full range's boundaries and at random) most switch functions are proven
    sign-constant without root isolation; every sign change seen by sampling
    the switch functions (numpy, independent of the solver) must still be a
    section boundary."""
    rng = np.random.default_rng(11)
    checked = 0
    for seed in range(40):
        case = make_case(seed, family)
        args = (Box(case.lo_a, case.hi_a), QuadraticMotion(case.coeffs_a),
                Box(case.lo_b, case.hi_b), QuadraticMotion(case.coeffs_b))
        span = case.t1 - case.t0
        cuts = sections(*args, (case.t0, case.t1))
        centres = list(cuts[1:-1]) + list(rng.uniform(case.t0, case.t1, 3))
        for c in centres:
            width = span * 10.0 ** rng.uniform(-6, -1)
            lo = max(case.t0, c - width * rng.uniform())
            hi = min(case.t1, lo + width)
            ts = np.linspace(lo, hi, 201)
            window = sections(*args, (lo, hi))
            vals, scale = _switch_values(case.coeffs_a, case.coeffs_b, ts)
            clear = np.abs(vals) > 1e-9 * scale
            flips = clear[:-1] & clear[1:] & (np.sign(vals[:-1]) != np.sign(vals[1:]))
            tol = 1e-12 * span
            for k in np.flatnonzero(flips.any(axis=1)):
                checked += 1
                assert np.any((window >= ts[k] - tol) & (window <= ts[k + 1] + tol)), (seed, lo, hi, k)
    assert checked > 40
