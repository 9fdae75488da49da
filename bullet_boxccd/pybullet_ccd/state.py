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

import numpy as np

from .. import _core
from ._hooks import raw
from .layout import POSE, STATE_SIZE
from .world import STATIC

__all__ = ["FrameState", "read_twists", "read_poses"]

# Relative size below which a kinematic frame's jump is rounding of the path's
# reconstruction, not a move.
_JUMP = 1e-12


def read_twists(cid, keys, frames) -> list:
    """pybullet's velocity reads of the given frames as they come, ((vx, vy, vz), (wx,
    wy, wz)) each (world, centre of mass)."""
    get_v, get_link = raw.getBaseVelocity, raw.getLinkState
    return [get_v(keys[f][0], physicsClientId=cid) if keys[f][1] == -1 else
            get_link(keys[f][0], keys[f][1], computeLinkVelocity=1, physicsClientId=cid)[6:8] for f in frames]


def read_poses(cid, keys, frames) -> list:
    """pybullet's reads of the given frames' centre-of-mass poses as they come, ((x, y,
    z), (qx, qy, qz, qw)) each."""
    get_pose, get_link = raw.getBasePositionAndOrientation, raw.getLinkState
    return [get_pose(keys[f][0], physicsClientId=cid) if keys[f][1] == -1 else
            get_link(keys[f][0], keys[f][1], physicsClientId=cid)[:2] for f in frames]


class FrameState:
    """The (F, 13) state of every frame after the current step, and the kinematic frames."""

    def __init__(self, cid, tables):
        self.cid, self.tables = cid, tables
        self.rows = np.zeros((len(tables.keys), STATE_SIZE))
        self.rows[:, 6] = 1.0
        static = np.flatnonzero(tables.kind == STATIC).tolist()
        _core.put_poses(self.rows, static, read_poses(cid, tables.keys, static))
        self._static = set(static)
        self.moving = list(tables.moving)  # frames whose velocity is read at every step
        self.with_velocity = set()  # static frames the user gave a velocity (Bullet moves them)
        self.kinematic = []  # static frames the user moved before the current step, or that have a velocity
        self.pose0 = {}  # kinematic frame -> its pose before the current step (E0)
        self.jumps = {}  # kinematic frame -> (E0, P1): it jumped before the step
        self.fresh = set()  # moving or kinematic frames whose poses in ``rows`` are this step's (read or set)

    def twists(self) -> list:
        """pybullet's velocity reads of the moving frames (see read_twists)."""
        return read_twists(self.cid, self.tables.keys, self.moving)

    def read_velocities(self):
        _core.put_twists(self.rows, self.moving, self.twists())

    def read_poses(self, frames):
        if frames:
            _core.put_poses(self.rows, frames, read_poses(self.cid, self.tables.keys, frames))
            self.fresh.update(frames)

    def stale(self, frames):
        """Those of ``frames`` whose poses in ``rows`` are not this step's."""
        fresh, static = self.fresh, self._static
        return [f for f in frames if f not in fresh and f not in static]

    def begin_kinematic(self, moved_static, with_velocity):
        """Before the step: note the static frames the user moved since the last step and
        those with a velocity (their poses before the step are the ones known now)."""
        self.fresh = set()
        if not (moved_static or with_velocity or self.with_velocity):
            self.pose0, self.kinematic = {}, []
            return
        self.with_velocity.update(with_velocity)
        frames = sorted(set(moved_static) | self.with_velocity)
        self.pose0 = {f: self.rows[f, POSE].copy() for f in frames}
        self.kinematic = frames

    def end_kinematic(self, dt):
        """After the step: the kinematic frames' poses and velocities now; the frames that
        jumped (E0 != P1) go to ``jumps`` as {frame: (E0, P1)}."""
        frames = self.kinematic
        self.jumps = {}
        if not frames:
            return
        self.read_poses(frames)
        _core.put_twists(self.rows, frames, read_twists(self.cid, self.tables.keys, frames))
        starts = _core.frame_poses(self.rows, dt, np.array(frames, dtype=np.int64), np.zeros(len(frames)))
        for f, p1 in zip(frames, starts):
            e0 = self.pose0[f]
            a, b = p1[3:], e0[3:]
            turn = b[3] * a[:3] - a[3] * b[:3] - np.cross(a[:3], b[:3])  # sin(angle / 2) axis of q1 q0^-1
            if np.abs(p1[:3] - e0[:3]).max() > _JUMP * (1.0 + np.abs(e0[:3]).max()) or \
                    np.linalg.norm(turn) > _JUMP:
                self.jumps[f] = (e0, p1)
