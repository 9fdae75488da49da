"""An articulated body's links as pybullet describes them, for the core's link paths.

``read_chain`` reads a body's constant description once (getJointInfo and
getDynamicsInfo per link); ``read_joint_state`` reads its joints after a step (one
getJointStatesMultiDof call); ``read_base_state`` its base (two calls). The core's
``ChainMotion`` then gives every link's centre-of-mass frame at any step fraction
tau in [0, 1] (0: the start of the step, 1: after it), rebuilt backwards from the
state after the step by Bullet's own integration rules (docs/design.md, "Link
paths"), and conservative quadratic fits of those paths; ``LinkBoxPath`` puts a box
on a link, for ``paths_first_touch``.

Frames: a link's pose is its centre-of-mass (inertial) frame, world, as
``getLinkState(...)[0:2]``; position (3) then quaternion x y z w (4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as p

from .. import _core
from ..motion import pose_matrix

__all__ = ["BodyChain", "read_base_state", "read_chain", "read_joint_state"]

# Coordinates and velocities per joint type (pybullet's numbers); planar is refused.
_Q_SIZE = {p.JOINT_REVOLUTE: 1, p.JOINT_PRISMATIC: 1, p.JOINT_SPHERICAL: 4, p.JOINT_FIXED: 0}
_QDOT_SIZE = {p.JOINT_REVOLUTE: 1, p.JOINT_PRISMATIC: 1, p.JOINT_SPHERICAL: 3, p.JOINT_FIXED: 0}


@dataclass(frozen=True)
class BodyChain:
    """One body's links, as pybullet reports them (n links, pybullet's link order).

    Attributes
    ----------
    body : int
    parent : (n,) int64
        Parent link, -1 for the base; always an earlier link.
    joint_type : (n,) int64
        p.JOINT_REVOLUTE, p.JOINT_PRISMATIC, p.JOINT_SPHERICAL or p.JOINT_FIXED.
    axis : (n, 3) float
        getJointInfo's jointAxis, in the link's centre-of-mass frame.
    parent_pos, parent_orn : (n, 3), (n, 4) float
        getJointInfo's parentFramePos (the pivot in the parent's centre-of-mass frame)
        and parentFrameOrn (the parent's frame to the link's at q = 0).
    inertial_pos, inertial_orn : (n, 3), (n, 4) float
        getDynamicsInfo's local inertial frame (the centre-of-mass frame in the URDF
        link frame, which is also the joint frame).
    q_index, qdot_index : (n,) int64
        Where each joint's coordinates start in the flat q and qdot of read_joint_state.
    core : _core.Chain
    """

    body: int
    parent: np.ndarray
    joint_type: np.ndarray
    axis: np.ndarray
    parent_pos: np.ndarray
    parent_orn: np.ndarray
    inertial_pos: np.ndarray
    inertial_orn: np.ndarray
    q_index: np.ndarray
    qdot_index: np.ndarray
    core: _core.Chain

    @property
    def n_links(self) -> int:
        return len(self.parent)

    def motion(self, state, q, qdot, dt: float) -> _core.ChainMotion:
        """The chain over a step of dt, from the state after it: ``state`` (13,) the base's
        frame state (read_base_state), ``q``, ``qdot`` from read_joint_state."""
        return _core.ChainMotion(self.core, _floats(state, "state"), _floats(q, "q"), _floats(qdot, "qdot"), dt)

    def link_poses(self, state, q, qdot, dt: float, tau: float) -> np.ndarray:
        """(n, 7) every link's centre-of-mass frame at step fraction tau."""
        return self.motion(state, q, qdot, dt).link_poses(tau)

    def local_inertial_matrices(self) -> np.ndarray:
        """(n, 4, 4) each link's centre-of-mass frame in its URDF link frame: the link frame
        (getLinkState()[4:6]) is the centre-of-mass frame times the inverse of this."""
        return np.array([pose_matrix(pos, orn) for pos, orn in zip(self.inertial_pos, self.inertial_orn)]).reshape(
            self.n_links, 4, 4)


def _floats(x, name: str) -> np.ndarray:
    a = np.ascontiguousarray(x, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"{name}: expected a 1-d array, got shape {a.shape}")
    return a


def read_chain(cid: int, body: int) -> BodyChain:
    """A body's links (getJointInfo and getDynamicsInfo per link; read once per body).

    Raises ValueError for a planar joint (pybullet reports 2 of its 3 coordinates and no
    axis) or a joint type the core does not know.
    """
    n = p.getNumJoints(body, physicsClientId=cid)
    parent = np.empty(n, np.int64)
    joint_type = np.empty(n, np.int64)
    axis, parent_pos, inertial_pos = (np.zeros((n, 3)) for _ in range(3))
    parent_orn, inertial_orn = np.zeros((n, 4)), np.zeros((n, 4))
    q_index, qdot_index = np.zeros(n, np.int64), np.zeros(n, np.int64)
    nq = nqdot = 0
    for j in range(n):
        info = p.getJointInfo(body, j, physicsClientId=cid)
        kind = info[2]
        if kind not in _Q_SIZE:
            name = "planar" if kind == p.JOINT_PLANAR else f"type {kind}"
            raise ValueError(f"body {body}, link {j}: {name} joints are not supported (pybullet reports 2 of a "
                             "planar joint's 3 coordinates and no axis)")
        dyn = p.getDynamicsInfo(body, j, physicsClientId=cid)
        parent[j], joint_type[j] = info[16], kind
        axis[j], parent_pos[j], parent_orn[j] = info[13], info[14], info[15]
        inertial_pos[j], inertial_orn[j] = dyn[3], dyn[4]
        q_index[j], qdot_index[j] = nq, nqdot
        nq += _Q_SIZE[kind]
        nqdot += _QDOT_SIZE[kind]
    core = _core.Chain(parent, joint_type, axis, parent_pos, parent_orn, inertial_pos, inertial_orn, q_index,
                       qdot_index)
    return BodyChain(body, parent, joint_type, axis, parent_pos, parent_orn, inertial_pos, inertial_orn, q_index,
                     qdot_index, core)


def read_joint_state(cid: int, body: int, n_links: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(q, qdot): every joint's coordinates and velocities, flat in link order (one
    getJointStatesMultiDof call). A revolute or prismatic joint gives one of each, a
    spherical one its quaternion x y z w and its angular velocity (in the link's
    centre-of-mass frame), a fixed one none. n_links: the body's, if known."""
    if n_links is None:
        n_links = p.getNumJoints(body, physicsClientId=cid)
    if n_links == 0:
        return np.zeros(0), np.zeros(0)
    states = p.getJointStatesMultiDof(body, list(range(n_links)), physicsClientId=cid)
    q = np.fromiter((x for s in states for x in s[0]), np.float64)
    qdot = np.fromiter((x for s in states for x in s[1]), np.float64)
    return q, qdot


def read_base_state(cid: int, body: int) -> np.ndarray:
    """(13,) the base's frame state: centre of mass, quaternion x y z w, v, w (world)."""
    pos, orn = p.getBasePositionAndOrientation(body, physicsClientId=cid)
    v, w = p.getBaseVelocity(body, physicsClientId=cid)
    return np.array([*pos, *orn, *v, *w], dtype=np.float64)
