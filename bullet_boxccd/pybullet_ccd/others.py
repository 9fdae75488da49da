"""The bodies with no box BoxCCD sweeps (a sphere, a mesh, a capsule robot), taken back
with the world.

When a contact takes the world back to its time, every body has to go back, or the rest
of the step simulated again from there would move these twice over that time. Their
state is read only then, after the step being gone back into:

* a free single body goes where Bullet's path has it at that time, with its velocity
  after the step less the rest of the step's gravity and damping (its velocity before
  the step is not read; in free flight this ends the rest of the step exactly where the
  step ended);
* an articulated one goes back in joint space (``chain``), its base's velocity so (a
  fixed base's kept), its joint velocities those after the step;
* a fixed base the user gave a velocity (Bullet moves it by it) goes back on its path,
  with the velocity that the rest of the step turns into the one it ended with.

For a robot, its damping and its joints' accelerations over the rest of the step are
applied again. A body whose state pybullet does not give (a soft body, the links of a
maximal-coordinate body) cannot go back: a warning names it the first time the world
goes back without it.
"""

from __future__ import annotations

import numpy as np
import pybullet

from .. import _core
from ._hooks import raw
from .chain import read_base_state, read_chain, read_joint_state

__all__ = ["Others", "joint_layout", "put_body"]


def joint_layout(chain):
    """(moving joints, their spans in the flat q, their spans in the flat qdot) of a chain."""
    moving = [j for j in range(chain.n_links) if chain.joint_type[j] != pybullet.JOINT_FIXED]
    spherical = [chain.joint_type[j] == pybullet.JOINT_SPHERICAL for j in moving]
    q_spans = [(int(chain.q_index[j]), int(chain.q_index[j]) + (4 if s else 1)) for j, s in zip(moving, spherical)]
    qdot_spans = [(int(chain.qdot_index[j]), int(chain.qdot_index[j]) + (3 if s else 1))
                  for j, s in zip(moving, spherical)]
    return moving, q_spans, qdot_spans


def put_body(cid, body, base, twist, layout, q, qdot):
    """Set an articulated body's base pose (7,) and velocities (6,), and its moving joints'
    positions and velocities (flat q and qdot, ``layout`` from ``joint_layout``)."""
    raw.resetBasePositionAndOrientation(body, base[:3].tolist(), base[3:].tolist(), physicsClientId=cid)
    raw.resetBaseVelocity(body, twist[:3].tolist(), twist[3:].tolist(), physicsClientId=cid)
    moving, q_spans, qdot_spans = layout
    if moving:
        q, qdot = q.tolist(), qdot.tolist()
        raw.resetJointStatesMultiDof(body, moving, [q[a:b] for a, b in q_spans], [qdot[a:b] for a, b in qdot_spans],
                                     physicsClientId=cid)


class Others:
    """The world's bodies with no tracked box: ``rigid`` (free single bodies),
    ``articulated`` (their links read the first time the world goes back), ``fixed``
    (fixed bases with no links: they move only if the user gave them a velocity, which the
    journal knows); ``stuck``: {body: why it cannot go back}."""

    def __init__(self, cid, journal, rigid, articulated, fixed, stuck, warn, damping):
        self.cid, self.journal, self.rigid, self.fixed = cid, journal, list(rigid), list(fixed)
        self._damping = damping  # body -> (linear, angular) damping, as Bullet damps a free base
        self.stuck, self._warn = dict(stuck), warn
        self._unread, self.chains = list(articulated), {}  # chains: {body: (chain, joint layout, falls)}

    def _read_chains(self):
        for b in self._unread:
            try:
                chain = read_chain(self.cid, b)
            except ValueError as e:
                self.stuck[b] = str(e)
                continue
            falls = raw.getDynamicsInfo(b, -1, physicsClientId=self.cid)[0] > 0.0  # a fixed base does not
            self.chains[b] = (chain, joint_layout(chain), falls)
        self._unread = []

    def back(self, dt, tau, gravity):
        """After a (partial) step of dt: every such body where its path has it at tau."""
        cid = self.cid
        if self._unread:
            self._read_chains()
        # A body standing exactly still after the step stays where it is (placing it would
        # wake a sleeping one).
        given = self.journal.velocity_set  # (mode 2: a free body; 0: a fixed base moved by its velocity)
        states = [(b, read_base_state(cid, b), 2) for b in self.rigid]
        states += [(b, read_base_state(cid, b), 0) for b in self.fixed if b in given]
        states = [(b, x, mode) for b, x, mode in states if np.any(x[7:13])]
        if states:
            bodies, rows, modes = zip(*states)
            rows = np.array(rows)
            poses = _core.frame_poses(rows, dt, np.arange(len(rows), dtype=np.int64), np.full(len(rows), tau))
            damp = np.array([self._damping(b) for b in bodies], dtype=np.float64)
            twists = _core.twists_at(rows[:, 7:13], list(modes), dt, tau, gravity, damp)
            for b, pose, twist in zip(bodies, poses.tolist(), twists.tolist()):
                raw.resetBasePositionAndOrientation(b, pose[:3], pose[3:], physicsClientId=cid)
                raw.resetBaseVelocity(b, twist[:3], twist[3:], physicsClientId=cid)
        for b, (chain, layout, falls) in self.chains.items():
            state = read_base_state(cid, b)
            q, qdot = read_joint_state(cid, b, chain.n_links)
            if not (np.any(state[7:13]) or np.any(qdot)):
                continue
            motion = chain.motion(state, q, qdot, dt)
            twist = _core.twists_at(state[None, 7:13], [2], dt, tau, gravity)[0] if falls else state[7:13]
            put_body(cid, b, motion.base_pose(tau), twist, layout, motion.joint_positions(tau), qdot)
        for b, why in self.stuck.items():
            self._warn(("stuck", b), f"body {b} is not taken back with the world when a contact takes it back to "
                                     f"its time ({why}): it runs ahead of the rest by the time gone back")
