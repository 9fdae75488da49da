"""Numerical extremes: named families of cases, each judged against the oracle.

Used by tests/test_stress.py (a reduced tier in the default run, the full sweep
under ``pytest -m stress``) and by docs/make_accuracy.py, which writes the
tables of docs/accuracy.md. Every family yields (parameter, Case); ``judge``
compares the solver with the truth:

* the oracle's crossing (conservative advancement, then bisection of the
  mpmath gap to 1e-14 of the range) for hits, its advancement for misses;
* for the "far from the origin" family (the scene turned and moved up to 1e6
  box sizes away), the crossing of the moved case's own mpmath gap, bisected
  around its twin's at the origin; also reported: how far each answer lies from
  its twin's (the far rows must equal the near ones).

Reported per case: the time error (solver minus truth, in units of the range;
negative is early), the mpmath gap at the solver's time (in units of the smaller
box's size; positive is early, apart), and whether it missed, hit falsely or
was late.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from cases import make_case, pose

from bullet_boxccd import Box, QuadraticMotion, time_of_impact
from bullet_boxccd.motion import rotation_matrix
from bullet_boxccd.testing import Case, mp_bisect, mp_gap, reference

LATE = 1e-12  # of the range: later than the truth by more than this is "late"


def solve(case):
    return time_of_impact(Box(case.lo_a, case.hi_a), QuadraticMotion(case.coeffs_a), Box(case.lo_b, case.hi_b),
                          QuadraticMotion(case.coeffs_b), (case.t0, case.t1))


def moving(lo, hi, motion_a, lo_b, hi_b, motion_b, t0=0.0, t1=1.0):
    return Case(np.asarray(lo, float), np.asarray(hi, float), motion_a.coeffs.copy(), np.asarray(lo_b, float),
                np.asarray(hi_b, float), motion_b.coeffs.copy(), t0, t1)


def mp_crossing(case, lo, hi):
    """The mpmath gap's crossing, bisected (in floats) to 1e-14 of the range in [lo, hi]
    (gap(lo) > 0 >= gap(hi)): the first float time of the final bracket's gap <= 0."""
    return mp_bisect(case, lo, hi, 1e-14 * (case.t1 - case.t0))[1]


def true_contact(case, ref=None):
    """Truth: ('hit', t) with t bisected on the mpmath gap, or ('miss', min gap) /
    ('unresolved', min gap) from the oracle's advancement."""
    ref = ref or reference(case)
    if ref.outcome != "hit":
        return ref.outcome, ref.min_gap
    span = case.t1 - case.t0
    if ref.t_hit == case.t0:
        return "hit", case.t0
    lo, hi = max(case.t0, ref.t_hit - 1e-9 * span), min(case.t1, ref.t_hit + 1e-9 * span)
    if mp_gap(case, lo) <= 0 or mp_gap(case, hi) > 0:
        return "hit", ref.t_hit  # the float bisection's answer already sits on the crossing
    return "hit", mp_crossing(case, lo, hi)


@dataclass
class Tally:
    """What one family's sweep found at one parameter value."""

    cases: int = 0
    hits: int = 0
    misses: int = 0  # truth hits, solver None
    false_hits: int = 0  # truth clear miss, solver hit where the boxes are apart beyond tolerance
    late: int = 0
    worst_early: float = 0.0  # most negative time error (range units)
    worst_gap: float = 0.0  # largest mpmath gap at a reported time (box sizes)
    worst_shift: float = 0.0  # far family: largest |t - t of the twin at the origin| (range units)
    notes: list = field(default_factory=list)

    def add(self, other: "Tally"):
        for k in ("cases", "hits", "misses", "false_hits", "late"):
            setattr(self, k, getattr(self, k) + getattr(other, k))
        self.worst_early = min(self.worst_early, other.worst_early)
        self.worst_gap = max(self.worst_gap, other.worst_gap)
        self.worst_shift = max(self.worst_shift, other.worst_shift)
        self.notes += other.notes


