"""Seeded query families for ``boxccd validate``: the stress families, vectorised.

Each family is a function ``f(rng, n) -> QueryBatch`` drawing ``n`` box pairs from a
numpy ``Generator``; ``FAMILIES`` maps names to them. A batch shares one time
range (``t_range``), so the solver takes it in one ``time_of_impact_batch`` call;
families that vary the range draw it per batch. ``param`` holds each query's
value of the family's knob (named by ``QueryBatch.param_name``), for the tables
and the case files.

Motions are built here, vectorised, from the same definitions as
``QuadraticMotion``: ``screw`` is the quadratic through the start, middle and end
poses of a rigid translate-and-spin (``QuadraticMotion.screw``), ``ballistic`` a
fixed orientation with p + v t + a t^2 / 2. Box A plays the BMS algorithm's S, box B its
M; B is thrown at A from a few box sizes away so that about half the pairs touch.

Families (the knob in brackets):

* ``scale`` [box size, 1e-4..1e4]: the whole scene scaled, B spinning up to pi/2.
* ``aspect`` [aspect ratio, 1e1..1e4]: plates and needles, both boxes.
* ``speed`` [box lengths per range, 1e1..1e4]: B arrives from far away.
* ``rotation`` [angle over the range, 0..pi]: both boxes spin and move.
* ``far`` [distance from the origin in box sizes, 1e2..1e6]: a pair moved and turned.
* ``grazing`` [gap at the apex in box sizes: 0, +-1e-9]: B on a parabola whose lowest
  vertex (or face) just reaches A's top face: double roots.
* ``near_parallel`` [tilt in rad, 0 or 1e-16..1e-2]: edges or faces parallel up to a tilt.
* ``range_ends`` [distance of the contact from an end of the range, in ranges,
  1e-15..1e-6]: ranges other than [0, 1].
* ``both_moving`` [box size]: both boxes translate and spin; off-centre boxes.
* ``one_static`` [box size]: A static; thin plates and off-centre boxes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..geometry import SIGNS, BoxPairs
from ..motion import axis_angle_matrix

__all__ = ["FAMILIES", "QueryBatch", "make_batch"]


@dataclass
class QueryBatch(BoxPairs):
    """``n`` box pairs: corners (n, 3), motions (n, 3, 4, 4), one shared ``t_range``."""

    t_range: tuple
    param: np.ndarray
    param_name: str

    @property
    def n(self) -> int:
        return len(self.lo_a)

    def take(self, idx) -> "QueryBatch":
        """The queries at ``idx`` (an index array or a mask)."""
        return replace(self, lo_a=self.lo_a[idx], hi_a=self.hi_a[idx], coeffs_a=self.coeffs_a[idx],
                       lo_b=self.lo_b[idx], hi_b=self.hi_b[idx], coeffs_b=self.coeffs_b[idx], param=self.param[idx])


# ---------------------------------------------------------------- vectorised motions
def unit(rng, n) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def random_rotations(rng, n) -> np.ndarray:
    return axis_angle_matrix(unit(rng, n), rng.uniform(0.0, np.pi, n))


# ``_through`` and ``screw`` fit the same motions as motion.through_coeffs and
# motion.screw_coeffs, rounded otherwise (an inverse Vandermonde matrix; the translation
# fitted too): the queries of a random seed are fixed to the bit (shards resume from reports, committed
# case files name their shard and index), so they stay until the report format changes.
def _through(times, poses) -> np.ndarray:
    """(n, 3, 4, 4) quadratic through three (n, 4, 4) poses at three shared times."""
    V = np.vander(np.asarray(times, float), 3, increasing=True)
    c = np.einsum("ki,inrs->nkrs", np.linalg.inv(V), np.asarray(poses))
    c[:, 0, 3] = (0.0, 0.0, 0.0, 1.0)
    c[:, 1:, 3] = 0.0
    return c


def screw(R0, p0, v, w, t_range=(0.0, 1.0)) -> np.ndarray:
    """Quadratic fits of rigid motions: origin p0 + v (t - t0), orientation turned at the
    constant angular velocity ``w`` (rad per unit t, world axes); as ``QuadraticMotion.screw``."""
    t0, t1 = t_range
    times = (t0, 0.5 * (t0 + t1), t1)
    speed = np.linalg.norm(w, axis=1)
    axis = np.where(speed[:, None] > 0, w / np.where(speed > 0, speed, 1.0)[:, None], (1.0, 0.0, 0.0))
    poses = []
    for t in times:
        T = np.zeros((len(p0), 4, 4))
        T[:, :3, :3] = axis_angle_matrix(axis, speed * (t - t0)) @ R0
        T[:, :3, 3] = p0 + v * (t - t0)
        T[:, 3, 3] = 1.0
        poses.append(T)
    return _through(times, poses)


def ballistic(R, p, v, a=None) -> np.ndarray:
    """(n, 3, 4, 4): fixed orientation R, position p + v t + a t^2 / 2."""
    c = np.zeros((len(p), 3, 4, 4))
    c[:, 0, :3, :3] = R
    c[:, 0, :3, 3] = p
    c[:, 0, 3, 3] = 1.0
    c[:, 1, :3, 3] = v
    if a is not None:
        c[:, 2, :3, 3] = 0.5 * a
    return c


def static(R, p) -> np.ndarray:
    return ballistic(R, p, np.zeros_like(p))


def moved(T, coeffs) -> np.ndarray:
    """The motions seen after the fixed affine maps T (n, 4, 4): T @ M(t)."""
    return np.einsum("nij,nkjl->nkil", T, coeffs)


def rigid(R, p) -> np.ndarray:
    T = np.zeros((len(p), 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = R, p, 1.0
    return T


def _batch(lo_a, hi_a, ca, lo_b, hi_b, cb, param, name, t_range=(0.0, 1.0)) -> QueryBatch:
    return QueryBatch(lo_a, hi_a, ca, lo_b, hi_b, cb, (float(t_range[0]), float(t_range[1])), param, name)


def _thrown(rng, n, L, t_range=(0.0, 1.0), spin=np.pi / 2, reach=(2.5, 5.0), aim=1.5):
    """B's motion: from ``reach`` box sizes away towards a point within ``aim`` sizes of
    A's centre, spinning up to ``spin`` over the range. L (n,) is the box size."""
    span = t_range[1] - t_range[0]
    start = unit(rng, n) * (L * rng.uniform(*reach, n))[:, None]
    target = L[:, None] * rng.uniform(-aim, aim, (n, 3))
    w = unit(rng, n) * (rng.uniform(0, spin, n) / span)[:, None]
    return screw(random_rotations(rng, n), start, (target - start) / span, w, t_range)


