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

Where a body's boxes come from (a fixed base's planes too, as half-space boxes:
``shapes.plane_box``): ``getCollisionShapeData`` for a multibody, except a body
``loadMJCF`` made (that call can kill the process on it: its boxes are read from the file,
``mjcf.py``) and a link whose shape the journal knows is a heightfield (pybullet prints an
error when asked: left to pybullet); a shadow multibody or closest-point probes for a
maximal-coordinate body (``shapes.py``). Boxes pybullet has but gives no pose for (the
links of a maximal-coordinate body, a file that no longer matches its body) are named in
one BoxCCDWarning per body and in ``summary()``.
"""

from __future__ import annotations

import os
import re
import sys
import warnings
from dataclasses import dataclass, field
from functools import partial

import numpy as np
import pybullet

from ..motion import pose_matrix
from . import mjcf
from ._hooks import MAX_VELOCITY, damping, journal, new_serial, raw
from .events import BoxCCDWarning
from .filters import Filters, default_group_mask
from .shapes import SHADOW, SPHERE, multibody_boxes, plane_box, probe_boxes

__all__ = ["STATIC", "FREE", "LINK", "World", "Tables"]

STATIC, FREE, LINK = 0, 1, 2
_GEOMETRY = {pybullet.GEOM_SPHERE: "sphere", pybullet.GEOM_CAPSULE: "capsule", pybullet.GEOM_CYLINDER: "cylinder",
             pybullet.GEOM_MESH: "mesh", pybullet.GEOM_PLANE: "plane", pybullet.GEOM_HEIGHTFIELD: "heightfield"}
# Names pybullet's MJCF importer gives: a body's fixed joint, an unnamed body's link.
_MJCF_JOINT, _MJCF_LINK = re.compile(r"jointfix_\d+_-?\d+$"), re.compile(r"link\d+_\d+$")
# getDynamicsInfo(...)[10], the body's type: a rigid body (maximal coordinates), a soft body.
MAXIMAL_TYPE, _SOFT = 1, 3


def restitution(cid, key, info):
    """The restitution of frame ``key`` (body, link) whose getDynamicsInfo is ``info``, or None
    where it is not known. For a maximal-coordinate body pybullet leaves that field as its
    previous answer had it: the body's own is the journal's (the latest given through
    changeDynamics, else the one it was made with), unknown for one made before this package
    was imported and not given one since."""
    return journal(cid).restitution.get(key) if info[10] == MAXIMAL_TYPE else info[5]


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
    thickness: dict = field(default_factory=dict)  # link -> [shapes.thickness] of those shapes
    unreadable: list = field(default_factory=list)  # (link, why): boxes that could not be read
    maximal: bool = False
    moves: str = ""  # how Bullet moves it: "rigid" (a free single body), "chain" (links on joints), "soft"
    unposed: bool = False  # a maximal-coordinate body with links (pybullet gives no state of them)
    # Boxes pybullet has but BoxCCD cannot place: [(link, number of boxes)] and why.
    untracked: list = field(default_factory=list)
    untracked_why: str = ""
    groups: dict = field(default_factory=dict)  # link -> (group, mask) its file sets (MJCF)
    fixed_base: bool = False
    names: dict = field(default_factory=dict)  # link -> its name


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
    free_frames: list  # the free bodies' frames
    # (body, link) -> what: the shapes left to pybullet that a fast box can pass through
    # (all but soft bodies, and planes on a moving frame: a plane's reach is everywhere; one
    # on a fixed base is swept, as a half-space: shapes.plane_box)
    unswept: dict
    # (body, link) -> [the smallest extent of each of those shapes, or None where pybullet
    # does not report it: shapes.thickness]
    unswept_thickness: dict
    damping: np.ndarray  # (F, 2): its body's linear and angular damping, as Bullet damps a free base
    # Bodies with no frame here (others.py): free single ones, articulated ones, fixed bases
    # with no links, and {body: why} those whose state pybullet does not give.
    other_rigid: list
    other_chains: list
    other_fixed: list
    other_stuck: dict

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
        self._probe_shape = -1
        self._seen = 0  # journal serial consumed
        self.count = -1  # body count at the last sync
        self.tables = None

    # ---------------------------------------------------------------- changes
    def sync(self) -> bool:
        """Read what changed since the last call; True if the tables were rebuilt."""
        j = self.journal
        count = raw.getNumBodies(physicsClientId=self.cid)
        if self.tables is not None and j.reset <= self._seen:
            if count == self.count and j.last_body <= self._seen and j.filters <= self._seen:
                return False
            # Bodies made or removed through pybullet's calls are in the journal; one it did
            # not see made is not among those read yet, and one removed is not among the ids.
            dirty = [b for b, s in j.bodies.items() if s > self._seen]
        else:
            dirty = None  # read everything
        if j.reset <= self._seen:
            self._name_dangling(j)
        self._seen = max(j.reset, j.last_body, j.filters, self._seen)
        self.count, ids = self._ids(count)
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

    def _name_dangling(self, j):
        """Name the constraints pybullet left holding a maximal-coordinate body removed since
        the last read: its removeBody frees the body but leaves the constraints of its joints
        and the user's on it in the world, and every later step reads the freed body."""
        gone = [b for b, rec in self._bodies.items() if rec.maximal and j.renewed.get(b, 0) > self._seen]
        if not gone:
            return
        consequence = "every later step reads the freed body, which can crash the process or move other bodies"
        for b in gone:
            if self._bodies[b].unposed:
                self._warn(("dangling", b, j.renewed[b]),
                           f"body {b} (in maximal coordinates, with links) was removed: pybullet's removeBody "
                           f"leaves the constraints of its joints in the world, and {consequence}; make such a "
                           "body with useMaximalCoordinates=False to remove it")
        cid = self.cid
        for i in range(raw.getNumConstraints(physicsClientId=cid)):
            uid = raw.getConstraintUniqueId(i, physicsClientId=cid)
            info = raw.getConstraintInfo(uid, physicsClientId=cid)
            for b in {info[0], info[2]}.intersection(gone):
                self._warn(("dangling", b, j.renewed[b], uid),
                           f"constraint {uid} holds body {b} (in maximal coordinates), which was removed: "
                           f"pybullet's removeBody leaves it in the world, and {consequence}; remove the "
                           "constraint first (p.removeConstraint)")

    def _ids(self, count):
        """(body count, every body's id). After ``createMultiBody(batchPositions=...)`` pybullet's client
        lists only the last body of the batch (getNumBodies, getBodyUniqueId, getBodyInfo),
        though the server simulates them all: when a body the journal saw being made is
        missing from the list but alive, the client's list is brought up to date
        (``syncBodyInfo``, which changes nothing in the simulation) and read again."""
        cid = self.cid
        ids = [raw.getBodyUniqueId(i, physicsClientId=cid) for i in range(count)]
        for b in self.journal.created.difference(ids):
            try:
                raw.getBasePositionAndOrientation(b, physicsClientId=cid)
            except pybullet.error:
                continue
            raw.syncBodyInfo(physicsClientId=cid)
            count = raw.getNumBodies(physicsClientId=cid)
            return count, [raw.getBodyUniqueId(i, physicsClientId=cid) for i in range(count)]
        return count, ids

    def _warn_unseen(self, ids):
        unseen = [b for b in ids if b not in self.journal.created]
        if unseen:
            # (pybullet reports no restitution of a maximal-coordinate body: ``restitution``)
            maximal = [b for b in unseen if raw.getDynamicsInfo(b, -1, physicsClientId=self.cid)[10] == MAXIMAL_TYPE
                       and (b, -1) not in self.journal.restitution]
            self._warn(("unseen",) + tuple(unseen),
                       f"bodies {unseen} were created before bullet_boxccd was imported (or through a pybullet "
                       "function it does not see): collision filters set on them with pybullet's own calls, "
                       "their damping and velocity clamp set by changeDynamics (pybullet's defaults are "
                       "assumed), " + (f"the restitution of {maximal} (in maximal coordinates: none is assumed "
                                      "where BoxCCD parts them), " if maximal else "") +
                       "their removal and re-creation under the same id, and kinematic moves cannot "
                       "be known. Import bullet_boxccd before building the world.")
        for b, why in self.journal.filters_unknown.items():
            if b in self._bodies:
                self._warn(("groups", b), f"body {b}: collision groups are not mirrored ({why}); BoxCCD may sweep "
                                          "pairs that pybullet does not collide")

    # --------------------------------------------------------------- reading
    def _read_body(self, b) -> _Body:
        cid = self.cid
        info = raw.getDynamicsInfo(b, -1, physicsClientId=cid)
        rec = _Body(maximal=info[10] == MAXIMAL_TYPE)
        if info[10] == _SOFT:
            rec.left.append((-1, "soft body"))
            rec.moves = "soft"
            return rec
        n_joints = raw.getNumJoints(b, physicsClientId=cid)
        fixed_base = info[0] == 0.0
        names = rec.names = self._link_names(b, n_joints)
        from_file = self._mjcf_links(b, rec, names, n_joints)
        shadow = None
        if rec.maximal and from_file is None and self.journal.link_geometry.get(b, {}).get(-1) != \
                pybullet.GEOM_HEIGHTFIELD:
            remade = SHADOW.remake(self.journal, b)
            if remade is not None:
                shadow = remade.boxes
                self.journal.restitution.setdefault((b, -1), remade.restitution)  # (unless given one since)
                # pybullet integrates a rigid body only if it was made with a mass, whatever
                # mass it is given since.
                fixed_base = fixed_base or remade.mass == 0.0
                # pybullet poses no link of a maximal-coordinate body (getNumJoints is 0)
                rec.unposed = any(lk >= 0 for lk in shadow)
                left = [(lk, len(bx)) for lk, (bx, _) in sorted(shadow.items()) if lk >= 0 and bx]
                if left:
                    rec.untracked = left
                    rec.untracked_why = ("pybullet reports neither the pose nor the velocity of the links of a "
                                         "maximal-coordinate body (getNumJoints is 0, getLinkState gives nothing); "
                                         "make it with useMaximalCoordinates=False to have them swept")
        rec.fixed_base = fixed_base
        rec.moves = "chain" if n_joints else "" if fixed_base else "rigid"
        for link in range(-1, n_joints):
            boxes, why = self._frame_boxes(b, link, rec, shadow, from_file, static=link == -1 and fixed_base)
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

    def _mjcf_links(self, b, rec, names, n_joints):
        """{link: MjcfLink} of a body loaded by loadMJCF, read from its file ({} if it cannot be
        mapped, the reason in ``rec``); None for other bodies. getCollisionShapeData is never
        called on such a body: it can kill the process (pybullet 3.2.x; see mjcf.py)."""
        load = self.journal.mjcf.get(b)
        if load is None:
            if b not in self.journal.created and self._looks_mjcf(b, names, n_joints):
                rec.untracked_why = ("it was made unseen and looks loaded by loadMJCF (link or joint names of "
                                     "pybullet's MJCF importer), whose bodies getCollisionShapeData can crash on; "
                                     "import bullet_boxccd before loading it")
                rec.untracked = [(None, None)]
                return {}
            return None
        if load.mapping is None:
            load.mapping = mjcf.match(raw, self.cid, load)
        model = load.mapping.get(b)
        if isinstance(model, str) or model is None:
            rec.untracked_why = f"loaded by loadMJCF: {model or 'unknown to the journal'}"
            rec.untracked = self._file_boxes(load)
            return {}
        if rec.maximal:  # loadMJCF(useMultiBody=0): pybullet keeps only the root as the body
            rec.unposed = len(model.links) > 1
            left = [(i - 1, len(lk.boxes)) for i, lk in enumerate(model.links) if i and lk.boxes]
            if left:
                rec.untracked = left
                rec.untracked_why = ("loaded by loadMJCF with useMultiBody=0: pybullet reports neither the pose nor "
                                     "the velocity of its links other than the root; load it with useMultiBody=1 to "
                                     "have them swept")
            links = {-1: model.links[0]}
        else:
            links = {i - 1: lk for i, lk in enumerate(model.links)}
        rec.groups = {lk: m.group_mask for lk, m in links.items() if m.group_mask is not None}
        return links

    @staticmethod
    def _file_boxes(load):
        try:
            models = mjcf.read_models(load.path, load.flags)
        except Exception:  # the reason is given already
            return [(None, None)]
        n = sum(len(lk.boxes) for m in models if m is not None for lk in m.links)
        return [(None, n)]

    def _looks_mjcf(self, b, names, n_joints) -> bool:
        if any(_MJCF_LINK.match(name) for name in names.values()):
            return True
        return any(_MJCF_JOINT.match(raw.getJointInfo(b, j, physicsClientId=self.cid)[1].decode("utf-8", "replace"))
                   for j in range(n_joints))

    def _frame_boxes(self, b, link, rec, shadow, from_file=None, static=False):
        """(boxes, why unreadable or None) of one frame; shapes left to pybullet are noted.
        ``static``: a fixed base, whose planes are swept as the half-spaces they are."""
        if (b, link) in self.registered:
            return self.registered[(b, link)][1], None
        if from_file is not None:
            lk = from_file.get(link)
            if lk is None:
                return [], None
            planes = [plane_box((0.0, 0.0, 1.0), X) for X in lk.planes] if static else []
            rec.left.extend((link, what) for what in lk.others + ([] if static else ["plane"] * len(lk.planes)))
            return list(lk.boxes) + planes, None
        if self.journal.link_geometry.get(b, {}).get(link) == pybullet.GEOM_HEIGHTFIELD:
            rec.left.append((link, "heightfield"))  # getCollisionShapeData would print an error for it
            return [], None
        if not rec.maximal or shadow is not None:
            boxes, others = multibody_boxes(self.cid, b, link, planes=static) if shadow is None else \
                shadow.get(link, ([], []))
            rec.left.extend((link, _GEOMETRY.get(g, str(g))) for g, _ in others)
            rec.thickness.setdefault(link, []).extend(size for _, size in others)
            return boxes, None
        if link != -1:
            return [], "a link of a maximal-coordinate body made before bullet_boxccd was imported"
        if self._probe_shape < 0:
            self._probe_shape = raw.createCollisionShape(pybullet.GEOM_SPHERE, radius=1e-3, physicsClientId=self.cid)
        pos, q = raw.getBasePositionAndOrientation(b, physicsClientId=self.cid)
        boxes, why = probe_boxes(self.cid, b, link, pose_matrix(pos, q), self._probe_shape)
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
        unswept, unswept_groups = {}, {}  # shapes left to pybullet: (body, link) -> what; its default and file groups
        unswept_thickness = {}
        box_frame, half, X_CS = [], [], []
        for b in ids:
            rec = self._bodies[b]
            file_groups = self.journal.file_group_mask.get(b, {})
            file_group = partial(_file_group, rec, file_groups)
            for fr in rec.frames:
                f = len(keys)
                keys.append((b, fr.link))
                kinds.append(fr.kind)
                selfc.append(b in self.self_collision_bodies or b in self.journal.self_collision)
                defaults.append(default_group_mask(fr.fixed))
                group = file_group(fr.link)
                if group is not None:
                    fgm[(b, fr.link)] = group
                for h, X in fr.boxes:
                    box_frame.append(f)
                    half.append(h)
                    X_CS.append(X)
            for link, what in rec.left:
                if what not in ("plane", "soft body"):
                    unswept[(b, link)] = what
                    unswept_thickness[(b, link)] = rec.thickness.get(link, [None])
                    unswept_groups[(b, link)] = (default_group_mask(link == -1 and rec.fixed_base), file_group(link))
            for link, why in rec.unreadable:
                self._warn(("unreadable", b, link), f"body {b} link {link}: its boxes cannot be read ({why}); "
                                                    "left to pybullet (declare them with BoxCCD.register_box)")
            if rec.untracked:
                self._warn(("untracked", b, self.journal.bodies.get(b, 0), self.journal.reset),
                           f"body {b}: {_untracked(rec)} left to pybullet, not swept: {rec.untracked_why}")
        half = np.array(half, dtype=float).reshape(-1, 3)
        X_CS = np.array(X_CS, dtype=float).reshape(-1, 4, 4)
        frame_boxes = [[] for _ in keys]
        for i, f in enumerate(box_frame):
            frame_boxes[f].append(i)
        frames_of = {}
        for f, (b, _) in enumerate(keys):
            frames_of.setdefault(b, []).append(f)
        rigid, chains, fixed, stuck = [], [], [], {}
        for b in ids:
            rec = self._bodies[b]
            if rec.moves == "soft":
                stuck[b] = "a soft body"
            elif rec.unposed:
                stuck[b] = "pybullet gives no state of a maximal-coordinate body's links"
            elif any(fr.kind != STATIC for fr in rec.frames):
                continue  # its boxes' frames go back (contacts.py, articulated.py)
            elif rec.moves == "chain":
                chains.append(b)
            elif rec.moves == "rigid":
                rigid.append(b)
            elif not rec.frames:
                fixed.append(b)
        kind = np.array(kinds, dtype=np.int8)
        self.tables = Tables(
            keys=keys, index={k: i for i, k in enumerate(keys)},
            body=np.array([k[0] for k in keys], dtype=np.int64), kind=kind,
            self_collides=np.array(selfc, dtype=np.uint8), box_frame=np.array(box_frame, dtype=np.int64),
            half=half, X_CS=X_CS,
            radius=np.linalg.norm(X_CS[:, :3, 3], axis=1) + np.linalg.norm(half, axis=1),
            frame_boxes=frame_boxes, frames_of=frames_of,
            filters=Filters(keys, defaults, fgm, self.journal, unswept_groups),
            free_frames=np.flatnonzero(kind == FREE).tolist(), unswept=unswept, unswept_thickness=unswept_thickness,
            damping=np.array([self.damping(b) for b, _ in keys], dtype=np.float64).reshape(-1, 2),
            other_rigid=rigid, other_chains=chains, other_fixed=fixed, other_stuck=stuck)

    # ---------------------------------------------------------------- summary
    def fixed_base(self, b) -> bool:
        """Whether body b's base is fixed (of no mass), as read when the body was."""
        rec = self._bodies.get(b)
        return rec is not None and rec.fixed_base

    def maximal(self, b) -> bool:
        """Whether body b is in maximal coordinates (a btRigidBody: pybullet's velocity clamp
        is its multibodies')."""
        rec = self._bodies.get(b)
        return rec is not None and rec.maximal

    def velocity_clamp(self, b):
        """The speed pybullet cuts each component of body b's base velocity and spin to (its
        maxJointVelocity, given or pybullet's 100), or None in maximal coordinates (pybullet
        cuts a rigid body's at none)."""
        return None if self.maximal(b) else self.journal.max_velocity.get(b, MAX_VELOCITY)

    def damping(self, b) -> tuple:
        """(linear, angular) damping of body b as Bullet damps a free multibody base."""
        return damping(self.journal, b, self.maximal(b))

    def summary(self) -> str:
        t = self.tables
        lines = [f"BoxCCD: {len(t.half)} boxes on {len(t.keys)} links of {len(set(t.body.tolist()))} bodies "
                 f"({int((t.kind == STATIC).sum())} static links)"]
        for b, rec in self._bodies.items():
            for link, what in rec.left:
                lines.append(f"  left to pybullet: body {b} link {link}: {what}")
            for link, why in rec.unreadable:
                lines.append(f"  body {b} link {link}: boxes unreadable ({why}); use register_box()")
            if rec.untracked:
                lines.append(f"  not tracked: body {b}: {_untracked(rec)} ({rec.untracked_why})")
        return "\n".join(lines)


