"""The boxes a body's frames carry, as pybullet reports them (or can be made to show).

Frames are centre-of-mass frames: ``getCollisionShapeData`` gives a box's full
extents and its frame relative to the link's centre-of-mass frame, and
``getBasePositionAndOrientation`` / ``getLinkState(...)[0:2]`` give those frames. A plane
on a fixed base is a half-space, and is given as a box too (``plane_box``).

Maximal-coordinate bodies (``useMaximalCoordinates=True``) do not answer
``getCollisionShapeData`` (pybullet prints "getCollisionShapeData failed" at C level
and raises). Two ways round it, neither of which moves the body (a pose reset is not
bit-exact: it would perturb a resting pile):

1. ``Shadow``: the call that made the body (recorded by ``_hooks``, with the calls that
   made its collision shapes) is made again in a private DIRECT client as a multibody,
   which does answer; pybullet builds both kinds from the same description, with the
   same centre-of-mass frames. One such client serves the whole process (``SHADOW``),
   whatever number of worlds and BoxCCDs come and go.
2. For a body made before this package was imported, closest-point probes:
``getClosestPoints`` between the body and a tiny sphere (a collision shape, not a
body) placed far away in 64 directions gives the point of the body's surface nearest
to each probe. Bullet's box is the sharp box rounded by its collision margin m, so a
probe in a corner's region of directions meets the rounded corner at v + m n (v the
inner corner, n the unit direction from it to the probe): two probes meet the same
corner exactly when their points differ by m times the difference of their
directions. Grouping by that gives the corners; a least-squares fit gives the 8 inner
corners and m at once, and the sharp box is the inner one grown by m. The result is
checked: 8 corners forming a box (orthogonal edges to 1e-9) and every probe point on
the rounded box to 1e-9 of its size. Anything else is not a box (a single group is a
sphere, which is left to pybullet without a warning).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from itertools import combinations, product

import numpy as np
import pybullet

from ..motion import pose_matrix
from . import _hooks
from ._hooks import raw

__all__ = ["multibody_boxes", "plane_box", "probe_boxes", "fit_rounded_box", "Shadow", "SHADOW", "NOT_A_BOX", "SPHERE",
           "THIN"]

NOT_A_BOX, SPHERE = "not a box", "sphere"
THIN = "a box thinner than twice its collision margin"
_N_PROBES = 64
_FAR = 64.0  # probe distance, in sizes of the body's bounding box: far enough that corners are met
_REL = 1e-9  # relative tolerance of the fit's checks


# A plane is a half-space to Bullet: one on a fixed base is swept as a cube of this half
# extent whose top face is the plane, so a box moving within 100 km of the plane's origin
# meets it where Bullet's plane is met (the solver counts boxes closer than 1e-12 of their
# sizes as touching: 2e-7 m here, below the 1e-5 m overlap a contact is acted on at).
PLANE_HALF = 1e5


def plane_box(normal, X):
    """(half extents (3,), X_CS (4, 4)) of the half-space under the plane through the
    origin of frame X (4, 4, in the link's centre-of-mass frame) with ``normal`` (in X)."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(a, n)
    x /= np.linalg.norm(x)
    X_PB = np.eye(4)
    X_PB[:3, :3] = np.column_stack([x, np.cross(n, x), n])
    X_PB[:3, 3] = -PLANE_HALF * n
    return np.full(3, PLANE_HALF), X @ X_PB


def _normal(v) -> bool:
    """Whether v can be a plane's normal (a plane of normal 0 meets nothing in Bullet)."""
    n = float(np.linalg.norm(v))
    return math.isfinite(n) and n > 0.0


def multibody_boxes(cid, body, link, planes=False):
    """(boxes, others) of a multibody link: boxes [(half extents (3,), X_CS (4, 4))] in the
    link's centre-of-mass frame (with ``planes``, its planes too, as ``plane_box``es), and
    its other shapes [(geometry type, ``thickness``)]."""
    boxes, others = [], []
    for d in raw.getCollisionShapeData(body, link, physicsClientId=cid):
        if d[2] == pybullet.GEOM_BOX:
            boxes.append((0.5 * np.asarray(d[3], float), pose_matrix(d[5], d[6])))
        elif d[2] == pybullet.GEOM_PLANE and planes and _normal(d[3]):  # its dimensions are the plane's normal
            boxes.append(plane_box(d[3], pose_matrix(d[5], d[6])))
        else:
            others.append((d[2], thickness(d[2], d[3])))
    return boxes, others


def thickness(geometry, dimensions):
    """The smallest extent (m) of a shape of getCollisionShapeData's geometry type and
    dimensions: a sphere's diameter, a capsule's, the lesser of a cylinder's diameter and
    length; None where pybullet does not report its size (a mesh: its scale only)."""
    if geometry == pybullet.GEOM_SPHERE:
        return 2.0 * dimensions[0]
    if geometry == pybullet.GEOM_CAPSULE:  # (length, radius)
        return 2.0 * dimensions[1]
    if geometry == pybullet.GEOM_CYLINDER:
        return min(2.0 * dimensions[1], dimensions[0])
    return None


@dataclass
class Remade:
    """A maximal-coordinate body as it was made: {link: ``multibody_boxes``}, and its base's
    mass and restitution then."""

    boxes: dict
    mass: float
    restitution: float


class Shadow:
    """A private DIRECT client in which maximal-coordinate bodies are made again as
    multibodies, to read their boxes with ``getCollisionShapeData``. The collision shapes it
    makes again are kept for the next body made of them, up to ``KEPT_SHAPES``: beyond, the
    client is reset and they are made again as needed."""

    KEPT_SHAPES = 1024

    def __init__(self):
        self.cid = -1
        self._journal = None  # the private client's: closed once the user disconnects it by its id
        self._shapes = {}  # (user's journal's serials, private journal's reset, user's shape index) -> shadow index
        self._lock = threading.Lock()

    def remake(self, journal, body):
        """A maximal-coordinate body the journal saw being made, as it was made (``Remade``),
        or None. (One read at a time: worlds stepped in several threads share the client.)"""
        with self._lock:
            return self._remake(journal, body)

    def _remake(self, journal, body):
        recipe = journal.maximal.get(body)
        if recipe is None:
            return None
        if self._journal is None or self._journal.closed:
            # (a client the user disconnected may be theirs again under the same id)
            self.cid = raw.connect(pybullet.DIRECT)
            self._journal, self._shapes = _hooks.journal(self.cid), {}
        elif len(self._shapes) > self.KEPT_SHAPES:
            raw.resetSimulation(physicsClientId=self.cid)
            self._shapes = {}
        if journal.search_paths:  # pybullet keeps one additional path: the latest
            raw.setAdditionalSearchPath(journal.search_paths[-1], physicsClientId=self.cid)
        name, named, index = recipe
        named = dict(named, useMaximalCoordinates=False)
        try:
            if name == "createMultiBody":
                named = self._shapes_mapped(journal, named)
                named.pop("batchPositions", None)
                ids = [raw.createMultiBody(**named, physicsClientId=self.cid)]
                index = 0
            else:
                made = getattr(raw, name)(**named, physicsClientId=self.cid)
                ids = list(made) if isinstance(made, (tuple, list)) else [made]
        except (pybullet.error, KeyError, TypeError):
            return None
        try:
            shadow = ids[index]
            links = range(-1, raw.getNumJoints(shadow, physicsClientId=self.cid))
            mass, restitution = (raw.getDynamicsInfo(shadow, -1, physicsClientId=self.cid)[i] for i in (0, 5))
            boxes = {lk: multibody_boxes(self.cid, shadow, lk, planes=mass == 0.0 and lk == -1) for lk in links}
            return Remade(boxes, mass, restitution)
        finally:
            for b in ids:
                raw.removeBody(b, physicsClientId=self.cid)

    def _shapes_mapped(self, journal, named):
        named = dict(named, baseVisualShapeIndex=-1)
        named["baseCollisionShapeIndex"] = self._shape(journal, named.get("baseCollisionShapeIndex", -1))
        links = named.get("linkCollisionShapeIndices")
        if links:
            named["linkCollisionShapeIndices"] = [self._shape(journal, i) for i in links]
            named["linkVisualShapeIndices"] = [-1] * len(links)
        return named

    def _shape(self, journal, index):
        if index is None or index < 0:
            return -1
        key = (journal.made, journal.reset, self._journal.reset, index)
        if key not in self._shapes:
            name, named = journal.shapes[index]  # KeyError: made unseen
            self._shapes[key] = getattr(raw, name)(**named, physicsClientId=self.cid)
        return self._shapes[key]


def _directions(n):
    """n unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / n)
    azimuth = np.pi * (1.0 + 5.0**0.5) * i
    return np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1)


def probe_boxes(cid, body, link, X_WC, probe_shape):
    """The box of a maximal-coordinate frame: ([(half, X_CS)], None) or ([], reason).

    ``X_WC``: the frame's centre-of-mass pose (4, 4); ``probe_shape``: a collision shape
    index of a small sphere in the same client."""
    lo, hi = (np.asarray(v, float) for v in raw.getAABB(body, link, physicsClientId=cid))
    size = float(np.linalg.norm(hi - lo))
    if not (np.isfinite(size) and size > 0.0):
        return [], NOT_A_BOX
    centre, far = 0.5 * (lo + hi), _FAR * size
    points, directions = [], []
    for u in _directions(_N_PROBES):
        q = centre + far * u
        found = raw.getClosestPoints(bodyA=body, bodyB=-1, distance=2.0 * far, linkIndexA=link,
                                     collisionShapeB=probe_shape, collisionShapePositionB=q.tolist(),
                                     physicsClientId=cid)
        if len(found) != 1:  # several shapes on the frame (a compound), or none
            return [], NOT_A_BOX
        x = np.asarray(found[0][5], float)
        points.append(x)
        directions.append((q - x) / np.linalg.norm(q - x))
    fit = fit_rounded_box(np.array(points), np.array(directions), size)
    if isinstance(fit, str):
        return [], fit
    centre_W, axes_W, half = fit
    if np.isnan(half).any():
        return [], THIN
    X_WS = np.eye(4)
    X_WS[:3, :3], X_WS[:3, 3] = axes_W, centre_W
    return [(half, np.linalg.solve(X_WC, X_WS))], None


def fit_rounded_box(points, directions, size):
    """(centre, axes (3, 3) columns, sharp half extents) of the rounded box whose surface
    points ``points`` (n, 3) are nearest to far probes in ``directions`` (n, 3, unit,
    from the point towards its probe); or NOT_A_BOX / SPHERE. A half extent the probes
    cannot tell is NaN.

    Bullet keeps a box as its inner box (the half extents less the margin m) rounded by
    m; a box thinner than 2 m has a negative inner extent (its corners then swap sides),
    and one exactly 2 m thin a zero one (two corners become one)."""
    n, tol = len(points), _REL * size
    dx = points[:, None, :] - points[None, :, :]
    dn = directions[:, None, :] - directions[None, :, :]
    nn = np.einsum("ijk,ijk->ij", dn, dn)
    m_pair = np.einsum("ijk,ijk->ij", dx, dn) / np.where(nn > 0, nn, 1.0)
    upper = np.triu(np.ones((n, n), bool), 1)
    fits = upper & (np.linalg.norm(dx - m_pair[..., None] * dn, axis=2) <= tol)
    if not fits.any():
        return NOT_A_BOX
    margin = float(np.median(m_pair[fits]))  # the rounding radius, shared by every corner
    same = np.linalg.norm(dx - margin * dn, axis=2) <= tol
    labels = _components(same)
    counts = np.bincount(labels)
    corners_of = np.flatnonzero(counts >= 2)  # a probe alone in its group met an edge or a face
    if margin < -tol or len(corners_of) not in (1, 2, 4, 8) or counts[corners_of].sum() < 0.75 * n:
        return NOT_A_BOX
    if len(corners_of) == 1:
        return SPHERE if margin > tol else NOT_A_BOX
    # Least squares over the corner groups: point = corner[group] + m * direction.
    on_corner = np.isin(labels, corners_of)
    group = np.searchsorted(corners_of, labels[on_corner])
    k, pts, dirs = len(corners_of), points[on_corner], directions[on_corner]
    A = np.zeros((3 * len(pts), 3 * k + 1))
    A[np.arange(3 * len(pts)), 3 * np.repeat(group, 3) + np.tile(np.arange(3), len(pts))] = 1.0
    A[:, -1] = dirs.reshape(-1)
    sol = np.linalg.lstsq(A, pts.reshape(-1), rcond=None)[0]
    corners, margin = sol[:-1].reshape(k, 3), max(float(sol[-1]), 0.0)
    if np.abs(A @ sol - pts.reshape(-1)).max() > tol:
        return NOT_A_BOX
    centre = corners.mean(axis=0)
    g = _box_generators(corners - centre, tol)
    if g is None:
        return NOT_A_BOX
    lengths = np.linalg.norm(g, axis=0)
    axes = g / lengths
    if g.shape[1] == 2:  # a box exactly 2 m thin: its third inner extent is zero
        axes, lengths = np.column_stack([axes, np.cross(axes[:, 0], axes[:, 1])]), np.append(lengths, 0.0)
    # A probe meets the corner on its own side of each axis: that extent is the inner
    # one grown by m. Where the inner extent is negative (a box thinner than 2 m) or
    # zero, Bullet's sphere-box query meets either side: that extent is left unknown.
    offset = (pts - dirs * margin - centre) @ axes
    toward = dirs @ axes
    half = np.full(3, np.nan)
    for j in range(g.shape[1]):
        seen = np.abs(toward[:, j]) > 1e-6
        if np.all(offset[seen, j] * toward[seen, j] > 0):
            half[j] = margin + lengths[j]
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    return centre, axes, half


def _components(adjacent):
    """Connected components of a symmetric boolean adjacency matrix: a label per node."""
    n = len(adjacent)
    labels = -np.ones(n, int)
    for i in range(n):
        if labels[i] >= 0:
            continue
        frontier, labels[i] = [i], i
        while frontier:
            nxt = np.flatnonzero(adjacent[frontier].any(axis=0) & (labels < 0))
            labels[nxt] = i
            frontier = nxt.tolist()
    return np.unique(labels, return_inverse=True)[1]


def _box_generators(offsets, tol):
    """The d = log2(k) half edges g (3, d columns) of a box whose k corner offsets from its
    centre are the sign combinations of +-g (d = 3; d = 2 when one inner extent is zero),
    or None if they are not such a box."""
    k = len(offsets)
    d = {2: 1, 4: 2, 8: 3}[k]
    if d < 2:
        return None
    # The corners joined to corner 0 by an edge differ from it by one 2 g each: the
    # d of the k - 1 differences that are orthogonal and generate every corner.
    diffs = (offsets[0] - offsets[1:]) / 2.0
    signs = np.array(list(product((-1.0, 1.0), repeat=d)))
    for pick in combinations(range(k - 1), d):
        g = diffs[list(pick)].T
        lengths = np.linalg.norm(g, axis=0)
        if lengths.min() <= tol or np.abs(g.T @ g / np.outer(lengths, lengths) - np.eye(d)).max() > _REL:
            continue
        expected = signs @ g.T
        if np.min(np.linalg.norm(offsets[:, None, :] - expected[None], axis=2), axis=1).max() <= tol:
            return g
    return None


SHADOW = Shadow()  # the process's (its client is connected when a body first needs it)