def _halves(rng, n, L):
    return L[:, None] * rng.uniform(0.2, 1.0, (n, 3))


# ---------------------------------------------------------------- families
def fam_scale(rng, n):
    L = 10.0 ** rng.uniform(-4, 4, n)
    ha, hb = _halves(rng, n, L), _halves(rng, n, L)
    spin_a = (rng.random(n) < 0.5)[:, None] * unit(rng, n) * rng.uniform(0, np.pi / 2, n)[:, None]
    ca = screw(random_rotations(rng, n), np.zeros((n, 3)), np.zeros((n, 3)), spin_a)
    return _batch(-ha, ha, ca, -hb, hb, _thrown(rng, n, L), L, "box size")


def fam_aspect(rng, n):
    ratio = 10.0 ** rng.uniform(1, 4, n)
    a = 1.0 / ratio

    def plate_or_needle():
        h = np.ones((n, 3))
        k = rng.integers(0, 3, n)
        h[np.arange(n), k] = a  # a plate: one thin axis
        needle = rng.random(n) < 0.5
        h[needle, (k[needle] + 1) % 3] = a[needle]  # a needle: two
        return h

    ha, hb = plate_or_needle(), plate_or_needle()
    ca = static(random_rotations(rng, n), np.zeros((n, 3)))
    return _batch(-ha, ha, ca, -hb, hb, _thrown(rng, n, np.ones(n), reach=(2.0, 3.0), aim=0.5), ratio,
                  "aspect ratio")


def fam_speed(rng, n):
    v = 10.0 ** rng.uniform(1, 4, n)
    h = rng.uniform(0.3, 1.0, (n, 3))
    start = unit(rng, n) * (v * rng.uniform(0.3, 0.7, n))[:, None]
    aim = rng.uniform(-1.0, 1.0, (n, 3))
    d = aim - start
    vel = d / np.linalg.norm(d, axis=1, keepdims=True) * v[:, None]
    cb = screw(random_rotations(rng, n), start, vel, rng.normal(size=(n, 3)))
    ca = static(random_rotations(rng, n), np.zeros((n, 3)))
    return _batch(-h, h, ca, -h[:, ::-1], h[:, ::-1], cb, v, "box lengths per range")


def fam_rotation(rng, n):
    angle = rng.uniform(0, np.pi, n)
    ha, hb = rng.uniform(0.2, 1.0, (n, 3)), rng.uniform(0.2, 1.0, (n, 3))
    ca = screw(random_rotations(rng, n), np.zeros((n, 3)), 0.3 * rng.normal(size=(n, 3)),
               unit(rng, n) * angle[:, None])
    start = unit(rng, n) * 2.5
    cb = screw(random_rotations(rng, n), start, -start + rng.uniform(-0.5, 0.5, (n, 3)), unit(rng, n) * angle[:, None])
    return _batch(-ha, ha, ca, -hb, hb, cb, angle, "angle over the range (rad)")


