"""Reading the frames' state from pybullet (one call per frame: pybullet has no batch
read) into the core's frame-state rows (``layout``), and keeping the start-of-step
poses of kinematic frames.

A kinematic frame is a ``STATIC`` one (a fixed base) that the user moves: teleported
between steps (``resetBasePositionAndOrientation``), or given a velocity
(``resetBaseVelocity``: Bullet then moves a fixed multibody base by it during the
step, the way it moves any body). Its move is two parts: the jump from its pose after
the previous step (E0) to the pose the step started from (P1: Bullet's path from the
pose after the step, E1, taken back to the step's start), instantaneous as far as
the step's physics is concerned; then the step's own motion from P1 to E1, swept like
any other.
"""

from __future__ import annotations

import math
from functools import partial

import numpy as np

from .. import _core
from ._hooks import MAX_VELOCITY, raw
from .layout import POSE, TWIST
from .world import STATIC

__all__ = ["FrameState"]

# Relative size below which a kinematic frame's jump is rounding of the path's
# reconstruction, not a move.
_JUMP = 1e-12


_AT_REST = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


def _readers(cid, body, link, at_rest=False):
    """pybullet's (pose, velocity) reads of a frame's centre of mass as they come: ((x,
    y, z), (qx, qy, qz, qw)) and ((vx, vy, vz), (wx, wy, wz)) (world). ``at_rest``: a
    static frame whose velocity pybullet neither moves it by nor gives its contacts (a
    fixed rigid body: its solver treats it as at rest), read as none."""
    if link == -1:
        return (partial(raw.getBasePositionAndOrientation, body, physicsClientId=cid),
                (lambda: _AT_REST) if at_rest else partial(raw.getBaseVelocity, body, physicsClientId=cid))
    return (lambda: raw.getLinkState(body, link, physicsClientId=cid)[:2],
            lambda: raw.getLinkState(body, link, computeLinkVelocity=1, physicsClientId=cid)[6:8])


