"""Seeded random box pairs in named families, shared by the oracle and property tests,
and a check of two pairs whose answers are known in closed form."""

from __future__ import annotations

import numpy as np

from bullet_boxccd import QuadraticMotion
from bullet_boxccd.motion import rotation_matrix
from bullet_boxccd.testing import Case

FAMILIES = ("ballistic", "rotating", "one_static", "both_moving", "off_centre", "thin_plates")


def _unit(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def pose(R=None, p=(0.0, 0.0, 0.0)):
    """(4, 4) pose of a rotation R (3, 3) (None: the identity) and a position p."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = p
    return T


def _pose(rng, position):
    return pose(rotation_matrix(_unit(rng), rng.uniform(0, np.pi)), position)


def _box(rng, scale, family):
    h = scale * rng.uniform(0.2, 1.0, size=3)
    if family == "thin_plates":
        h[rng.integers(3)] *= 0.01
    c = scale * rng.uniform(-2.0, 2.0, size=3) if family == "off_centre" else np.zeros(3)
    return c - h, c + h


def make_case(seed: int, family: str) -> Case:
    """One pair: B flies from a few box sizes away towards a point near A, so that
    roughly half the pairs hit. Scale 1e-3..1e3, time ranges other than [0, 1]."""
    rng = np.random.default_rng([seed, FAMILIES.index(family)])
    scale = 10.0 ** rng.uniform(-3, 3)
    t0 = rng.uniform(-5, 5) if rng.random() < 0.7 else 0.0
    t1 = t0 + (10.0 ** rng.uniform(-1, 1) if rng.random() < 0.7 else 1.0)
    lo_a, hi_a = _box(rng, scale, family)
    lo_b, hi_b = _box(rng, scale, family)
    spin = {"ballistic": 0.0}.get(family, rng.uniform(0, np.pi / 2))  # rotation over the range
    start_b = _unit(rng) * scale * rng.uniform(2.5, 5.0)
    aim = scale * rng.uniform(-1.5, 1.5, size=3)
    pose_a = _pose(rng, np.zeros(3))
    if family in ("ballistic", "one_static", "off_centre") or family == "thin_plates" and rng.random() < 0.5:
        m_a = QuadraticMotion.static(pose_a)
    else:
        m_a = QuadraticMotion.screw(pose_a, scale * rng.normal(size=3), _unit(rng) * rng.uniform(0, np.pi / 2)
                                    / (t1 - t0), (t0, t1))
    pose_b = _pose(rng, start_b)
    m_b = QuadraticMotion.screw(pose_b, (aim - start_b) / (t1 - t0), _unit(rng) * spin / (t1 - t0), (t0, t1))
    return Case(lo_a, hi_a, m_a.coeffs.copy(), lo_b, hi_b, m_b.coeffs.copy(), t0, t1)


def batch_rows(n, gap_x=5.0):
    """Arrays for time_of_impact_batch: n pairs of 2 m cubes, B static at x = gap_x
    (1 m gaps at 3 or more apart: they never touch; 2 or less: touching)."""
    lo, hi = -np.ones((n, 3)), np.ones((n, 3))
    c = np.zeros((n, 3, 4, 4))
    c[:, 0] = np.eye(4)
    cb = c.copy()
    cb[:, 0, 0, 3] = gap_x
    return [lo, hi, c, lo.copy(), hi.copy(), cb]


def assert_known_answers():
    """Two unit cubes, B thrown from x = 3 at -4 per unit t: faces meet at t = 0.5;
    B thrown at y = 5 instead never touches. The hostile-input tests end with this
    (the solver must still answer exactly, single and batch, whatever came before)."""
    # Imported here: hypothesis keeps this module alive past the core's teardown, and
    # a module-level reference to the queries (their default Tolerances) would then
    # show as a nanobind leak at exit.
    from bullet_boxccd import Box, time_of_impact, time_of_impact_batch

    cube, still = Box.centered((0.5, 0.5, 0.5)), QuadraticMotion.static()
    hit = QuadraticMotion.ballistic((3.0, 0.1, 0.2), (-4.0, 0, 0))
    miss = QuadraticMotion.ballistic((3.0, 5.0, 0), (-4.0, 0, 0))
    c = time_of_impact(cube, still, cube, hit)
    assert c is not None and abs(c.t - 0.5) < 1e-11, c
    assert time_of_impact(cube, still, cube, miss) is None
    lo, hi = np.full((2, 3), -0.5), np.full((2, 3), 0.5)
    t = time_of_impact_batch(lo, hi, np.array([still.coeffs] * 2), lo, hi, np.array([hit.coeffs, miss.coeffs]))
    assert abs(t[0] - 0.5) < 1e-11 and np.isnan(t[1]), t