def fam_far(rng, n):
    D = 10.0 ** rng.uniform(2, 6, n)
    ha, hb = rng.uniform(0.2, 1.0, (n, 3)), rng.uniform(0.2, 1.0, (n, 3))
    spin_a = (rng.random(n) < 0.5)[:, None] * unit(rng, n) * rng.uniform(0, np.pi / 2, n)[:, None]
    ca = screw(random_rotations(rng, n), np.zeros((n, 3)), 0.5 * rng.normal(size=(n, 3)), spin_a)
    cb = _thrown(rng, n, np.ones(n))
    T = rigid(random_rotations(rng, n), unit(rng, n) * D[:, None])
    return _batch(-ha, ha, moved(T, ca), -hb, hb, moved(T, cb), D, "distance from the origin (box sizes)")


def fam_grazing(rng, n):
    """B translates on a parabola, y(t) = y_apex + k (t - tm)^2 in A's frame, whose apex brings
    B's lowest vertex (for a quarter of the pairs: its bottom face, B aligned with A) to A's
    top face plus ``gap``; B is above that face at every other time. Half the scenes are
    then moved and turned as a whole (the gap then carries the rounding of the move)."""
    gap = rng.choice([0.0, 0.0, 1e-9, -1e-9], n)
    ha, hb = rng.uniform(0.3, 1.0, (n, 3)), rng.uniform(0.3, 1.0, (n, 3))
    aligned = rng.random(n) < 0.25
    Rb = np.where(aligned[:, None, None], np.eye(3), random_rotations(rng, n))
    corners = np.einsum("nij,nvj->nvi", Rb, SIGNS[None] * hb[:, None, :])
    lowest = corners[np.arange(n), np.argmin(corners[:, :, 1], axis=1)]  # relative to B's centre
    k = rng.uniform(0.5, 5.0, n)
    tm = rng.uniform(0.2, 0.8, n)
    foot = rng.uniform(-0.8, 0.8, (n, 2)) * ha[:, [0, 2]]  # where that vertex passes over A's top face
    apex = np.stack([foot[:, 0] - lowest[:, 0], ha[:, 1] + gap - lowest[:, 1], foot[:, 1] - lowest[:, 2]], axis=1)
    drift = rng.uniform(-0.5, 0.5, (n, 2)) * (rng.random(n) < 0.5)[:, None]  # sideways, or straight down
    v = np.stack([drift[:, 0], -2 * k * tm, drift[:, 1]], axis=1)
    p = np.stack([apex[:, 0] - drift[:, 0] * tm, apex[:, 1] + k * tm * tm, apex[:, 2] - drift[:, 1] * tm], axis=1)
    acc = np.zeros((n, 3))
    acc[:, 1] = 2 * k
    T = rigid(random_rotations(rng, n), unit(rng, n) * rng.uniform(0, 10, n)[:, None])
    T[rng.random(n) < 0.5] = np.eye(4)
    ca = moved(T, static(np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3))))
    return _batch(-ha, ha, ca, -hb, hb, moved(T, ballistic(Rb, p, v, acc)), gap, "gap at the apex (box sizes)")


def fam_near_parallel(rng, n):
    """Half the pairs: vertical edges of both boxes (each turned pi/4 about z) meet edge on
    edge, B's tilted by ``tilt`` about a horizontal axis; the other half: faces meet face on
    face, B's tilted by ``tilt`` about a random axis. A fifth of the tilts are exactly 0;
    half the scenes are moved and turned as a whole."""
    tilt = np.where(rng.random(n) < 0.2, 0.0, 10.0 ** rng.uniform(-16, -2, n))
    edges = rng.random(n) < 0.5
    h = rng.uniform(0.4, 0.6, (n, 3))
    Rz = axis_angle_matrix(np.tile([0.0, 0.0, 1.0], (n, 1)), np.full(n, np.pi / 4))
    horizontal = unit(rng, n) * (1.0, 1.0, 0.0)
    horizontal /= np.linalg.norm(horizontal, axis=1, keepdims=True)
    axis = np.where(edges[:, None], horizontal, unit(rng, n))
    Ra = np.where(edges[:, None, None], Rz, np.eye(3))
    Rb = axis_angle_matrix(axis, tilt) @ Ra
    lateral = np.where(edges, rng.uniform(-1e-3, 1e-3, n), rng.uniform(-0.5, 0.5, n))
    start = np.stack([np.full(n, 3.0), lateral, rng.uniform(-0.5, 0.5, n)], axis=1)
    cb = ballistic(Rb, start, np.tile([-4.0, 0.0, 0.0], (n, 1)))
    T = rigid(random_rotations(rng, n), unit(rng, n) * rng.uniform(0, 10, n)[:, None])
    T[rng.random(n) < 0.5] = np.eye(4)
    return _batch(-h, h, moved(T, static(Ra, np.zeros((n, 3)))), -h, h, moved(T, cb), tilt, "tilt (rad)")