class FrameState:
    """The (F, 13) state of every frame after the current step, and the kinematic frames."""

    def __init__(self, cid, tables, sweep_reach, articulated=frozenset(), not_finite=lambda frames: None,
                 clamped=lambda frames: None, at_rest=frozenset()):
        self.cid, self.tables, self._not_finite, self._clamped = cid, tables, not_finite, clamped
        f = tables.filters
        # The core's sweeper holds the box tables and the rows (``rows`` is a numpy view of
        # them): a step's calls into the core pass no array.
        self._reach = sweep_reach
        self.sweeper = _core.Sweeper(tables.box_frame, tables.radius, tables.X_CS, tables.half, sweep_reach,
                                     tables.body, tables.self_collides, f.group, f.mask, f.mode)
        self.rows = self.sweeper.state
        self._at_rest = at_rest  # static frames whose velocity pybullet ignores (``_readers``)
        readers = [_readers(cid, b, link, f in at_rest) for f, (b, link) in enumerate(tables.keys)]
        self._pose, self._twist = zip(*readers) if readers else ((), ())
        static = np.flatnonzero(tables.kind == STATIC).tolist()
        self._static = set(static)
        self.fresh = set()  # moving or kinematic frames whose poses in ``rows`` are this step's (read or set)
        self._read_static(static)
        # Frames whose velocity is read at every step (an articulated body's are read
        # whole: articulated.py).
        self.moving = [f for f in tables.moving if f not in articulated]
        self._moving_twists = [self._twist[f] for f in self.moving]
        # Static frames the user gave a velocity (Bullet moves them), before this state was
        # made too: Bullet keeps moving a fixed base by its velocity at every step.
        self.with_velocity = {f for f in static if any(x != 0.0 for part in self._twist[f]() for x in part)}
        self.kinematic = []  # static frames the user moved before the current step, or that have a velocity
        self.pose0 = {}  # kinematic frame -> its pose before the current step (E0)
        self.jumps = {}  # kinematic frame -> (E0, P1): it jumped before the step
        self.twist0 = None  # (F, 6) every frame's velocities when the (partial) step began, if known

    def begin(self, known):
        """Before a (partial) step: keep the velocities it starts from, where ``rows`` holds
        them (``known``: they were read after the last step, or set since, and the user
        changed nothing in between)."""
        self.twist0 = self.rows[:, TWIST].copy() if known else None

    def fast(self, dt, read=False):
        """``Sweeper.fast`` of a step of dt (the moving frames' velocities read first, with
        ``read``): (fast boxes, slack, their frames), or None. Frames whose state pybullet
        left not finite, which pybullet alone steps, are told to ``not_finite``; frames with a
        component of velocity at pybullet's default clamp or above, to ``clamped``."""
        found = self.sweeper.fast(dt, self.moving, self.twists(), MAX_VELOCITY) if read else \
            self.sweeper.fast(dt, clamp=MAX_VELOCITY)
        if found is None:
            return None
        boxes, slack, frames, broken, clamped = found
        if broken:
            self._not_finite(broken)
        if clamped:
            self._clamped(clamped)
        return (boxes, slack, frames) if boxes else None

    def twists(self) -> list:
        """pybullet's velocity reads of the moving frames, as they come."""
        return [read() for read in self._moving_twists]

    def read_velocities(self):
        self.sweeper.put_twists(self.moving, self.twists())

    def read_twists(self, frames):
        """Read the velocities of ``frames`` now."""
        if frames:
            self.sweeper.put_twists(frames, [self._twist[f]() for f in frames])

    def read_poses(self, frames):
        if frames:
            pose = self._pose
            self.sweeper.put_poses(frames, [pose[f]() for f in frames])
            self.fresh.update(frames)

    def pose_of(self, f):
        """Frame f's (position, orientation) as pybullet holds it now (``rows`` untouched)."""
        return self._pose[f]()

    def name_not_finite(self, frames):
        """Tell ``not_finite`` those of ``frames`` whose pose pybullet holds not finite now (a
        pose the user gave; one read each, kept out of ``rows``)."""
        pose = self._pose
        self._name_broken(frames, [[x for part in pose[f]() for x in part] for f in frames])

    def _read_static(self, frames):
        """Read the poses of static ``frames``; those pybullet holds not finite (the user placed
        them so) are told to ``not_finite``: nothing meets them, in pybullet or in a sweep."""
        self.read_poses(frames)
        self._name_broken(frames, self.rows[frames][:, POSE].tolist())

    def _name_broken(self, frames, poses):
        """Tell ``not_finite`` the frames whose poses (a list of numbers each) are not finite."""
        broken = [f for f, row in zip(frames, poses) if not all(map(math.isfinite, row))]
        if broken:
            self._not_finite(broken)

    def stale(self, frames):
        """Those of ``frames`` whose poses in ``rows`` are not this step's (a static frame's
        are, unless the user gave it a velocity: Bullet moves it then)."""
        fresh, static, moved = self.fresh, self._static, self.with_velocity
        return [f for f in frames if f not in fresh and (f not in static or f in moved)]

    def begin_kinematic(self, moved_static, with_velocity):
        """Before the step: note the static frames the user moved since the last step and
        those given a velocity (but those whose velocity pybullet ignores: ``_readers``; their
        poses before the step are the ones known now)."""
        self.fresh = set()
        with_velocity = [f for f in with_velocity if f not in self._at_rest]
        if not (moved_static or with_velocity or self.with_velocity):
            self.pose0, self.kinematic = {}, []
            return
        self.with_velocity.update(with_velocity)
        frames = sorted(set(moved_static) | self.with_velocity)
        self.pose0 = {f: self.rows[f, POSE].copy() for f in frames}
        self.kinematic = frames

    def end_kinematic(self, dt, erp):
        """After the step: the kinematic frames' poses and velocities now; the frames that
        jumped (E0 != P1) farther than pybullet holds (``erp``: the contact ERP) go to
        ``jumps`` as {frame: (E0, P1)}."""
        frames = self.kinematic
        self.jumps = {}
        if not frames:
            return
        self._read_static(frames)
        self.read_twists(frames)
        starts = _core.frame_poses(self.rows, dt, np.array(frames, dtype=np.int64), np.zeros(len(frames)))
        t = self.tables
        for f, p1, pose1 in zip(frames, starts.tolist(), starts):
            e0 = self.pose0[f].tolist()
            (ax, ay, az, aw), (bx, by, bz, bw) = p1[3:], e0[3:]
            # sin(angle / 2) axis of q1 q0^-1: bw a - aw b - a x b
            turn = (bw * ax - aw * bx - (ay * bz - az * by), bw * ay - aw * by - (az * bx - ax * bz),
                    bw * az - aw * bz - (ax * by - ay * bx))
            shift, sin_half = math.dist(p1[:3], e0[:3]), min(math.hypot(*turn), 1.0)
            if shift <= _JUMP * (1.0 + max(map(abs, e0[:3]))) and sin_half <= _JUMP:
                continue
            # pybullet gives a teleport no velocity: its solver pushes a box out of the overlap
            # a teleport made by ERP x that overlap a step only, so a box a body is teleported
            # into by s at every step sinks into it until it is s / ERP deep (a box on a plate
            # teleported up at 2 m/s, 240 Hz: 10 cm, through the plate). A jump that leaves no
            # box of the frame deeper than a free box may move unswept in a step is pybullet's.
            boxes = t.frame_boxes[f]
            if np.any(shift + 2.0 * math.asin(sin_half) * t.radius[boxes] > erp * self._reach[boxes]):
                self.jumps[f] = (self.pose0[f], pose1)
