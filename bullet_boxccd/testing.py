"""Independent references for checking the solver: box-box contact under
quadratic motion, used by the tests and the benchmarks, never by the solver.

Written apart from the solver: it never builds a Minkowski sum, a section or a
polynomial. It only evaluates the world vertices of both boxes at a time t and
runs a separating-axis test on them (15 axes: 3 face normals of each
parallelepiped and the 9 edge cross products, all taken from vertex
differences), which gives a signed gap: > 0 proves the boxes apart, <= 0 means
they intersect.

First contact: conservative advancement on that gap. The SAT gap is a lower
bound of the Euclidean distance, and the distance changes no faster than
V = (fastest vertex speed of A) + (fastest vertex speed of B); dM/dt is linear
in t, so each vertex speed peaks at an end of the range. Stepping by gap / V
therefore never steps over a contact. The advancement runs vectorised over all
cases in float64; the crossing is then bisected in float64 and confirmed in
mpmath at 40 digits (mpmath, a test extra, is imported on first use).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import SIGNS, BoxPairs  # SIGNS: vertex order of Box.vertices()

__all__ = ["SIGNS", "Case", "Reference", "box_size", "check_answer", "local_vertices", "motion_at", "mp_bisect",
           "mp_gap", "placed_vertices", "reference", "sat_gap", "world_vertices"]

# Vertex pairs (by index in SIGNS) that span the three edge directions.
_EDGE = ((0, 4), (0, 2), (0, 1))


def local_vertices(lo, hi):
    """(..., 8, 3) box corners in the box frame."""
    lo = np.asarray(lo, dtype=float)[..., None, :]
    hi = np.asarray(hi, dtype=float)[..., None, :]
    return np.where(SIGNS > 0, hi, lo)


def motion_at(coeffs, t):
    """(..., 4, 4) matrices of (..., 3, 4, 4) coefficients at times t (...)."""
    t = np.asarray(t, dtype=float)[..., None, None]
    return coeffs[..., 0, :, :] + t * (coeffs[..., 1, :, :] + t * coeffs[..., 2, :, :])


def placed_vertices(M, lo, hi):
    """(..., 8, 3) world corners of boxes (corners lo, hi (..., 3)) placed by affine
    matrices M (..., 4, 4) (or their top rows, (..., 3, 4))."""
    v = local_vertices(lo, hi)
    return np.einsum("...ij,...vj->...vi", M[..., :3, :3], v) + M[..., None, :3, 3]


def world_vertices(coeffs, lo, hi, t):
    return placed_vertices(motion_at(coeffs, t), lo, hi)


def _axes(VA, VB):
    """(..., 15, 3) SAT axes and (..., 15) the product of the two edge lengths behind each."""
    ea = np.stack([VA[..., j, :] - VA[..., i, :] for i, j in _EDGE], axis=-2)
    eb = np.stack([VB[..., j, :] - VB[..., i, :] for i, j in _EDGE], axis=-2)
    la, lb = np.linalg.norm(ea, axis=-1), np.linalg.norm(eb, axis=-1)
    pairs = ((1, 2), (2, 0), (0, 1))
    axes = [np.cross(ea[..., i, :], ea[..., j, :]) for i, j in pairs]
    axes += [np.cross(eb[..., i, :], eb[..., j, :]) for i, j in pairs]
    axes += [np.cross(ea[..., i, :], eb[..., j, :]) for i in range(3) for j in range(3)]
    lens = [la[..., i] * la[..., j] for i, j in pairs] + [lb[..., i] * lb[..., j] for i, j in pairs]
    lens += [la[..., i] * lb[..., j] for i in range(3) for j in range(3)]
    return np.stack(axes, axis=-2), np.stack(lens, axis=-1)


def sat_gap(VA, VB):
    """Signed SAT gap of vertex sets (..., 8, 3): > 0 apart (a lower bound of the
    distance), <= 0 intersecting."""
    axes, lens = _axes(VA, VB)
    n = np.linalg.norm(axes, axis=-1)
    # Axes of (nearly) parallel edges have no reliable direction; every other
    # axis is still a valid separating-axis test, so skipping one only makes the
    # gap smaller (never claims apart when touching).
    ok = n > 1e-9 * lens
    u = axes / np.where(ok, n, 1.0)[..., None]
    pa = np.einsum("...kj,...vj->...kv", u, VA)
    pb = np.einsum("...kj,...vj->...kv", u, VB)
    gap = np.maximum(pb.min(-1) - pa.max(-1), pa.min(-1) - pb.max(-1))
    return np.where(ok, gap, -np.inf).max(-1)


def box_size(coeffs, lo, hi, t):
    """World size of a box at t: the longest of its three edge lengths."""
    V = world_vertices(coeffs, lo, hi, t)
    return max(np.linalg.norm(V[..., j, :] - V[..., i, :], axis=-1).max() for i, j in _EDGE)


@dataclass
class Case(BoxPairs):
    """One query: a box pair over [t0, t1]."""

    t0: float
    t1: float

    def gap(self, t):
        return sat_gap(world_vertices(self.coeffs_a, self.lo_a, self.hi_a, t),
                       world_vertices(self.coeffs_b, self.lo_b, self.hi_b, t))

    def size(self):
        """Smaller box's world size at the start: the unit of the gap tolerances."""
        return min(box_size(self.coeffs_a, self.lo_a, self.hi_a, self.t0),
                   box_size(self.coeffs_b, self.lo_b, self.hi_b, self.t0))

    def repro(self) -> str:
        """The case to 20 digits, to paste into a regression test."""
        f = lambda a: np.array2string(np.asarray(a), precision=20, separator=", ", max_line_width=200)  # noqa: E731
        return (f"lo_a={f(self.lo_a)}\nhi_a={f(self.hi_a)}\ncoeffs_a={f(self.coeffs_a)}\n"
                f"lo_b={f(self.lo_b)}\nhi_b={f(self.hi_b)}\ncoeffs_b={f(self.coeffs_b)}\n"
                f"t_range=({self.t0!r}, {self.t1!r})")


