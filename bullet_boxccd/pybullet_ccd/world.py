"""The world as the plugin tracks it: which frames carry boxes, of what kind, and
what changed since the last step.

A frame is a (body, link) with at least one box, in its centre-of-mass frame. Its kind:

* ``STATIC``: a fixed base (a mass-0 body); Bullet does not move it by itself, but the
  user may (a kinematic body: see ``kinematic``),
* ``FREE``: the base of a free single rigid body (the plugin can rewind it),
* ``LINK``: a link of an articulated body, or its free base (swept, not rewound).

``World.sync`` brings the tables up to date at the start of each step from the journal
(``_hooks``): only bodies that were created, removed, re-massed or re-scaled since the
last step are read again; filters are re-derived when they changed; a world that
``resetSimulation`` rebuilt is read whole. A change of the body count that the journal
did not see (a call through a reference taken before this package was imported) also
triggers a full read.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import pybullet

from ..motion import quat_to_matrix
from ._hooks import journal, new_serial, raw
from .events import BoxCCDWarning
from .filters import Filters, default_group_mask
from .shapes import SPHERE, Shadow, multibody_boxes, probe_boxes

__all__ = ["STATIC", "FREE", "LINK", "World", "Tables"]

STATIC, FREE, LINK = 0, 1, 2
_GEOMETRY = {pybullet.GEOM_SPHERE: "sphere", pybullet.GEOM_CAPSULE: "capsule", pybullet.GEOM_CYLINDER: "cylinder",
             pybullet.GEOM_MESH: "mesh", pybullet.GEOM_PLANE: "plane"}
_MAXIMAL, _SOFT = 1, 3  # getDynamicsInfo(...)[10]: the body's type


@dataclass
class _Frame:
    link: int
    kind: int
    boxes: list  # [(half (3,), X_CS (4, 4))]
    fixed: bool  # pybullet's static collision group (a fixed base)
    name: str


@dataclass
class _Body:
    frames: list = field(default_factory=list)
    left: list = field(default_factory=list)  # (link, what): shapes left to pybullet
    unreadable: list = field(default_factory=list)  # (link, why): boxes that could not be read
    maximal: bool = False


@dataclass
class Tables:
    """Frames (F) and boxes (B) as parallel arrays, in body order."""

    keys: list  # (body, link) per frame
    index: dict  # (body, link) -> frame
    body: np.ndarray  # (F,) int64
    kind: np.ndarray  # (F,) int8
    self_collides: np.ndarray  # (F,) uint8: 1 if its body's links collide with each other
    box_frame: np.ndarray  # (B,) int64
    half: np.ndarray  # (B, 3)
    X_CS: np.ndarray  # (B, 4, 4): box in its frame
    radius: np.ndarray  # (B,): farthest box point from the frame's origin
    frame_boxes: list  # frame -> its boxes
    frames_of: dict  # body -> its frames
    filters: Filters

    @property
    def moving(self) -> list:
        """Frames whose velocity is read at every step (every kind but STATIC)."""
        return np.flatnonzero(self.kind != STATIC).tolist()


class World:
    """Discovery and tracking of one physics client's boxes."""

    def __init__(self, cid, self_collision_bodies, warn):
        self.cid = cid
        self.journal = journal(cid)
        self.self_collision_bodies = set(self_collision_bodies)
        self.registered = {}  # (body, link) -> (serial, [(half, X_CS)]) declared with BoxCCD.register_box
        self._warn = warn
        self._bodies = {}  # body -> _Body
        self._shadow = Shadow()
        self._probe_shape = -1
        self._seen = 0  # journal serial consumed
        self.count = -1  # body count at the last sync
        self.tables = None

    # ---------------------------------------------------------------- changes
    def sync(self) -> bool:
        """Read what changed since the last call; True if the tables were rebuilt."""
        j = self.journal
        count = raw.getNumBodies(physicsClientId=self.cid)
        if self.tables is not None and count == self.count and j.reset <= self._seen:
            if j.last_body <= self._seen and j.filters <= self._seen:
                return False
            dirty = [b for b, s in j.bodies.items() if s > self._seen]
        else:
            dirty = None  # read everything
        self._seen = max(j.reset, j.last_body, j.filters, self._seen)
        self.count = count
        ids = [raw.getBodyUniqueId(i, physicsClientId=self.cid) for i in range(count)]
        # A registration outlives no change of its body (a new body may reuse the id).
        self.registered = {k: v for k, v in self.registered.items()
                           if v[0] > max(j.reset, j.bodies.get(k[0], 0)) and k[0] in ids}
        if dirty is None:
            self._bodies = {}
        else:
            for b in dirty:
                self._bodies.pop(b, None)
        for b in ids:
            if b not in self._bodies:
                self._bodies[b] = self._read_body(b)
        for b in set(self._bodies) - set(ids):
            del self._bodies[b]
        self._build(ids)
        self._warn_unseen(ids)
        return True

    def _warn_unseen(self, ids):
        unseen = [b for b in ids if b not in self.journal.created]
        if unseen:
            self._warn(("unseen",) + tuple(unseen),
                       f"bodies {unseen} were created before bullet_boxccd was imported (or through a pybullet "
                       "function it does not see): collision filters set on them with pybullet's own calls, "
                       "their removal and re-creation under the same id, and kinematic moves cannot be known. "
                       "Import bullet_boxccd before building the world.")
        for b, why in self.journal.filters_unknown.items():
            if b in self._bodies:
                self._warn(("groups", b), f"body {b}: collision groups are not mirrored ({why}); BoxCCD may sweep "
                                          "pairs that pybullet does not collide")

    # --------------------------------------------------------------- reading
    def _read_body(self, b) -> _Body:
        cid = self.cid
        info = raw.getDynamicsInfo(b, -1, physicsClientId=cid)
        rec = _Body(maximal=info[10] == _MAXIMAL)
        if info[10] == _SOFT:
            rec.left.append((-1, "soft body"))
            return rec
        n_joints = raw.getNumJoints(b, physicsClientId=cid)
        fixed_base = info[0] == 0.0
        names = self._link_names(b, n_joints)
        shadow = self._shadow.boxes(cid, self.journal, b) if rec.maximal else None
        for link in range(-1, n_joints):
            boxes, why = self._frame_boxes(b, link, rec, shadow)
            if why is not None:
                rec.unreadable.append((link, why))
            if not boxes:
                continue
            if link == -1:
                kind = STATIC if fixed_base else (FREE if n_joints == 0 else LINK)
            else:
                kind = LINK
            rec.frames.append(_Frame(link, kind, boxes, fixed=link == -1 and fixed_base, name=names[link]))
        return rec

    def _frame_boxes(self, b, link, rec, shadow):
        """(boxes, why unreadable or None) of one frame; shapes left to pybullet are noted."""
        if (b, link) in self.registered:
            return self.registered[(b, link)][1], None
        if not rec.maximal:
            boxes, others = multibody_boxes(self.cid, b, link)
            rec.left.extend((link, _GEOMETRY.get(g, str(g))) for g in others)
            return boxes, None
        if shadow is not None:
            return shadow.get(link, []), None
        if link != -1:
            return [], "a link of a maximal-coordinate body made before bullet_boxccd was imported"
        if self._probe_shape < 0:
            self._probe_shape = raw.createCollisionShape(pybullet.GEOM_SPHERE, radius=1e-3, physicsClientId=self.cid)
        pos, q = raw.getBasePositionAndOrientation(b, physicsClientId=self.cid)
        X_WC = np.eye(4)
        X_WC[:3, :3], X_WC[:3, 3] = quat_to_matrix(q), pos
        boxes, why = probe_boxes(self.cid, b, link, X_WC, self._probe_shape)
        if why == SPHERE:
            rec.left.append((link, "sphere"))
            return [], None
        return boxes, why

    def _link_names(self, b, n_joints):
        names = {-1: raw.getBodyInfo(b, physicsClientId=self.cid)[0].decode("utf-8", "replace")}
        for j in range(n_joints):
            names[j] = raw.getJointInfo(b, j, physicsClientId=self.cid)[12].decode("utf-8", "replace")
        return names

    def self_collision(self) -> dict:
        """{body: URDF_USE_SELF_COLLISION* bits} of the bodies whose links collide with each
        other: as loaded, or named in ``self_collision_bodies`` (pybullet's default rule)."""
        out = dict.fromkeys(self.self_collision_bodies, pybullet.URDF_USE_SELF_COLLISION)
        out.update(self.journal.self_collision)
        return out

    def register(self, b, link, box) -> None:
        """Declare a box on a frame whose boxes cannot be read (checked by the caller)."""
        boxes = self.registered.get((b, link), (0, []))[1]
        self.registered[(b, link)] = (new_serial(), boxes + [box])
        self._bodies.pop(b, None)
        self.tables = None  # read again at the next sync

    def frame_readable(self, b, link) -> bool:
        """Whether pybullet (or the shadow, or probes) can read the frame's shapes."""
        saved, self.registered = self.registered, {k: v for k, v in self.registered.items() if k[0] != b}
        try:
            rec = self._read_body(b)
        finally:
            self.registered = saved
        return any(f.link == link for f in rec.frames) or any(lk == link for lk, _ in rec.left)

    # ---------------------------------------------------------------- tables
    def _build(self, ids):
        keys, kinds, selfc, defaults, fgm = [], [], [], [], {}
        box_frame, half, X_CS = [], [], []
        for b in ids:
            rec = self._bodies[b]
            file_groups = self.journal.file_group_mask.get(b, {})
            for fr in rec.frames:
                f = len(keys)
                keys.append((b, fr.link))
                kinds.append(fr.kind)
                selfc.append(b in self.self_collision_bodies or b in self.journal.self_collision)
                defaults.append(default_group_mask(fr.fixed))
                if fr.name in file_groups:
                    fgm[(b, fr.link)] = file_groups[fr.name]
                for h, X in fr.boxes:
                    box_frame.append(f)
                    half.append(h)
                    X_CS.append(X)
            for link, why in rec.unreadable:
                self._warn(("unreadable", b, link), f"body {b} link {link}: its boxes cannot be read ({why}); "
                                                    "left to pybullet (declare them with BoxCCD.register_box)")
        half = np.array(half, dtype=float).reshape(-1, 3)
        X_CS = np.array(X_CS, dtype=float).reshape(-1, 4, 4)
        frame_boxes = [[] for _ in keys]
        for i, f in enumerate(box_frame):
            frame_boxes[f].append(i)
        frames_of = {}
        for f, (b, _) in enumerate(keys):
            frames_of.setdefault(b, []).append(f)
        self.tables = Tables(
            keys=keys, index={k: i for i, k in enumerate(keys)},
            body=np.array([k[0] for k in keys], dtype=np.int64), kind=np.array(kinds, dtype=np.int8),
            self_collides=np.array(selfc, dtype=np.uint8), box_frame=np.array(box_frame, dtype=np.int64),
            half=half, X_CS=X_CS,
            radius=np.linalg.norm(X_CS[:, :3, 3], axis=1) + np.linalg.norm(half, axis=1),
            frame_boxes=frame_boxes, frames_of=frames_of, filters=Filters(keys, defaults, fgm, self.journal))

    # ---------------------------------------------------------------- summary
    def summary(self) -> str:
        t = self.tables
        lines = [f"BoxCCD: {len(t.half)} boxes on {len(t.keys)} links of {len(set(t.body.tolist()))} bodies "
                 f"({int((t.kind == STATIC).sum())} static links)"]
        for b, rec in self._bodies.items():
            for link, what in rec.left:
                lines.append(f"  left to pybullet: body {b} link {link}: {what}")
            for link, why in rec.unreadable:
                lines.append(f"  body {b} link {link}: boxes unreadable ({why}); use register_box()")
        return "\n".join(lines)


def pose_matrix(position, quaternion) -> np.ndarray:
    X = np.eye(4)
    X[:3, :3] = quat_to_matrix(quaternion)
    X[:3, 3] = position
    return X


def warn_once(seen: set):
    """A warner that emits each key's BoxCCDWarning once."""
    def warn(key, message):
        if key not in seen:
            seen.add(key)
            warnings.warn(message, BoxCCDWarning, stacklevel=4)
    return warn
