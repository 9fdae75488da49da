"""An independent checker of the solver's answers: separating axes, interval bounds, witnesses.

It shares nothing with the solver but the input format: no Minkowski sum, no section,
no facet polynomial. It works on the world vertices of both boxes, each a quadratic in t
(``X[k, v]`` is the coefficient of t^k of vertex v), and on three facts:

* **Apart** (a separating-axis gap): for any direction u, the boxes (parallelepipeds: the
  motions are affine) are at least ``min_j u.b_j - max_i u.a_i`` apart, the vertices'
  projections. Any u gives a valid lower bound of the distance, however it was computed,
  so rounding in the axis costs nothing; the checker tries the 15 SAT axes (3 face normals
  per box, 9 edge cross products) and keeps the best.
* **Apart over an interval** (no Lipschitz guess): along a *fixed* u, every
  ``u.(b_j(t) - a_i(t))`` is a quadratic in t, so the separation's minimum over [ta, tb]
  is the minimum of 64 quadratics, each at its ends or its vertex: exact, not sampled.
  The axes tried on an interval are the best axes at its two ends.
* **Overlap** (a witness, not a negative gap): a point inside both boxes by more than the
  rounding bound, its depth measured from its coordinates in each box's edge frame. Two
  convex polyhedra that intersect have an edge of one meeting the other: the checker
  tries the deepest point of each edge inside the other box (a concave piecewise-linear
  function along the edge: its breakpoints are tried), and the centroid of the ends of
  those edge parts (inside both boxes by convexity; it is the witness when faces are
  coplanar and every edge point lies on the other box's surface). A negative SAT gap
  is only where to look.

Every float64 value carries a rounding bound, ``c * eps * R`` with R a bound of every
term's magnitude, and a verdict needs its quantity to clear that bound, so **every
verdict is certain** (up to the stated margins). To keep R small, the float tier first
re-centres each query, in extended precision (numpy ``longdouble``; where that is plain
double the bound below simply becomes eps * R): time is measured from ``tc`` (the end of
the range nearer zero when the range does not contain zero, so ``t - tc`` is exact for
every t in it, by Sterbenz), and space from A's first vertex at ``tc`` (translating both
boxes changes no distance). The vertex coefficients are then rounded to float64; the
re-centring's own error, at most ``32 * eps_ext * R_orig`` per coordinate, joins every
bound. So a scene far from the origin, or a range far from t = 0, costs no precision.

Verdicts (``t_s`` the solver's answer, NaN for none, on the range [t0, t1]):

* ``CLEAR_MISS``: no answer, and the boxes are certified apart over all of [t0, t1].
* ``MISS``: no answer, and an overlap is certified somewhere in [t0, t1].
* ``HIT``: an answer, certified apart over [t0, t_s - late] (nothing earlier) and the
  SAT gap at some sample of the range is within the touching tolerance (not a ghost).
* ``LATE``: an answer, and an overlap certified at some t < t_s - late.
* ``FALSE_HIT`` (a ghost): an answer, and the boxes certified more than the touching
  tolerance apart over all of [t0, t1]: they never touch. (An answer given while the
  boxes are still apart, before a contact that does come, is early, not false: the
  solver promises never late, and rounds early. ``Checked.early`` flags the answers
  certified more than the touching tolerance apart at t_s, and ``early_gap`` measures
  every answer's gap.)
* ``UNRESOLVED``: none of the above could be certified within the budget.

Search: per query, samples on a uniform grid over [t0, t_end] (t_end = t_s or t1) and, for
answers, on a geometric ladder t_s - late * 64^k towards t_s (and, for an answer whose gap
at t_s exceeds the touching tolerance, a grid and ladder t_s + late * 64^k on [t_s, t1]
too, where a ghost must be told from an early answer); intervals between samples
whose bound does not settle the question are halved, round after round (vectorised over
all open intervals of all queries), until every query has a verdict, a query exceeds its
interval budget or the rounds run out. Queries left doubtful go to the same search in
mpmath at ``mp_prec`` bits (``numpy`` object arrays of ``mpf``: the code path is the same),
starting from the intervals still open, on the exact inputs (no re-centring). An interval
the float64 tier would have settled but for its rounding bound is parked for mpmath at
once rather than halved further.

Tolerances (``CheckTolerances``) and why:

* ``late_rel`` 1e-12 of the range: an overlap at least this much before the answer makes
  it late (the solver's answers are exact up to rounding; the stress tier uses the same).
* touching tolerance ``tau = touch_rel * S + touch_round * eps * R_world``, S the sum of
  both boxes' world half edges (the solver's size) and R_world the magnitude bound in the
  solver's own (unshifted) coordinates: the solver counts gaps up to 1e-12 S plus a rounding
  allowance (64 eps per term; measured up to ~1.3e4 eps R: docs/accuracy.md) as touching;
  the checker calls a hit false only beyond 1000x the first and 10x the second.
* ``gap_round``, ``overlap_round``: multiples of eps * R bounding the rounding of a SAT
  projection and interval bound (about 10 dependent operations on terms <= R) and of a
  witness's depth (the box's edge frame from rounded vertices: ~7 vertex errors, the
  point's own, Cramer's rule); both about 4x over a term-by-term count.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import SIGNS
from .families import QueryBatch

__all__ = ["CheckTolerances", "Checked", "check", "VERDICTS", "CLEAR_MISS", "MISS", "HIT", "LATE", "FALSE_HIT",
           "UNRESOLVED"]

CLEAR_MISS, MISS, HIT, LATE, FALSE_HIT, UNRESOLVED = range(6)
VERDICTS = ("clear_miss", "miss", "hit", "late", "false_hit", "unresolved")

# Edges of a box as vertex-index pairs (indices into SIGNS: bit 2 = x, bit 1 = y, bit 0 = z).
_EDGE_I = np.array([i for i in range(8) for b in (4, 2, 1) if not i & b])
_EDGE_J = np.array([i | b for i in range(8) for b in (4, 2, 1) if not i & b])
_AXIS_EDGES = (4, 2, 1)  # vertex 0 to these: the x, y and z edges
# Pairs among the six linear pieces of a depth along an edge (their crossings are its breakpoints).
_PAIRS = np.array([(m, k) for m in range(6) for k in range(m + 1, 6)])


@dataclass(frozen=True)
class CheckTolerances:
    """The checker's margins (see the module docstring for each one's reason)."""

    late_rel: float = 1e-12
    touch_rel: float = 1e-9
    touch_round: float = 2.0**17
    gap_round: float = 64.0
    overlap_round: float = 256.0
    grid: int = 2  # uniform intervals per query before refinement
    ladder: float = 64.0  # ratio of the geometric samples towards an answer
    max_rounds: int = 72  # halvings: enough to reach late_rel of the range from the grid and beyond
    max_intervals: int = 512  # open intervals per query before it is handed on as doubtful
    mp_prec: int = 200  # bits for the mpmath tier
    mp_max_intervals: int = 8  # a doubtful query with more open intervals than this is not worth mpmath
    mp_max_rounds: int = 40


DEFAULT = CheckTolerances()


# ---------------------------------------------------------------- arithmetic backends
class _Float:
    """float64: vectorised."""

    eps = float(np.finfo(float).eps)
    ninf = -np.inf
    sqrt = staticmethod(np.sqrt)

    @staticmethod
    def tofloat(x):
        return x


class _MP:
    """mpmath at ``prec`` bits through numpy object arrays (same code, elementwise mpf)."""

    def __init__(self, prec):
        import mpmath

        self.mp = mpmath
        self.prec = prec
        self.eps = 2.0 ** (1 - prec)
        self.ninf = mpmath.ninf
        self._mpf = np.frompyfunc(mpmath.mpf, 1, 1)
        self.sqrt = np.frompyfunc(mpmath.sqrt, 1, 1)

    def arr(self, x):
        x = np.asarray(x)
        return x if x.dtype == object else self._mpf(x.astype(float))  # doubles convert exactly

    @staticmethod
    def tofloat(x):
        return np.asarray(x, dtype=object).astype(float)  # mpf -> nearest double


# ---------------------------------------------------------------- geometry
def _vertex_coeffs(lo, hi, coeffs):
    """(n, 3, 8, 3): coefficient of t^k of each world vertex, from (n, 3) corners and motions."""
    p = np.where(SIGNS[None] > 0, hi[:, None, :], lo[:, None, :])  # (n, 8, 3) local corners
    rot = coeffs[:, :, None, :3, :3]  # (n, 3, 1, 3, 3)
    return (rot @ p[:, None, :, :, None])[..., 0] + coeffs[:, :, None, :3, 3]


def _magnitude(lo, hi, coeffs, tmax):
    """(n,) bound of |every term| of a vertex coordinate: sum_k (|C_k| |p| + |c_k|) tmax^k."""
    p = np.maximum(np.abs(lo), np.abs(hi))
    per_k = (np.abs(coeffs[:, :, :3, :3]) @ p[:, None, :, None])[..., 0] + np.abs(coeffs[:, :, :3, 3])
    return (per_k * (tmax ** np.arange(3))[:, None]).sum(axis=1).max(axis=1)


def _reach(X, smax):
    """(n,) bound of |vertex coordinate| over |s| <= smax from coefficients (n, 3, 8, 3)."""
    return (np.abs(X) * (smax ** np.arange(3))[:, None, None]).sum(axis=1).max(axis=(1, 2))


def _time_origin(t0, t1):
    """A float tc such that t - tc is exact for every float t in [t0, t1] (Sterbenz), and small."""
    span = t1 - t0
    return t0 if t0 >= span else (t1 if t1 <= -span else 0.0)


def _recentred(batch, tc):
    """Vertex coefficients of both boxes in time t - tc and space minus A's first vertex at tc,
    computed in longdouble and rounded to float64; and the bound of that computation's
    error on a vertex position, per query."""
    ext = np.longdouble
    eps_ext = float(np.finfo(ext).eps)  # the double eps where longdouble is double
    X = []
    for lo, hi, c in ((batch.lo_a, batch.hi_a, batch.coeffs_a), (batch.lo_b, batch.hi_b, batch.coeffs_b)):
        x = _vertex_coeffs(lo.astype(ext), hi.astype(ext), np.asarray(c, ext))
        X.append(np.stack([x[:, 0] + tc * (x[:, 1] + tc * x[:, 2]), x[:, 1] + 2 * tc * x[:, 2], x[:, 2]], axis=1))
    origin = X[0][:, 0, 0].astype(float)[:, None, :]  # A's first vertex at tc, as a float
    for x in X:
        x[:, 0] -= origin
    # Each step above rounds once per term, and |tc| + |t - tc| <= tmax for t in the range, so a
    # vertex position at t is off by at most ~8 eps_ext R_orig (R_orig: the terms at tmax); 4x that.
    tmax = max(abs(batch.t_range[0]), abs(batch.t_range[1]))
    r_orig = np.maximum(_magnitude(batch.lo_a, batch.hi_a, batch.coeffs_a, tmax),
                        _magnitude(batch.lo_b, batch.hi_b, batch.coeffs_b, tmax))
    return X[0].astype(float), X[1].astype(float), 32 * eps_ext * r_orig


def _at(X, t):
    """(m, 8, 3) vertex positions from coefficients (m, 3, 8, 3) at times t (m,)."""
    t = t[:, None, None]
    return X[:, 0] + t * (X[:, 1] + t * X[:, 2])


def _cross(a, b):
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1], a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _edges(V):
    return V[:, list(_AXIS_EDGES)] - V[:, :1]  # (m, 3, 3): x, y, z edge vectors


def _sat(VA, VB, num):
    """Best separating axis of vertex sets (m, 8, 3): gap (m,), unit axis (m, 3), side (m,)
    (+1: B on the axis' positive side of A). The gap is a lower bound of the distance."""
    ea, eb = _edges(VA), _edges(VB)
    roll = ([1, 2, 0], [2, 0, 1])
    axes = np.concatenate([_cross(ea[:, roll[0]], ea[:, roll[1]]), _cross(eb[:, roll[0]], eb[:, roll[1]]),
                           _cross(ea[:, :, None], eb[:, None]).reshape(len(VA), 9, 3)], axis=1)
    n = num.sqrt((axes * axes).sum(-1))
    ok = n > 0  # an exactly zero axis (parallel edges) has no direction; any other is a valid test
    u = axes / np.where(ok, n, 1)[..., None]
    pa, pb = u @ np.swapaxes(VA, 1, 2), u @ np.swapaxes(VB, 1, 2)  # (m, 15, 8)
    plus, minus = pb.min(-1) - pa.max(-1), pa.min(-1) - pb.max(-1)
    side = np.where(plus >= minus, 1, -1)
    sep = np.where(ok, np.where(side > 0, plus, minus), num.ninf)
    k = np.argmax(sep.astype(float) if sep.dtype == object else sep, axis=1)
    rows = np.arange(len(VA))
    return sep[rows, k], u[rows, k], side[rows, k]


def _interval_min(XA, XB, u, side, ta, tb):
    """(m,) exact minimum over [ta, tb] of the separation along the fixed axis u (m, 3) with
    B on ``side``: the least of the 64 quadratics side * u.(b_j(t) - a_i(t)). At the ends the
    least pair is the least b_j minus the greatest a_i; inside, only a pair whose quadratic
    is convex with its vertex in the interval can go lower."""
    ca = side[:, None, None] * (XA @ u[:, None, :, None])[..., 0]  # (m, 3, 8): coefficient k of side u.a_i
    cb = side[:, None, None] * (XB @ u[:, None, :, None])[..., 0]

    def ends(t):
        t = t[:, None]
        return (cb[:, 0] + t * (cb[:, 1] + t * cb[:, 2])).min(-1) - (ca[:, 0] + t * (ca[:, 1] + t * ca[:, 2])).max(-1)

    low = np.minimum(ends(ta), ends(tb))
    f2 = cb[:, 2, None, :] - ca[:, 2, :, None]  # (m, 8, 8)
    convex = f2 > 0
    if not convex.any():
        return low
    f1 = cb[:, 1, None, :] - ca[:, 1, :, None]
    tv = -f1 / np.where(convex, 2 * f2, 1)
    ta, tb = ta[:, None, None], tb[:, None, None]
    inside = convex & (tv > ta) & (tv < tb)
    f0 = cb[:, 0, None, :] - ca[:, 0, :, None]
    tv = np.where(inside, tv, ta)
    vertex = np.where(inside, f0 + tv * (f1 + tv * f2), np.inf)
    return np.minimum(low, vertex.reshape(len(u), 64).min(-1))


def _frame(V, num):
    """Box Q (vertices (m, 8, 3)) as its first vertex, the normals to its three face pairs,
    its signed volume and its widths across them: coordinates lam = n_k.(x - q0) / vol run
    over [0, 1] inside Q, and lam_k * width_k is the distance past the face lam_k = 0."""
    e = _edges(V)
    nrm = _cross(e[:, [1, 2, 0]], e[:, [2, 0, 1]])  # (m, 3, 3): normal k is across edge k
    vol = (nrm[:, 0] * e[:, 0]).sum(-1)
    return V[:, 0], nrm, vol, np.abs(vol)[:, None] / num.sqrt((nrm * nrm).sum(-1))


def _coords(X, frame):
    """(m, p, 3) coordinates of points X (m, p, 3) in a box's edge frame."""
    q0, nrm, vol, _ = frame
    return ((X - q0[:, None]) @ np.swapaxes(nrm, 1, 2)) / vol[:, None, None]


def _inside(lam, width):
    """Distance inside the box of points with coordinates lam (m, p, 3), negative outside."""
    w = width[:, None, :]
    return np.minimum(lam * w, (1 - lam) * w).min(-1)


def _edge_depth(la, lb, width):
    """(m,) the largest depth inside Q of a point on one of P's edges, given the edges' end
    coordinates la, lb (m, 12, 3) in Q's frame: the depth along an edge is concave and
    piecewise linear in the edge parameter, so its maximum is at an end or a breakpoint."""
    h = width[:, None, :]
    alpha = np.concatenate([la * h, (1 - la) * h], axis=-1)  # distance past each face plane at s = 0
    beta = np.concatenate([(lb - la) * h, (la - lb) * h], axis=-1)  # and its slope along the edge
    a1, a2 = alpha[..., _PAIRS[:, 0]], alpha[..., _PAIRS[:, 1]]
    den = beta[..., _PAIRS[:, 0]] - beta[..., _PAIRS[:, 1]]
    s = np.where(den != 0, np.minimum(np.maximum((a2 - a1) / np.where(den != 0, den, 1), 0), 1), 0)
    ends = s[..., :1] * 0
    cand = np.concatenate([ends, ends + 1, s], axis=-1)  # (m, 12, 17)
    depth = (alpha[..., None, :] + cand[..., None] * beta[..., None, :]).min(-1)
    return depth.reshape(len(la), -1).max(-1)


def _clipped(VP, la, lb):
    """The parts of P's edges inside Q (Liang-Barsky on Q's coordinates): their end points
    (m, 24, 3) and which exist (m, 24)."""
    d = lb - la
    flat = d == 0
    dd = np.where(flat, 1, d)
    s0, s1 = -la / dd, (1 - la) / dd
    enter = np.where(flat, np.where((la >= 0) & (la <= 1), -np.inf, np.inf), np.minimum(s0, s1)).max(-1)
    leave = np.where(flat, np.where((la >= 0) & (la <= 1), np.inf, -np.inf), np.maximum(s0, s1)).min(-1)
    lo, hi = np.maximum(enter, 0), np.minimum(leave, 1)
    ok = lo <= hi
    lo, hi = np.where(ok, lo, 0), np.where(ok, hi, 0)
    a, e = VP[:, _EDGE_I], VP[:, _EDGE_J] - VP[:, _EDGE_I]
    pts = np.concatenate([a + lo[..., None] * e, a + hi[..., None] * e], axis=1)
    return pts, np.concatenate([ok, ok], axis=1)


def _witness_depth(VA, VB, num):
    """(m,) depth of the best overlap witness found: a point on an edge of one box inside the
    other (in P by construction), or the centroid of the ends of the edge parts inside
    the other box (in both, by convexity; its depth is measured in both), for overlaps
    whose edges all lie in the other box's faces (coplanar faces)."""
    fa, fb = _frame(VA, num), _frame(VB, num)
    a_in_b, b_in_a = _coords(VA, fb), _coords(VB, fa)
    best = np.maximum(_edge_depth(a_in_b[:, _EDGE_I], a_in_b[:, _EDGE_J], fb[3]),
                      _edge_depth(b_in_a[:, _EDGE_I], b_in_a[:, _EDGE_J], fa[3]))
    pa, oka = _clipped(VA, a_in_b[:, _EDGE_I], a_in_b[:, _EDGE_J])
    pb, okb = _clipped(VB, b_in_a[:, _EDGE_I], b_in_a[:, _EDGE_J])
    pts, ok = np.concatenate([pa, pb], axis=1), np.concatenate([oka, okb], axis=1)
    count = ok.sum(-1)
    c = (pts * ok[..., None]).sum(1) / np.maximum(count, 1)[:, None]
    depth_c = np.minimum(_inside(_coords(c[:, None], fa), fa[3]), _inside(_coords(c[:, None], fb), fb[3]))[:, 0]
    return np.maximum(best, np.where(count > 0, depth_c, best))


# ---------------------------------------------------------------- the search
@dataclass
class _Problem:
    """One tier's view of n queries: vertex coefficients in its arithmetic (in time t - tc),
    the questions asked and the bounds, and what has been found so far."""

    num: object
    XA: np.ndarray  # (n, 3, 8, 3)
    XB: np.ndarray
    tc: float  # the coefficients' time origin
    ts: np.ndarray  # (n,) the solver's answers (NaN: none), as floats
    hit: np.ndarray
    cut: np.ndarray  # certify apart on [t0, cut]: ts - late for answers, t1 otherwise
    tau: np.ndarray  # touching tolerance
    err_gap: np.ndarray  # rounding bound of a SAT value or interval bound
    err_overlap: np.ndarray  # rounding bound of a witness depth
    ghost_open: np.ndarray  # answers not yet shown to touch within tau (a SAT gap <= tau somewhere)

    def __post_init__(self):
        n = len(self.ts)
        self.verdict = np.full(n, -1)  # -1 while undecided
        self.evidence = np.full(n, np.nan)  # the time of a certified overlap (MISS, LATE)
        self.doubtful = np.zeros(n, bool)  # gave up: budget or precision exhausted
        self.parked = np.zeros(n, bool)  # has intervals only rounding keeps open (for the next tier)

    def sample(self, q, t):
        """SAT at (query q, time t) pairs; certifies overlaps and touching as it goes. Times
        are compared in the tier's own arithmetic (a float cut is exact in mpmath)."""
        VA, VB = _at(self.XA[q], t - self.tc), _at(self.XB[q], t - self.tc)
        g, u, side = _sat(VA, VB, self.num)
        look = (g <= 0) & (self.verdict[q] < 0)
        if look.any():
            depth = _witness_depth(VA[look], VB[look], self.num)
            qq, tt = q[look], t[look]
            sure = depth > self.err_overlap[qq]
            qq, tt = qq[sure], tt[sure]
            miss, late = ~self.hit[qq], self.hit[qq] & (tt < self.cut[qq])
            self.verdict[qq[miss]] = MISS
            self.verdict[qq[late]] = LATE
            self.evidence[qq[miss | late]] = self.num.tofloat(tt[miss | late]).astype(float)
        touch = self.hit[q] & (g <= self.tau[q] - self.err_gap[q])
        self.ghost_open[q[touch]] = False
        return g, u, side

    def bound(self, q, ta, tb, ends):
        """Certified lower bound of the distance over each [ta, tb]: along the axis of its
        left end, and where that does not settle it, also along its right end's axis."""
        (_, ua, sa), (_, ub, sb) = ends
        lb = self._along(q, ta, tb, ua, sa)
        redo = self.open_(q, ta, lb)
        if redo.any():
            lb[redo] = np.maximum(lb[redo], self._along(q[redo], ta[redo], tb[redo], ub[redo], sb[redo]))
        return lb

    def _along(self, q, ta, tb, u, side):
        m = _interval_min(self.XA[q], self.XB[q], u, side, ta - self.tc, tb - self.tc)
        # As a float: rounding is monotone, so lb > x (a float) still implies it exactly.
        return self.num.tofloat(m - self.err_gap[q]).astype(float)

    def open_(self, q, ta, lb, slack=0.0):
        """Intervals that do not settle their query's question yet (with ``slack`` added to
        their bounds: the rounding bound, to ask whether only rounding keeps them open)."""
        lb = lb + slack
        need_apart = (~self.hit[q] | (ta < self.cut[q])) & ~(lb > 0)
        need_ghost = self.hit[q] & self.ghost_open[q] & ~(lb > self.tau[q])
        return (self.verdict[q] < 0) & ~self.doubtful[q] & (need_apart | need_ghost)


def _search(P: _Problem, q, ta, tb, ends, max_rounds, max_intervals):
    """Halve the open intervals round after round. Returns the intervals (q, ta, tb) left
    for the next tier: those parked (open only by rounding) and all open ones of the
    queries that gave up (too many intervals, no room to halve, or out of rounds)."""
    left = []

    def hand_on(mask):
        nonlocal q, ta, tb, ends
        left.append((q[mask], ta[mask], tb[mask]))
        keep = ~mask
        q, ta, tb = q[keep], ta[keep], tb[keep]
        ends = tuple(tuple(x[keep] for x in e) for e in ends)

    for rnd in range(max_rounds + 1):
        lb = P.bound(q, ta, tb, ends)
        keep = P.open_(q, ta, lb)
        q, ta, tb, lb = q[keep], ta[keep], tb[keep], lb[keep]
        ends = tuple(tuple(x[keep] for x in e) for e in ends)
        # Halving brings the bound towards the smaller end value; when even that is within a few
        # rounding bounds of deciding, only more precision helps: park the interval.
        err = P.num.tofloat(P.err_gap[q]).astype(float)
        ends_low = P.num.tofloat(np.minimum(ends[0][0], ends[1][0])).astype(float)
        parked = ~P.open_(q, ta, lb, slack=2 * err) & P.open_(q, ta, ends_low - 4 * err)
        P.parked[q[parked]] = True
        hand_on(parked)
        mid = (ta + tb) / 2
        stuck = (mid <= ta) | (mid >= tb)  # no room left at this precision
        crowded = np.bincount(q, minlength=len(P.ts)) > max_intervals
        give_up = crowded[q] | np.isin(q, q[stuck]) | (rnd == max_rounds)
        P.doubtful[q[give_up]] = True
        hand_on(give_up | P.doubtful[q])
        if len(q) == 0:
            break
        mid = (ta + tb) / 2
        m = P.sample(q, mid)
        q = np.concatenate([q, q])
        ta, tb = np.concatenate([ta, mid]), np.concatenate([mid, tb])
        ends = (tuple(np.concatenate([a, b]) for a, b in zip(ends[0], m)),
                tuple(np.concatenate([a, b]) for a, b in zip(m, ends[1])))
    if not left:
        return np.zeros(0, int), np.zeros(0), np.zeros(0)
    return tuple(np.concatenate(x) for x in zip(*left))


def _finish(P: _Problem):
    """Verdicts of the queries whose every interval settled."""
    done = (P.verdict < 0) & ~P.doubtful & ~P.parked
    P.verdict[done & ~P.hit] = CLEAR_MISS
    P.verdict[done & P.hit & P.ghost_open] = FALSE_HIT
    P.verdict[done & P.hit & ~P.ghost_open] = HIT


# ---------------------------------------------------------------- entry point
@dataclass(frozen=True)
class Checked:
    """Verdicts of one batch: ``verdict`` (n,) codes (``VERDICTS[code]`` names them);
    ``evidence`` (n,) the time of the certified overlap (MISS, LATE), else NaN; ``early_gap``
    (n,) the SAT gap at the answer in units of the smaller box's size, clipped at 0 (how far
    apart the boxes still were when reported touching; NaN without an answer); ``early``
    (n,) answers certified more than the touching tolerance apart at t_s; ``mp`` (n,)
    whether the query needed the mpmath tier."""

    verdict: np.ndarray
    evidence: np.ndarray
    early_gap: np.ndarray
    early: np.ndarray
    mp: np.ndarray


def _sizes(X, s):
    """(n,) half the sum of the three edge lengths, and the longest edge, of boxes at s."""
    V = _at(X, np.full(len(X), s))
    lengths = np.sqrt((_edges(V) ** 2).sum(-1))
    return 0.5 * lengths.sum(-1), lengths.max(-1)


def _initial_samples(t0, t_end, cut, ladder_on, late, grid, ratio):
    """(q, t) sorted: a uniform grid on each [t0, t_end] and, where ``ladder_on``, the
    ladder cut - late (ratio^k - 1) inside it (towards cut from below; with a negative
    ``late``, away from it upwards). ``t0`` is a float or one per query."""
    n = len(t_end)
    t0 = np.broadcast_to(np.asarray(t0, float), (n,))
    k = np.arange(grid + 1) / grid
    q = [np.repeat(np.arange(n), grid + 1)]
    t = [(t0[:, None] + (t_end - t0)[:, None] * k).ravel()]
    t[0][grid::grid + 1] = t_end  # the grid ends exactly at t_end
    span = max(float((t_end - t0).max()), abs(late))
    rungs = ratio ** np.arange(int(np.ceil(np.log(span / abs(late)) / np.log(ratio))) + 1) - 1
    lad = cut[:, None] - late * rungs
    ok = ladder_on[:, None] & (lad > t0[:, None]) & (lad < t_end[:, None])
    q.append(np.broadcast_to(np.arange(n)[:, None], lad.shape)[ok])
    t.append(lad[ok])
    q, t = np.concatenate(q), np.concatenate(t)
    order = np.lexsort((t, q))
    q, t = q[order], t[order]
    new = np.ones(len(q), bool)
    new[1:] = (q[1:] != q[:-1]) | (t[1:] != t[:-1])
    return q[new], t[new]


def check(batch: QueryBatch, t_solver, tol: CheckTolerances = DEFAULT) -> Checked:
    """Judge the solver's answers ``t_solver`` (n,) (NaN: no contact) on ``batch``."""
    n = batch.n
    ts = np.asarray(t_solver, dtype=float)
    t0, t1 = batch.t_range
    hit = np.isfinite(ts)
    late = tol.late_rel * (t1 - t0)
    cut = np.where(hit, ts - late, t1)
    t_end = np.where(hit, ts, t1)
    eps = _Float.eps

    tmax = max(abs(t0), abs(t1))
    r_world = np.maximum(_magnitude(batch.lo_a, batch.hi_a, batch.coeffs_a, tmax),
                         _magnitude(batch.lo_b, batch.hi_b, batch.coeffs_b, tmax))
    tc = _time_origin(t0, t1)
    XA, XB, err_prep = _recentred(batch, tc)
    (half_a, long_a), (half_b, long_b) = _sizes(XA, t0 - tc), _sizes(XB, t0 - tc)
    tau = tol.touch_rel * (half_a + half_b) + tol.touch_round * eps * r_world
    r = np.maximum(_reach(XA, max(abs(t0 - tc), abs(t1 - tc))), _reach(XB, max(abs(t0 - tc), abs(t1 - tc))))
    P = _Problem(_Float, XA, XB, tc, ts, hit, cut, tau, tol.gap_round * eps * r + 2 * err_prep,
                 tol.overlap_round * eps * r + 4 * err_prep, hit.copy())
    q, t = _initial_samples(t0, t_end, cut, hit, late, tol.grid, tol.ladder)
    g, u, side = P.sample(q, t)
    at_ts = hit[q] & (t == ts[q])
    early = np.full(n, np.nan)
    early[q[at_ts]] = np.maximum(g[at_ts], 0.0) / np.minimum(long_a, long_b)[q[at_ts]]
    beyond = np.zeros(n, bool)
    beyond[q[at_ts]] = g[at_ts] - P.err_gap[q[at_ts]] > tau[q[at_ts]]
    far = np.nonzero(P.ghost_open & (ts < t1))[0]  # no touch up to t_s: is one coming, or none at all?
    if len(far):
        qf, tf = _initial_samples(ts[far], np.full(len(far), t1), ts[far], np.ones(len(far), bool), -late, tol.grid,
                                  tol.ladder)
        gf, uf, sf = P.sample(far[qf], tf)
        q, t = np.concatenate([q, far[qf]]), np.concatenate([t, tf])
        g, u, side = np.concatenate([g, gf]), np.concatenate([u, uf]), np.concatenate([side, sf])
        order = np.lexsort((t, q))
        keep = np.ones(len(q), bool)
        keep[1:] = (q[order][1:] != q[order][:-1]) | (t[order][1:] != t[order][:-1])
        order = order[keep]
        q, t, g, u, side = q[order], t[order], g[order], u[order], side[order]
    pair = q[1:] == q[:-1]
    i, j = np.nonzero(pair)[0], np.nonzero(pair)[0] + 1
    lone = np.nonzero(np.bincount(q, minlength=n)[q] == 1)[0]  # an answer at t0: the interval [t0, t0]
    i, j = np.concatenate([i, lone]), np.concatenate([j, lone])
    left = _search(P, q[i], t[i], t[j], ((g[i], u[i], side[i]), (g[j], u[j], side[j])), tol.max_rounds,
                   tol.max_intervals)
    _finish(P)
    used_mp = (P.doubtful | P.parked) & (P.verdict < 0)
    if used_mp.any():
        _mp_tier(batch, P, left, tol)
    P.verdict[P.verdict < 0] = UNRESOLVED
    return Checked(P.verdict, P.evidence, early, beyond, used_mp)


def _mp_tier(batch, P: _Problem, left, tol):
    """The doubtful queries again at ``tol.mp_prec`` bits, from the intervals handed on."""
    q, ta, tb = left
    few = np.bincount(q, minlength=len(P.ts)) <= tol.mp_max_intervals
    todo = np.nonzero((P.doubtful | P.parked) & (P.verdict < 0) & few)[0]
    if len(todo) == 0:
        return
    num = _MP(tol.mp_prec)
    with num.mp.workprec(tol.mp_prec):
        sub = batch.take(todo)
        XA = _vertex_coeffs(num.arr(sub.lo_a), num.arr(sub.hi_a), num.arr(sub.coeffs_a))
        XB = _vertex_coeffs(num.arr(sub.lo_b), num.arr(sub.hi_b), num.arr(sub.coeffs_b))
        tmax = max(abs(sub.t_range[0]), abs(sub.t_range[1]))
        # float64 magnitudes, doubled: they bound the exact terms to within float rounding
        r = 2 * np.maximum(_magnitude(sub.lo_a, sub.hi_a, sub.coeffs_a, tmax),
                           _magnitude(sub.lo_b, sub.hi_b, sub.coeffs_b, tmax))
        Q = _Problem(num, XA, XB, 0.0, P.ts[todo], P.hit[todo], P.cut[todo], P.tau[todo],
                     tol.gap_round * num.eps * r, tol.overlap_round * num.eps * r, P.ghost_open[todo].copy())
        index = np.full(len(P.ts), -1)
        index[todo] = np.arange(len(todo))
        mine = index[q] >= 0
        qq, a, b = index[q[mine]], num.arr(ta[mine]), num.arr(tb[mine])
        _search(Q, qq, a, b, (Q.sample(qq, a), Q.sample(qq, b)), tol.mp_max_rounds, 4 * tol.mp_max_intervals)
        _finish(Q)
    P.verdict[todo] = Q.verdict  # still -1 where mpmath did not settle it either
    P.evidence[todo] = Q.evidence