def _max_speed(coeffs, lo, hi, t0, t1):
    v = np.concatenate([local_vertices(lo, hi), np.ones((8, 1))], axis=1)
    speeds = [np.linalg.norm((coeffs[1] + 2.0 * t * coeffs[2])[:3] @ v.T, axis=0).max() for t in (t0, t1)]
    return max(speeds)


@dataclass
class Reference:
    """Oracle verdict for one case.

    outcome: "hit" (the gap crosses below zero), "miss" (advancement reached the
    end of the range), or "unresolved" (advancement stalled at a gap it could not
    resolve: a shallow approach). t_hit: the crossing, to ~1e-13 of the range
    (hit only). min_gap: smallest gap seen by the advancement before t_hit.
    depth_after: the gap 1e-6 of the range after t_hit (how clearly it hits).
    """

    outcome: str
    t_hit: float = float("nan")
    min_gap: float = float("inf")
    depth_after: float = float("nan")


def reference(case: Case, max_steps: int = 200_000) -> Reference:
    """First contact of one case (see the module docstring)."""
    L = case.size()
    span = case.t1 - case.t0
    V = (_max_speed(case.coeffs_a, case.lo_a, case.hi_a, case.t0, case.t1)
         + _max_speed(case.coeffs_b, case.lo_b, case.hi_b, case.t0, case.t1))
    stop = 1e-11 * L
    t = case.t0
    g = float(case.gap(t))
    min_gap = g
    if g <= 0.0:
        return Reference("hit", case.t0, g, float(case.gap(min(case.t1, case.t0 + 1e-6 * span))))
    for _ in range(max_steps):
        if g <= stop:
            break
        t_next = t + g / V if V > 0 else case.t1
        if t_next >= case.t1:
            g_end = float(case.gap(case.t1))
            min_gap = min(min_gap, g_end)
            if g_end > 0.0:
                return Reference("miss", min_gap=min_gap)
            t_next = case.t1
        t = t_next
        g = float(case.gap(t))
        min_gap = min(min_gap, g)
        if g <= 0.0:
            break
    else:
        return Reference("unresolved", min_gap=min_gap)
    # From t (gap ~0, nothing earlier), look ahead on a geometric grid for the
    # first clearly negative gap, then bisect the sign change.
    lo, hi = t, None
    step = 1e-13 * span
    while lo < case.t1:
        cand = min(case.t1, lo + step)
        gc = float(case.gap(cand))
        if gc <= 0.0:
            hi = cand
            break
        lo, step = cand, step * 2.0
        min_gap = min(min_gap, gc)
        if gc > 1e-9 * L and cand > t + 1e-6 * span:
            # It moved away again without penetrating: continue the advancement.
            return _continue(case, cand, min_gap, max_steps)
    if hi is None:
        return Reference("unresolved", min_gap=min_gap)
    if float(case.gap(lo)) <= 0.0:
        return Reference("hit", lo, min_gap, float(case.gap(min(case.t1, lo + 1e-6 * span))))
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if float(case.gap(mid)) > 0.0:
            lo = mid
        else:
            hi = mid
    return Reference("hit", hi, min_gap, float(case.gap(min(case.t1, hi + 1e-6 * span))))