def fam_range_ends(rng, n):
    """Face-on-face contacts ``d`` ranges after the start or before the end of a range
    drawn per batch (t0 in [-3, 3], length 0.1 to 10); B flies in along -x at 3 box
    lengths per range; half the scenes are moved and turned as a whole."""
    t0 = rng.uniform(-3, 3)
    span = 10.0 ** rng.uniform(-1, 1)
    t_range = (t0, t0 + span)
    d = 10.0 ** rng.uniform(-15, -6, n)
    tc = np.where(rng.random(n) < 0.5, t0 + d * span, t_range[1] - d * span)
    ha, hb = rng.uniform(0.3, 1.0, (n, 3)), rng.uniform(0.3, 1.0, (n, 3))
    speed = 3.0 / span
    p = np.stack([ha[:, 0] + hb[:, 0] + speed * tc, *(rng.uniform(-0.8, 0.8, (2, n)) * ha[:, 1:].T)], axis=1)
    v = np.tile([-speed, 0.0, 0.0], (n, 1))
    T = rigid(random_rotations(rng, n), unit(rng, n) * rng.uniform(0, 10, n)[:, None])
    T[rng.random(n) < 0.5] = np.eye(4)
    eye = np.tile(np.eye(3), (n, 1, 1))
    return _batch(-ha, ha, moved(T, static(eye, np.zeros((n, 3)))), -hb, hb, moved(T, ballistic(eye, p, v)), d,
                  "contact's distance from a range end (ranges)", t_range)


def _random_range(rng):
    if rng.random() < 0.3:
        return (0.0, 1.0)
    t0 = rng.uniform(-5, 5)
    return (t0, t0 + 10.0 ** rng.uniform(-1, 1))


def _boxes(rng, n, L, thin=0.0, off_centre=0.0):
    """Corners of n boxes of size L: a fraction ``thin`` are plates (one axis x 0.01), a
    fraction ``off_centre`` sit off their frame's origin."""
    h = _halves(rng, n, L)
    plate = rng.random(n) < thin
    h[plate, rng.integers(0, 3, plate.sum())] *= 0.01
    c = L[:, None] * rng.uniform(-2.0, 2.0, (n, 3)) * (rng.random(n) < off_centre)[:, None]
    return c - h, c + h


def fam_both_moving(rng, n):
    t_range = _random_range(rng)
    span = t_range[1] - t_range[0]
    L = 10.0 ** rng.uniform(-3, 3, n)
    lo_a, hi_a = _boxes(rng, n, L, off_centre=0.3)
    lo_b, hi_b = _boxes(rng, n, L, off_centre=0.3)
    ca = screw(random_rotations(rng, n), np.zeros((n, 3)), L[:, None] * rng.normal(size=(n, 3)) / span,
               unit(rng, n) * (rng.uniform(0, np.pi / 2, n) / span)[:, None], t_range)
    return _batch(lo_a, hi_a, ca, lo_b, hi_b, _thrown(rng, n, L, t_range), L, "box size", t_range)


def fam_one_static(rng, n):
    t_range = _random_range(rng)
    L = 10.0 ** rng.uniform(-3, 3, n)
    lo_a, hi_a = _boxes(rng, n, L, thin=0.3, off_centre=0.3)
    lo_b, hi_b = _boxes(rng, n, L, thin=0.3)
    ca = static(random_rotations(rng, n), np.zeros((n, 3)))
    return _batch(lo_a, hi_a, ca, lo_b, hi_b, _thrown(rng, n, L, t_range), L, "box size", t_range)


FAMILIES = {
    "scale": fam_scale,
    "aspect": fam_aspect,
    "speed": fam_speed,
    "rotation": fam_rotation,
    "far": fam_far,
    "grazing": fam_grazing,
    "near_parallel": fam_near_parallel,
    "range_ends": fam_range_ends,
    "both_moving": fam_both_moving,
    "one_static": fam_one_static,
}


def make_batch(name: str, rng, n: int) -> QueryBatch:
    return FAMILIES[name](rng, n)