def judge(case, truth=None, touch=1e-9) -> Tally:
    """Compare the solver with the truth on one case (``touch``: the gap, in box sizes,
    below which a pass counts as touching)."""
    got = solve(case)
    kind, value = truth or true_contact(case)
    L, span = case.size(), case.t1 - case.t0
    t = Tally(cases=1)
    if kind == "hit":
        t.hits = 1
        if got is None:
            t.misses = 1
            t.notes.append("miss:\n" + case.repro())
            return t
        err = (got.t - value) / span
        t.worst_early = min(0.0, err)
        if err > LATE:
            t.late = 1
            t.notes.append(f"late by {err:.3e}:\n" + case.repro())
        t.worst_gap = max(0.0, float(mp_gap(case, got.t)) / L)
        return t
    if got is not None:
        gap = float(mp_gap(case, got.t)) / L
        t.worst_gap = max(0.0, gap)
        if kind == "miss" and value > 2 * touch * L and gap > touch:
            t.false_hits = 1
            t.notes.append(f"false hit (gap {gap:.3e}):\n" + case.repro())
    return t


# ------------------------------------------------------------------ families
def scaled(case: Case, s: float) -> Case:
    c = lambda m: np.concatenate([m[:, :3, :], m[:, 3:, :]], axis=1)  # noqa: E731
    ca, cb = case.coeffs_a.copy(), case.coeffs_b.copy()
    ca[:, :3, 3] *= s
    cb[:, :3, 3] *= s
    return Case(case.lo_a * s, case.hi_a * s, c(ca), case.lo_b * s, case.hi_b * s, c(cb), case.t0, case.t1)


def fam_size(n):
    """Box size from 1e-4 to 1e4 (the whole scene scaled)."""
    for s in (1e-4, 1e-2, 1e2, 1e4):
        for seed in range(n):
            case = make_case(seed + 4, "rotating")  # from seed 4: hits and misses alike, even for n = 3
            yield f"{s:.0e}", scaled(case, s / case.size())


def fam_aspect(n):
    """Plates and needles: aspect ratio up to 1e4, both boxes."""
    rng = np.random.default_rng(1)
    for a in (1e-2, 1e-3, 1e-4):
        for seed in range(n):
            ha = np.array([1.0, 1.0, a]) if seed % 2 else np.array([1.0, a, a])
            hb = np.array([1.0, a, 1.0]) if seed % 2 else np.array([a, a, 1.0])
            Ra = rotation_matrix(rng.normal(size=3), rng.uniform(0, np.pi))
            Rb = rotation_matrix(rng.normal(size=3), rng.uniform(0, np.pi))
            start = rng.normal(size=3)
            start *= 3.0 / np.linalg.norm(start)
            aim = rng.uniform(-0.5, 0.5, 3)
            m_b = QuadraticMotion.screw(pose(Rb, start), aim - start, rng.normal(size=3) * 0.5)
            yield f"{1 / a:.0e}", moving(-ha, ha, QuadraticMotion.static(pose(Ra)), -hb, hb, m_b)


def fam_speed(n):
    """Up to 1e4 box lengths per unit time (B starts far and arrives mid-range)."""
    rng = np.random.default_rng(2)
    for v in (1e2, 1e3, 1e4):
        for _ in range(n):
            h = rng.uniform(0.3, 1.0, 3)
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            start = d * v * rng.uniform(0.3, 0.7)
            aim = rng.uniform(-1.0, 1.0, 3)
            m_b = QuadraticMotion.screw(pose(rotation_matrix(rng.normal(size=3), 1.0), start),
                                        (aim - start) / np.linalg.norm(aim - start) * v, rng.normal(size=3))
            yield f"{v:.0e}", moving(-h, h, QuadraticMotion.static(), -h[::-1], h[::-1], m_b)


def fam_rotation(n):
    """Rotation over the range up to pi (both boxes)."""
    for angle in (np.pi / 2, 0.9 * np.pi, np.pi):
        rng = np.random.default_rng(3)
        for _ in range(n):
            h = rng.uniform(0.2, 1.0, 3)
            start = rng.normal(size=3)
            start *= 2.5 / np.linalg.norm(start)
            m_a = QuadraticMotion.screw(pose(rotation_matrix(rng.normal(size=3), 2.0)), (0, 0, 0),
                                        rng.normal(size=3) / np.sqrt(3) * angle)
            axis = rng.normal(size=3)
            m_b = QuadraticMotion.screw(pose(rotation_matrix(rng.normal(size=3), 1.0), start),
                                        -start + rng.uniform(-0.5, 0.5, 3), axis / np.linalg.norm(axis) * angle)
            yield f"{angle / np.pi:.2g} pi", moving(-h, h, m_a, -h[::-1], h[::-1], m_b)