def _file_group(rec, file_groups, link):
    """The (group, mask) a body's file sets on a link ({link name: ...} of a URDF), or None."""
    if link in rec.groups:
        return rec.groups[link]
    return file_groups.get(rec.names.get(link))


def _untracked(rec) -> str:
    """The boxes of a body that BoxCCD cannot track, in words."""
    known = [(lk, n) for lk, n in rec.untracked if lk is not None]
    if known:
        total = sum(n for _, n in known)
        return (f"{total} box{'es' if total != 1 else ''} on link{'s' if len(known) > 1 else ''} "
                + ", ".join(f"{lk} ({n})" for lk, n in known))
    n = rec.untracked[0][1]
    return "its boxes" if n is None else f"its boxes (its file has {n})"


_PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _in_package(filename) -> bool:
    return os.path.abspath(filename).startswith(_PACKAGE + os.sep)


def outside_stacklevel() -> int:
    """The ``stacklevel`` for warnings.warn, called right here, that names the first frame
    outside this package: the user's line that built or stepped the BoxCCD."""
    level, frame = 1, sys._getframe(1)
    while frame is not None and _in_package(frame.f_code.co_filename):
        frame, level = frame.f_back, level + 1
    return level


def warn_once(seen: set, cid: int = 0):
    """A warner that emits each key's BoxCCDWarning once, at the user's line; of a world of
    a client other than the first (0), the message names it (and so Python's warning filter,
    which shows a message once per line, tells it from the same of another client)."""
    prefix = f"physics client {cid}: " if cid else ""

    def warn(key, message):
        if key not in seen:
            seen.add(key)
            warnings.warn(prefix + message, BoxCCDWarning, stacklevel=outside_stacklevel())
    return warn