def _continue(case: Case, t: float, min_gap: float, max_steps: int) -> Reference:
    sub = Case(case.lo_a, case.hi_a, case.coeffs_a, case.lo_b, case.hi_b, case.coeffs_b, t, case.t1)
    r = reference(sub, max_steps)
    r.min_gap = min(r.min_gap, min_gap)
    if r.outcome == "hit" and r.t_hit == t:
        r.outcome = "unresolved"
    return r


# ---------------------------------------------------------------- mpmath part
def mp_gap(case: Case, t):
    """The same SAT gap at 40 significant digits (inputs converted exactly), an mpmath mpf."""
    import mpmath as mp

    with mp.workdps(40):
        t = mp.mpf(t)

        def verts(coeffs, lo, hi):
            C = [[[mp.mpf(float(coeffs[k, i, j])) for j in range(4)] for i in range(3)] for k in range(3)]
            M = [[C[0][i][j] + t * (C[1][i][j] + t * C[2][i][j]) for j in range(4)] for i in range(3)]
            out = []
            for s in SIGNS:
                p = [mp.mpf(float(hi[i])) if s[i] > 0 else mp.mpf(float(lo[i])) for i in range(3)]
                out.append([sum(M[i][j] * p[j] for j in range(3)) + M[i][3] for i in range(3)])
            return out

        VA = verts(case.coeffs_a, case.lo_a, case.hi_a)
        VB = verts(case.coeffs_b, case.lo_b, case.hi_b)

        def sub(p, q):
            return [p[i] - q[i] for i in range(3)]

        def cross(p, q):
            return [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]]

        ea = [sub(VA[j], VA[i]) for i, j in _EDGE]
        eb = [sub(VB[j], VB[i]) for i, j in _EDGE]
        axes = [cross(ea[1], ea[2]), cross(ea[2], ea[0]), cross(ea[0], ea[1]),
                cross(eb[1], eb[2]), cross(eb[2], eb[0]), cross(eb[0], eb[1])]
        axes += [cross(p, q) for p in ea for q in eb]
        best = mp.mpf("-inf")
        for ax in axes:
            n = mp.sqrt(sum(x * x for x in ax))
            if n == 0:
                continue
            pa = [sum(ax[i] * v[i] for i in range(3)) / n for v in VA]
            pb = [sum(ax[i] * v[i] for i in range(3)) / n for v in VB]
            best = max(best, min(pb) - max(pa), min(pa) - max(pb))
        return best


def mp_bisect(case: Case, lo, hi, tol, max_steps=None):
    """Bisect the sign change of ``mp_gap`` in [lo, hi] (the caller has checked gap(lo) > 0
    >= gap(hi)) until ``hi - lo <= tol`` or after ``max_steps`` halvings (None: no limit).
    The midpoints are taken in the arithmetic of lo and hi: floats give float midpoints,
    mpmath numbers midpoints at the working precision (``mp.workdps``). Returns the final
    (lo, hi) and the number of ``mp_gap`` calls."""
    n = 0
    while hi - lo > tol and (max_steps is None or n < max_steps):
        mid = (lo + hi) / 2
        if mp_gap(case, mid) > 0:
            lo = mid
        else:
            hi = mid
        n += 1
    return lo, hi, n


# ------------------------------------------------------------- judging answers
TIME_TOL = 1e-9  # of the range
GAP_TOL = 1e-9  # of the smaller box's size


def check_answer(case: Case, got, ref: Reference | None = None) -> str:
    """Judge a solver's answer (a Contact-like object with ``t`` and ``initial``, or
    None) against the reference; returns "hit", "miss" or "shallow", raises
    AssertionError with a 20-digit repro on disagreement.

    * clear hit (the gap goes at least 1e-8 box sizes below zero within 1e-6 of the
      range after the crossing): the answer agrees with the reference's crossing to
      1e-9 of the range, and mpmath brackets it: apart 1e-9 (range units) before,
      intersecting 1e-9 after;
    * clear miss (advancement reaches the end and never sees the gap below 2e-7 box
      sizes): the answer is None;
    * otherwise (shallow): a reported hit has its mpmath gap within 1e-9 box sizes of
      touching and is not later than the reference's crossing.
    """
    ref = ref or reference(case)
    L, span = case.size(), case.t1 - case.t0
    ctx = f"\nreference: {ref}\nsolver: {got}\n{case.repro()}"
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