def fam_near_parallel(n):
    """Edges of the two boxes parallel up to a tilt theta, down to 1e-15 rad and exactly."""
    for theta in (1e-2, 1e-4, 1e-6, 1e-9, 1e-12, 1e-15, 0.0):
        rng = np.random.default_rng(4)
        for _ in range(n):
            axis = rng.normal(size=3)
            axis[2] = 0.0
            Ra = rotation_matrix((0, 0, 1), np.pi / 4)
            Rb = rotation_matrix(axis, theta) @ rotation_matrix((0, 0, 1), np.pi / 4)
            m_b = QuadraticMotion.ballistic((3.0, rng.uniform(-1e-3, 1e-3), rng.uniform(-0.5, 0.5)), (-4.0, 0, 0),
                                            rotation=Rb)
            h = np.full(3, 0.5)
            yield f"{theta:.0e}", moving(-h, h, QuadraticMotion.static(pose(Ra)), -h, h, m_b)


def fam_faces(n):
    """Faces parallel up to a tilt theta (face-on-face approach), down to 1e-15 rad and exactly."""
    for theta in (1e-3, 1e-6, 1e-9, 1e-12, 1e-15, 0.0):
        rng = np.random.default_rng(5)
        for _ in range(n):
            Rb = rotation_matrix(rng.normal(size=3), theta)
            m_b = QuadraticMotion.ballistic((3.0, rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5)), (-4.0, 0, 0),
                                            rotation=Rb)
            h = np.array([0.5, 0.7, 0.6])
            yield f"{theta:.0e}", moving(-h, h, QuadraticMotion.static(), -h[::-1], h[::-1], m_b)


def fam_sliding(n):
    """Face-on-face sliding: B's bottom face exactly on A's top plane (gap 0), or a
    hair above (1e-12 box sizes: inside the touching tolerance) or below, sliding
    in from the side and turning about the shared normal."""
    for gap in (0.0, 1e-12, -1e-12):
        rng = np.random.default_rng(9)
        for _ in range(n):
            ha, hb = rng.uniform(0.3, 1.0, 3), rng.uniform(0.3, 1.0, 3)
            z = ha[2] + hb[2] + gap
            ang = rng.uniform(0, 2 * np.pi)
            start = np.array([np.cos(ang), np.sin(ang), 0.0]) * 3.0
            start[2] = z
            aim = np.array([*rng.uniform(-0.5, 0.5, 2), z])
            m_b = QuadraticMotion.screw(pose(rotation_matrix((0, 0, 1), rng.uniform(0, np.pi)), start), aim - start,
                                        (0.0, 0.0, rng.uniform(-1.0, 1.0)))
            yield f"gap {gap:+.0e}", moving(-ha, ha, QuadraticMotion.static(), -hb, hb, m_b)


def fam_near_singular(n):
    """Motions whose 3x3 part is close to singular (a box squashed to eps of its size)."""
    for eps in (1e-3, 1e-6, 1e-9, 1e-12):
        rng = np.random.default_rng(6)
        for seed in range(n):
            S = np.diag([1.0, 1.0, eps]) if seed % 2 else np.diag([1.0, eps, 1.0])
            Ra = rotation_matrix(rng.normal(size=3), rng.uniform(0, 3)) @ S
            start = rng.normal(size=3)
            start *= 3.0 / np.linalg.norm(start)
            m_b = QuadraticMotion.screw(pose(rotation_matrix(rng.normal(size=3), 1.0), start),
                                        -start + rng.uniform(-0.4, 0.4, 3), rng.normal(size=3))
            h = np.array([0.5, 0.6, 0.7])
            yield f"{eps:.0e}", moving(-h, h, QuadraticMotion.static(pose(Ra)), -h, h, m_b)


def fam_boundaries(n):
    """Contacts at section boundaries: B turns about z through an octant switch (its
    face normal crossing A's) at the moment of a face contact; and near the ends of
    the range (within 1e-15 of the range)."""
    h = np.full(3, 0.5)
    for seed in range(n):
        # B's x face turns through parallel with A's at t = 0.5, when its face reaches x = 0.5.
        w = 0.2 * (1 + seed / n)
        R0 = rotation_matrix((0, 0, 1), -0.5 * w)
        m_b = QuadraticMotion.screw(pose(R0, (2.0, 0.0, 0.0)), (-2.0, 0, 0), (0, 0, w))
        yield "switch", moving(-h, h, QuadraticMotion.static(), -h, h, m_b)
    for seed in range(n):
        for end, frac in (("start", 1e-15), ("end", 1 - 1e-15)):
            t0, t1 = -2.0 + seed, 1.0 + seed * 3
            tc = t0 + frac * (t1 - t0)
            m_b = QuadraticMotion.ballistic((1.0 + 3.0 * (tc - 0.0), 0.1, 0.2), (-3.0, 0, 0))
            yield f"within 1e-15 of the {end}", moving(-h, h, QuadraticMotion.static(), -h, h, m_b, t0, t1)


def fam_grazing(n):
    """Double roots: B on a parabola whose lowest point passes A's top face at a gap g
    (0: a hit with a double root; 1e-9 box sizes: a miss)."""
    h = np.full(3, 0.5)
    for g in (0.0, 1e-9):
        rng = np.random.default_rng(7)
        for _ in range(n):
            k = rng.uniform(0.5, 5.0)
            tm = rng.uniform(0.2, 0.8)
            # y(t) = 1 + g + k (t - tm)^2, B's bottom at y - 0.5
            m_b = QuadraticMotion.ballistic((rng.uniform(-0.4, 0.4), 1.0 + g + k * tm * tm, rng.uniform(-0.4, 0.4)),
                                            (0.0, -2 * k * tm, 0.0), (0.0, 2 * k, 0.0))
            yield f"gap {g:.0e}", moving(-h, h, QuadraticMotion.static(), -h, h, m_b)


FAMILIES = {
    "size": fam_size, "aspect": fam_aspect, "speed": fam_speed, "rotation": fam_rotation,
    "near_parallel_edges": fam_near_parallel, "near_parallel_faces": fam_faces, "sliding": fam_sliding,
    "near_singular": fam_near_singular, "boundaries": fam_boundaries, "grazing": fam_grazing,
}


def grazing_truth(param, case):
    """Analytic truth of the grazing family: a touch at the parabola's apex, or a miss."""
    if param.startswith("gap 0e+00"):
        c1, c2 = case.coeffs_b[1, 1, 3], case.coeffs_b[2, 1, 3]
        return "hit", -c1 / (2 * c2)
    return "miss", 1e-9 * case.size()


def run_family(name, n):
    """{parameter: Tally} for one family with n cases per parameter value."""
    out = {}
    for param, case in FAMILIES[name](n):
        truth = grazing_truth(param, case) if name == "grazing" else None
        out.setdefault(param, Tally()).add(judge(case, truth, touch=2e-9 if name == "grazing" else 1e-9))
    return out


FAR_OFFSETS = (0.0, 1e3, 1e4, 1e5, 1e6)  # box sizes from the origin


def truth_near(case, twin_truth):
    """The truth of a moved case from its twin's at the origin: the moved case's own
    mpmath gap bisected around the twin's crossing (the move costs at most the
    coordinates' rounding, far inside the bracket), or the oracle if that fails."""
    kind, value = twin_truth
    if kind != "hit":
        return kind, value
    span = case.t1 - case.t0
    if value == case.t0 and mp_gap(case, case.t0) <= 0:
        return "hit", case.t0
    lo, hi = max(case.t0, value - 1e-7 * span), min(case.t1, value + 1e-7 * span)
    if not (mp_gap(case, lo) > 0 and mp_gap(case, hi) <= 0):
        return true_contact(case)
    return "hit", mp_crossing(case, lo, hi)


def far_family(n):
    """{offset: Tally}: seeded cases (ballistic and rotating), the whole scene turned
    by a random rotation and moved D box sizes from the origin in a random
    direction, judged against their own truth like every family; worst_shift is
    the largest difference from the same case's answer at the origin."""
    out = {}
    for D in FAR_OFFSETS:
        rng = np.random.default_rng(8)
        tally = Tally()
        for seed in range(n):
            base = make_case(seed, "ballistic" if seed % 2 else "rotating")
            L = base.size()
            direction = rng.normal(size=3)
            T = pose(rotation_matrix(rng.normal(size=3), rng.uniform(0, np.pi)),
                     direction / np.linalg.norm(direction) * D * L)
            moved = Case(base.lo_a, base.hi_a, np.einsum("ij,kjl->kil", T, base.coeffs_a), base.lo_b, base.hi_b,
                         np.einsum("ij,kjl->kil", T, base.coeffs_b), base.t0, base.t1)
            t = judge(moved, truth_near(moved, true_contact(base)))
            near, far = solve(base), solve(moved)
            if near is not None and far is not None:
                t.worst_shift = abs(far.t - near.t) / (base.t1 - base.t0)
            tally.add(t)
        out["0 (at the origin)" if D == 0 else f"{D:.0e}"] = tally
    return out
