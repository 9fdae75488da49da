"""Drop-in tunneling prevention for pybullet worlds (this package is the only one that
imports pybullet).

``BoxCCD.step()`` replaces ``p.stepSimulation()``. The flow of a step, one module each:

1. ``world``: bring the tracked boxes up to date with what changed since the last
   step (bodies created, removed, re-massed, filters), from the journal that
   ``_hooks`` keeps of pybullet's world-changing calls; ``shapes`` reads a body's boxes.
2. pybullet takes its step (with ``numSubSteps = n``, the plugin takes the n substeps
   itself and sweeps each).
3. ``state``: read the velocities of the moving frames (and the poses of the
   kinematic ones: static bodies the user moves).
4. ``sweep``: the fast boxes' exact within-step paths (Bullet moves a centre of mass
   linearly with the post-solve velocity and turns it about a fixed axis:
   ``_core/paths/step_path.hpp``), their partners from pybullet's own broad phase on the
   swept bounds, the filters (``filters``: pybullet's own, mirrored), and each pair's
   first touch on conservatively fitted quadratic motions (the BMS solver).
5. ``contacts``: the contacts in one time-ordered pass (``articulated`` finds those
   of link boxes on their chain paths). Where a pair met inside the step and pybullet
   would resolve it from where the step left it wrongly (deep in, or past), the world is
   taken back to the contact's time on Bullet's own paths and the rest of the step is
   simulated again (a partial step), up to ``max_partial_steps`` times a step: pybullet's
   contact solver then sees the contact as it begins, as at a fine step, and the impact
   is the engine's.
6. ``events``: the step's contacts and the running counters.

Why sweep after the step rather than predict before it: the path depends on the
post-solve velocity, which is known only after pybullet solved the step's contacts;
afterwards the path is exact, not predicted.
"""

from __future__ import annotations

import itertools
import math
import numbers
import time
from contextlib import contextmanager

import numpy as np
import pybullet

from .. import _core
from .._arrays import as_float_array
from ..motion import pose_matrix
from ..solver import DEFAULT_TOLERANCES, InvalidInputError, Tolerances
from ._hooks import MAX_VELOCITY, joints_set_since, last_serial, position_motors, raw, replay_impulses
from .articulated import Articulated
from .contacts import Contacts
from .events import BoxCCDWarning, CCDEvent, CCDStats, ClientDisconnectedError, not_finite_message
from .layout import ANGULAR_VELOCITY, VELOCITY
from .others import Others
from .state import FrameState
from .sweep import jump_sweep, sweep
from .world import FREE, STATIC, World, warn_once

__all__ = ["BoxCCD", "BoxCCDWarning", "ClientDisconnectedError", "CCDEvent", "CCDStats"]

_CLAMP = 0.999 * 0.25 * math.pi  # (rad) just under Bullet's largest turn of a body in one step
# The default budget of partial steps a step takes: each steps the whole world, so as many as
# step this many moving bodies and links in all, within these bounds. A cascade of struck thin
# boxes in a small world needs 20 to 30 (a row of dominoes: each spins at 2,000 rad/s, a
# partial step of pi/4 being 0.4 ms); in a crowd 8 already cost more than numSubSteps=16
# (docs/design.md, mechanisms tried).
_PARTIAL_BODY_STEPS = 256
_PARTIAL_STEPS = (8, 32)
# A body pivoting on a contact turns in one stepSimulation by no more than keeps the drift of
# the point it pivots on under this share of its thinnest half extent (see _turn_limits).
_PIVOT_DRIFT = 0.25
# pybullet's position motor's defaults: its position gain and its force (N or N m).
_POSITION_GAIN, _MOTOR_FORCE = 0.1, 100000.0


class BoxCCD:
    """Continuous collision detection for every box in a pybullet world.

    Parameters
    ----------
    physics_client_id : int
        A connected pybullet client.
    sweep_threshold : float
        A box is swept when its fastest point moves more than this fraction of the
        box's smallest full extent in a step (a slower box overlaps anything it meets in
        some step, so pybullet's discrete contacts catch it). Default 0.25; at least 0;
        above 1 a box may skip a thin wall unswept (warned).
    sweep_distance : float
        A box is also swept when its fastest point moves more than this (m) in a step,
        whatever its size: a large box moving less than its ``sweep_threshold`` can still
        end a step this deep in what it meets. Default 0.01; at least 0.
    fit_tolerance : float
        Largest allowed error of the quadratic rotation fit, as a fraction of the box's
        smallest half extent, in (0, 1]; a step is split into 2, 4, ... pieces until it
        holds, and the box is inflated by what remains. Default 0.05.
    penetration : float
        Depth (m) by which a pair already touching must press in, or part, to count as
        doing so, and the overlap at which a link's contact is resolved; at least this
        for every impact. In (0, 1e-3]. Default 1e-5.
    impact_depth : float
        Overlap (m) at which an impact met inside a step is resolved: the world goes back
        to where the pair overlaps by this much, at most a quarter of the thinner box's
        smallest half extent. Bullet's box-box detector then sees every corner of an edge
        or face that arrives within it, as pybullet at a fine step sees them (a plank's end
        slapping the floor flat strikes with both corners); at 1e-5 m a roll of 1e-4 rad
        hides one, whose partner's impulse alone rolls the plank. In (0, 0.01]. Default
        1e-3.
    depth_tolerance : float
        A pair of free or kinematic bodies that meets inside a step and ends it
        overlapping by less than this (m), on the side it came from, or one already
        touching that ends less than this deeper, is left to pybullet's next step;
        deeper, the world is taken back to the contact (link pairs: only where they go
        wrong). At least 0. Default 1e-3.
    self_collision_bodies : iterable of int
        Bodies whose links collide with each other.
    max_partial_steps : int or None
        Partial steps (the rest of the step simulated again from a contact, or a piece of
        it under ``max_turn``, the step's pieces while a body an impact set turning touches
        something included) after which a contact no longer takes the world back: the
        rest goes to the step's end in one piece, and the bodies of each remaining contact
        go back to it on their own, with the velocities they had there (pybullet resolves
        it as the next step begins). At least 0. Default None: as many as step 256 moving
        bodies (and links) in all, at least 8 and at most 32 (each partial step steps the
        whole world: 32 in a world of up to 8 moving bodies, 8 from 32 on).
    max_turn : float
        The largest turn (rad) a body of the contact the world was taken back to makes in
        a partial step: a longer rest of the step is taken in even pieces. In (0, pi/4]:
        Bullet turns a body at most pi/4 a step, and above that its solver sees a spin
        that its integration does not make. Shorter pieces follow a spinning body's
        contact more closely, and its gyroscopic term more stably, at a partial step
        each. Default pi/4 (just under). A long body turns less: by at most
        sqrt(thin / 2r) (thin: its thinnest half extent, r: its reach), where the point it
        pivots on drifts off its pivot by a quarter of thin; and so does a free body an
        impact set turning, in the steps after it while it touches something (the step
        is then taken in pieces).
    tolerances : Tolerances
        Solver tolerances.
    """

    def __init__(self, physics_client_id: int = 0, *, sweep_threshold: float = 0.25, sweep_distance: float = 0.01,
                 fit_tolerance: float = 0.05,
                 penetration: float = 1e-5, impact_depth: float = 1e-3, depth_tolerance: float = 1e-3,
                 self_collision_bodies=(),
                 max_partial_steps: int | None = None, max_turn: float = _CLAMP,
                 tolerances: Tolerances = DEFAULT_TOLERANCES):
        self.cid = _client(physics_client_id)
        self.sweep_threshold = _number("sweep_threshold", sweep_threshold, 0.0, math.inf)
        self.sweep_distance = _number("sweep_distance", sweep_distance, 0.0, math.inf)
        self.fit_tolerance = _number("fit_tolerance", fit_tolerance, 0.0, 1.0, open_low=True)
        self.penetration = _number("penetration", penetration, 0.0, 1e-3, open_low=True)
        self.impact_depth = _number("impact_depth", impact_depth, 0.0, 1e-2, open_low=True)
        self.depth_tolerance = _number("depth_tolerance", depth_tolerance, 0.0, math.inf)
        self.max_partial_steps = None if max_partial_steps is None else _count("max_partial_steps", max_partial_steps)
        self.max_turn = _number("max_turn", max_turn, 0.0, 0.25 * math.pi, open_low=True)
        if not isinstance(tolerances, Tolerances):
            raise InvalidInputError(f"tolerances: expected a Tolerances, got {type(tolerances).__name__}")
        self.tolerances = tolerances
        self.stats = CCDStats()
        self._warned = set()  # what was said of this world (forgotten when it is reset; of a body, when it is)
        self._renewed_seen = 0  # the latest body removal or creation whose warnings were forgotten
        self._over_seen = 0  # the latest velocity given above the clamp that was looked at
        self._warn = warn_once(self._warned, self.cid)
        if self.sweep_threshold > 1.0:  # (of the knob, not of the world: said once)
            warn_once(set())(("sweep_threshold",),
                             f"sweep_threshold = {self.sweep_threshold:g}: a box that moves less than that many of "
                             "its extents (and less than sweep_distance) a step is not swept, and can skip a wall "
                             "thinner than its move")
        bodies = _bodies(self.cid, self_collision_bodies, "self_collision_bodies")
        self.world = World(self.cid, bodies, self._warn)
        self.contacts = Contacts(self.cid, self.penetration, self.impact_depth, self.depth_tolerance,
                                 self.fit_tolerance, self.tolerances, self.stats, self._clamped,
                                 self.world.velocity_clamp)
        self._params_seen = -1
        self._reset_seen = self.world.journal.reset
        self._alone = False  # pybullet steps the world alone (see _unswept_step)
        self._moves_seen = self.world.journal.last_move  # moves made while building the world are not sweeps
        self._stepped_seen = self.world.journal.stepped  # (direct steps before BoxCCD was made are no concern)
        self._quiet, self._epoch = False, -1  # whether a step may skip every check (see step)
        self._known = False  # whether the frame-state rows hold the velocities the next step starts from
        self._partial = False  # whether the world is set for a partial step (its time step and contact ERP)
        self._motors = {}  # the user's position motors given again for the partial steps (_take)
        self._spent = 0  # partial steps and pieces taken in the current step (at most _partial_steps)
        # Frames of the contact the world was taken back to as the partial step began (acted),
        # and those of them struck by an impact then (its impulse acts whole at that start);
        # the frames a step stopped at an impact, struck as the next step begins.
        self._acted, self._struck, self._struck_next, self._links_met = set(), set(), set(), set()
        self._turning = set()  # free frames an impact the world went back to set turning (see _step_pieces)
        self._clamp_candidates = set()  # frames swept as fast, or read at the velocity clamp, in the current (sub)step
        self._damped = (None, None)  # (when read, a body with a damped joint)
        self._sync()

    # ------------------------------------------------------------ the world
    def refresh(self) -> None:
        """Read the whole world again (``step`` does what is needed by itself). Raises
        ``ClientDisconnectedError`` if the client was disconnected."""
        self._check_connected()
        self.world.tables = None
        self._sync()

    def _sync(self):
        j = self.world.journal
        if j.reset > self._reset_seen:  # resetSimulation: a new world, of which nothing was said yet
            self._warned.clear()
            self._reset_seen = j.reset
            self._alone = False
        if j.stepped > self._stepped_seen:
            self._stepped_seen = j.stepped
            self._warn(("stepped",), "p.stepSimulation was called on this world directly: pybullet takes such steps "
                                     "alone, unswept (a fast box can pass through in them); call BoxCCD.step() "
                                     "in their place")
        if j.unknown:
            *most, last = sorted(j.unknown)
            unknown = f"{', '.join(most)} and {last}" if most else last
            self._warn(("unknown", unknown), f"this client was connected before bullet_boxccd was imported, and "
                                             f"pybullet does not report its {unknown}: BoxCCD takes pybullet's "
                                             "defaults (contactERP 0.08, erp 0.2, frictionERP 0.2, "
                                             "collisionFilterMode 1), and sets the ERPs back to those after its "
                                             "partial steps. Import "
                                             "bullet_boxccd before connecting, or set them again after importing it")
        if j.last_body > self._renewed_seen:
            self._forget_renewed(j)  # (before the bodies made anew are read, and named)
        if self.world.sync():
            self.stats.rediscoveries += 1
            t = self.world.tables
            self._sweep_reach = np.minimum(self.sweep_threshold * 2.0 * t.half.min(axis=1), self.sweep_distance)
            self._chains = Articulated(self.cid, t, self.world.self_collision(), self._sweep_reach, self._warn,
                                       self.world.journal.max_velocity)
            rigid_reach = self._sweep_reach.copy()
            rigid_reach[self._chains.boxes] = math.inf  # swept on their own paths (articulated)
            # A fixed maximal-coordinate body: pybullet neither moves it by a velocity the user
            # gives it nor lets its contacts see one.
            maximal = self.world.maximal
            at_rest = {f for f, (b, _) in enumerate(t.keys) if t.kind[f] == STATIC and maximal(b)}
            self._state = FrameState(self.cid, t, rigid_reach, self._chains.frames, self._not_finite,
                                     self._clamp_candidates.update, at_rest)
            self._others = Others(self.cid, self.world.journal, t.other_rigid, t.other_chains,
                                  [b for b in t.other_fixed if not maximal(b)], t.other_stuck, self._warn,
                                  self.world.damping)
            self._watched = bool(self._state.moving) or bool(self._chains.watched)
            moving = len(self._state.moving) + len(self._chains.frames)
            self._partial_steps = self.max_partial_steps if self.max_partial_steps is not None else \
                min(_PARTIAL_STEPS[1], max(_PARTIAL_STEPS[0], _PARTIAL_BODY_STEPS // max(moving, 1)))
            self._turn_limit = self._turn_limits(t)
            self._turning = set()  # (the frames are numbered anew)
            self._unswept = {k: v for k, v in t.unswept.items() if ("unswept", *k) not in self._warned}
            self._fast_unswept = self._loose_unswept(t)
            self._own_unswept = self._unswept_with_boxes(t)
            self._known = False
            self.stats.tracked_boxes = len(t.half)
            small = t.half.min() if len(t.half) else math.inf
            if self.penetration >= 0.1 * small:
                self._warn(("penetration", small), f"penetration = {self.penetration:g} m is not small against "
                                                  f"the thinnest tracked box (half extent {small:g} m)")
        if j.params > self._params_seen or j.reset > self._params_seen:
            params = raw.getPhysicsEngineParameters(physicsClientId=self.cid)
            self._dt, self._user_substeps = params["fixedTimeStep"], int(params.get("numSubSteps", 0))
            self._substeps = max(self._user_substeps, 1)
            self._gravity = np.array([params.get(f"gravityAcceleration{c}", 0.0) for c in "XYZ"])
            self._params_seen = max(j.params, j.reset)

    def _velocities_set(self):
        """Where the user set velocities or joint states since the last step, the velocities
        the step starts from are not those read after the last one: a free body's are read
        again now; an articulated body's start is not known; after restoreState, none is."""
        j, t, seen = self.world.journal, self.world.tables, self._moves_seen
        if j.last_move <= seen or not self._known:
            return
        if j.restored > seen or j.stepped > seen:
            self._known = False
            return
        changed = {b for b, s in j.velocity_set.items() if s > seen} | {b for b, s in j.moved.items() if s > seen}
        for b in changed & set(self._chains.bodies):
            self._chains.bodies[b].base_state = None
        frames = [f for b in changed - set(self._chains.bodies) for f in t.frames_of.get(b, ())]
        self._state.read_twists(frames)

    def _user_moves(self):
        """Static frames the user moved since the last step, those given a velocity, and
        every frame the user teleported."""
        j, t = self.world.journal, self.world.tables
        seen = self._moves_seen
        if j.last_move <= seen:
            return [], [], set()
        self._moves_seen = j.last_move
        jumps = joints_set_since(self.cid, seen)
        if jumps and j.restored <= seen and j.reset <= seen:
            self._name_joint_jumps(jumps, seen)
        if j.restored > seen:  # restoreState: every body jumped; no kinematic move is known
            self._state.read_poses(np.flatnonzero(t.kind == STATIC).tolist())
            return [], [], set(range(len(t.keys)))
        if j.stepped > seen:  # pybullet stepped the world directly: Bullet moved the frames with a velocity
            self._state.read_poses(sorted(self._state.with_velocity))
        moved = [f for b, s in j.moved.items() if s > seen for f in t.frames_of.get(b, ())]
        given = [f for b, s in j.velocity_set.items() if s > seen for f in t.frames_of.get(b, ())]
        free = set(self._state.moving)
        self._state.name_not_finite([f for f in moved if f in free])
        # (a joint reset moves a body's links, not its fixed base)
        bases = [f for b, s in j.base_moved.items() if s > seen for f in t.frames_of.get(b, ()) if t.kind[f] == STATIC]
        return bases, [f for f in given if t.kind[f] == STATIC], set(moved)

    def _name_joint_jumps(self, jumps, seen):
        """Name once each articulated body whose joints the user set between steps
        (resetJointState; ``jumps``: {body: {joint: position before}}, made after serial
        ``seen``) so that a link box moved through a free body's box: BoxCCD sweeps what a
        link does within a step, not such a set."""
        j, state = self.world.journal, self._state
        for b, joints in jumps.items():
            rec = self._chains.bodies.get(b)
            if rec is None or ("joint set", b) in self._warned or j.renewed.get(b, 0) > seen \
                    or j.base_moved.get(b, 0) > seen:
                continue
            hit = self._chains.jumped_into(rec, joints, self._dt, state.pose_of)
            if hit is not None:
                link, other, move = hit
                self._warn(("joint set", b), f"body {b}: a joint set by resetJointState between steps moved its "
                                             f"link {link} {move:.3g} m, through a box of body {other}: BoxCCD "
                                             "sweeps what a link does within a step, not a joint set between "
                                             "steps, so pybullet alone meets that box (pushes it out of the link, "
                                             "or lets the link pass it). Drive the joint (a motor, or its "
                                             "velocity) to have the link swept")

    # ------------------------------------------------------------- stepping
    def step(self) -> list:
        """``p.stepSimulation()``, swept, with partial steps from the contacts pybullet would
        resolve wrongly; returns this step's contacts. Raises ``ClientDisconnectedError`` if
        the client was disconnected."""
        try:
            events = self._step_once()
        except pybullet.error:
            self._clamp_candidates.clear()  # (what an interrupted step saw is not the next one's)
            self._chains.clamp_seen.clear()
            self._check_connected()
            raise
        j = self.world.journal
        j.impulses.clear()  # pybullet cleared the user's forces
        if self._fast_unswept and self._timed():
            self._name_fast_unswept()
        if j.last_over > self._over_seen:  # given a velocity above the clamp, which pybullet cut as it stepped
            for b, (serial, fastest) in j.over_clamp.items():
                clamp = j.max_velocity.get(b, MAX_VELOCITY)  # (the one this step had)
                if serial > self._over_seen and fastest > clamp:
                    self._name_clamp(b, clamp)
            self._over_seen = j.last_over
        return events

    def _check_connected(self):
        if self.world.journal.closed or not raw.getConnectionInfo(self.cid)["isConnected"]:
            again = raw.getConnectionInfo(self.cid)["isConnected"]
            raise ClientDisconnectedError(
                f"physics client {self.cid} was disconnected"
                + (" and a new world connected under its id: this BoxCCD's world is gone; make a new "
                   f"BoxCCD({self.cid}) for the new one" if again else " (p.disconnect)"))

    def _forget_renewed(self, j):
        """Forget what was said of the bodies removed or made since the last look: a new body
        under a removed one's id is named afresh."""
        renewed = {b for b, serial in j.renewed.items() if serial > self._renewed_seen}
        self._renewed_seen = j.last_body
        if renewed:
            self._warned -= {k for k in self._warned if len(k) > 1 and type(k[1]) is int and k[1] in renewed}

    def _step_once(self) -> list:
        struck, self._struck_next = self._struck_next, set()
        self._spent = 0
        if (self._quiet and last_serial() == self._epoch
                and raw.getNumBodies(physicsClientId=self.cid) == self.world.count):
            # Nothing changed in the world since the last step.
            self.stats.steps += 1
            if not self._watched:
                return self._pybullet_alone()
            n = self._step_pieces()
            events = self._quiet_step(self._dt, 0.0, self._dt, struck) if n == 1 else \
                self._substepped(struck, self._quiet_step, n)
        else:
            events = self._full_step(struck)
            self.stats.steps += 1
        # A world where no moving box can meet another is stepped by pybullet alone (its own
        # substeps too); one with a kinematic velocity otherwise takes the full path.
        self._quiet = not self._state.with_velocity and self._timed() and not self._alone
        self._epoch = last_serial()
        return events

    def _quiet_step(self, h, offset, dt, struck):
        """A (sub)step of h seconds (``offset`` into the user's step of dt) of a world nothing
        changed in since the last one: step, read the velocities (the one read per body
        pybullet's API forces), and stop there if nothing is fast."""
        st = self._state
        st.begin(self._known)
        raw.stepSimulation(physicsClientId=self.cid)
        self._known = True
        fast = st.fast(h, read=True) if st.moving else None
        if fast is None and (not self._chains.watched or self._chains.idle(h, st, self._unswept)):
            self._name_clamped()
            return []
        sw = None
        if not self._chains.bodies:
            # Free boxes only, and nothing the user moved: the sweep is all there is to
            # the step unless it finds a contact.
            st.begin_kinematic((), ())
            sw = sweep(self.cid, self.world.tables, st, h, self.fit_tolerance, self.tolerances, self.penetration,
                       self.stats, time.perf_counter(), fast, self._seen_fast,
                       self._near_unswept if self._unswept else None)
            if sw is None:
                self._name_clamped()
                return []
        return self._step(h, offset, dt, struck, stepped=True, fast=fast, sw=sw)

    def _full_step(self, struck):
        self._check_connected()
        self._sync()
        dt, n = self._dt, self._substeps
        if self._alone or not self._timed():
            return self._unswept_step(dt, n, struck)
        pieces = self._step_pieces()
        if pieces == 1:
            return self._step(dt, 0.0, dt, struck)
        if n == 1:
            return self._substepped(struck, self._step, pieces)
        if not self._watched and not self._state.with_velocity:
            return self._pybullet_alone()
        if self.world.journal.pd_control:
            self._warn(("pd",), "with numSubSteps > 1 BoxCCD takes the substeps itself: torques of PD_CONTROL and "
                                "STABLE_PD_CONTROL motors are computed again for each substep")
        damped = self._damped_body()
        if damped is not None:
            self._warn(("joint damping",), f"with numSubSteps > 1 BoxCCD takes the substeps itself: the joint damping "
                                           f"of body {damped} (and any other), which pybullet computes once a step "
                                           "from the joint velocities it starts with, is computed again for each "
                                           "substep, as a finer step computes it, so its joints move otherwise than "
                                           "in plain pybullet (far otherwise where the damping is strong for a "
                                           "link's inertia)")
        return self._substepped(struck, self._step, pieces)

    def _turn_limits(self, t):
        """Per frame, the largest turn (rad) it makes in one stepSimulation while it pivots on
        a contact: pybullet solves a contact once a stepSimulation, and a body turning by a
        about its centre of mass in one moves the point it pivots on off its pivot by about
        r a^2 / 2 (r: its reach), where a finer step holds that point down. The limit keeps
        that drift under _PIVOT_DRIFT of its thinnest half extent, and the turn under
        max_turn: a landing plank's end stays on the floor while it turns down
        (benchmarks/plank_landing.py)."""
        thin, reach = np.full(len(t.keys), np.inf), np.zeros(len(t.keys))
        np.minimum.at(thin, t.box_frame, t.half.min(axis=1))
        np.maximum.at(reach, t.box_frame, t.radius)
        limit = np.full(len(t.keys), self.max_turn)
        boxed = np.isfinite(thin)
        limit[boxed] = np.minimum(self.max_turn, np.sqrt(2.0 * _PIVOT_DRIFT * thin[boxed] / reach[boxed]))
        return limit

    def _step_pieces(self):
        """The stepSimulations the user's step is taken in: its numSubSteps, each split evenly
        so that no free body an impact set turning (``_turning``) that touches something as
        the step begins turns by more than its limit in one (``_turn_limits``), in at most
        the step's partial steps (``_spent``: what is left of them is the budget of its
        contacts). A body that turns by less is let go."""
        n = self._substeps
        self._forget_turning_set()
        if not self._turning:
            return n
        keys, pieces = self.world.tables.keys, 1
        for f in list(self._turning):
            turns = self._turns(f) * self._dt / n
            if not turns > 1.0:  # (not a number, too: let go)
                self._turning.discard(f)
            elif turns > pieces and raw.getContactPoints(keys[f][0], linkIndexA=keys[f][1], physicsClientId=self.cid):
                pieces = math.ceil(turns - 1e-9)
        pieces = min(pieces, 1 + self._partial_steps // n)
        self._spent = n * (pieces - 1)
        self.stats.pieces += self._spent
        return n * pieces

    def _forget_turning_set(self):
        """Drop from ``_turning`` the frames whose state the user set since the last step (all of
        them after restoreState): their spin is the user's, not an impact's."""
        if not self._turning:
            return
        j, seen = self.world.journal, self._moves_seen
        if j.last_move <= seen:
            return
        if j.restored > seen:
            self._turning.clear()
            return
        frames_of = self.world.tables.frames_of
        for b, serial in itertools.chain(j.moved.items(), j.velocity_set.items()):
            if serial > seen:
                self._turning.difference_update(frames_of.get(b, ()))

    def _substepped(self, struck, step, n):
        """The user's step taken as n stepSimulations (its numSubSteps, or more:
        ``_step_pieces``), each by ``step(h, offset, dt, struck)``."""
        dt = self._dt
        events = []
        with self._substepping(dt, n):
            for k in range(n):
                if k:  # pybullet cleared the user's forces after the last substep
                    replay_impulses(self.cid, self.world.journal.impulses)
                events += step(dt / n, k * dt / n, dt, struck)
                struck, self._struck_next = self._struck_next, set()
        self._struck_next = struck
        return events

    def _damped_body(self):
        """A body with a joint that has damping, or None: given through changeDynamics, else
        its file's (getJointInfo); read again when the world's bodies or a joint's damping
        changed."""
        j = self.world.journal
        key = (self.stats.rediscoveries, j.last_joint_damping)
        if self._damped[0] != key:
            cid, given = self.cid, j.joint_damping
            bodies = (raw.getBodyUniqueId(i, physicsClientId=cid) for i in range(raw.getNumBodies(physicsClientId=cid)))
            found = next((b for b in bodies for link in range(raw.getNumJoints(b, physicsClientId=cid))
                          if given.get((b, link), raw.getJointInfo(b, link, physicsClientId=cid)[6]) != 0.0), None)
            self._damped = (key, found)
        return self._damped[1]

    def _timed(self):
        """The world's step is a finite time > 0 (pybullet steps any other too)."""
        return math.isfinite(self._dt) and self._dt > 0.0

    def _unswept_step(self, dt, n, struck):
        """A step BoxCCD does not sweep, pybullet's alone: of no time (it moves nothing, and
        what the last step left stands), of a time below 0 or not finite (named once), and
        every step after one of those in a world with substeps or after one not finite
        (named once): pybullet's substep clock then owes the time it went back, or the
        world's state is not finite, which BoxCCD cannot follow, until resetSimulation."""
        if dt == 0.0 and not self._alone:
            raw.stepSimulation(physicsClientId=self.cid)
            self._struck_next = struck
            return []
        if not self._alone and (n > 1 or not math.isfinite(dt)):
            self._alone = True
            with_substeps = f" with numSubSteps = {n}" if n > 1 else ""
            self._warn(("alone",), f"the world's fixedTimeStep is {dt!r}{with_substeps}: after such a step pybullet's "
                                   "substep clock, or the world's state, is not one BoxCCD can follow, so pybullet "
                                   "takes this step and every later one alone, unswept, until p.resetSimulation")
        elif not self._alone:
            self._warn(("dt", repr(dt)), f"the world's fixedTimeStep is {dt!r}: BoxCCD sweeps steps of a finite time "
                                         "> 0 only, and pybullet takes this one alone (p.setTimeStep)")
        return self._pybullet_alone()

    def _pybullet_alone(self):
        """A step of pybullet alone (its own substeps too): no box that moves can meet another."""
        raw.stepSimulation(physicsClientId=self.cid)
        self._known, self._moves_seen = False, self.world.journal.last_move
        return []

    @contextmanager
    def _substepping(self, dt, n):
        """The world set to take one substep per stepSimulation, then back as the user had it."""
        raw.setPhysicsEngineParameter(fixedTimeStep=dt / n, numSubSteps=0, physicsClientId=self.cid)
        try:
            yield
        finally:
            raw.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=self._user_substeps, physicsClientId=self.cid)

    def _step(self, h, offset, dt, struck, stepped=False, fast=None, sw=None):
        """One stepSimulation of h seconds (``offset`` into the user's step of dt), swept,
        then the rest of it again from each contact the world is taken back to, until the
        step is done. ``struck``: frames the last step stopped at an impact (pybullet's
        solver meets it as this step begins). ``stepped``: pybullet took the step already,
        the velocities are read, ``fast`` are the fast boxes (``Sweeper.fast``; None:
        none) and ``sw`` their sweep, if it was taken already."""
        self._velocities_set()
        moved_static, with_velocity, user_moved = self._user_moves()
        t_start, elapsed, piece, events = time.perf_counter(), 0.0, h, []
        self._acted, self._struck, self._presses = set(), struck, {}
        self._pressed_again, hold, impacts = False, h, []
        try:
            k = 0
            while True:
                if sw is None:  # (a sweep taken already began the step's state)
                    self._state.begin_kinematic(moved_static, with_velocity)
                if not stepped:
                    self._state.begin(self._known)
                    self._simulate(impacts)
                    self._state.read_velocities()
                    if 0 < k and self._spent <= self._partial_steps:  # (not the very last piece: see below)
                        piece = self._within_clamp(piece, h, elapsed, impacts)
                t_sim = time.perf_counter()
                self.stats.seconds["step"] += t_sim - t_start
                back = self._spent < self._partial_steps
                found, tau = self._sweep(piece, t_sim, user_moved, back, stepped, fast, sw)
                stepped, fast, sw = False, None, None
                impacts = self.contacts.impacts if back and tau < 1.0 else []  # (the world went back to them)
                kind = self.world.tables.kind
                self._turning.update(f for pair in impacts for f in pair if kind[f] == FREE)
                events += [_shifted(e, offset + elapsed, dt) for e in found]
                elapsed += tau * piece
                if h - elapsed <= 1e-9 * h:
                    # (impacts pybullet resolves as the next step begins)
                    self._struck_next |= self.contacts.met | self._links_met
                    break
                # The world stands at ``elapsed``: simulate the rest from there, in pieces under
                # the turn limit and ``hold``. After max_partial_steps of them no contact takes the
                # world back again, and the rest goes to the step's end in one piece (after the
                # last piece an impact began, taken again shorter if it spun a body past the limit).
                moved_static, user_moved = [], set()
                # A link pair pressing in again after the world went back to it (a robot's landing
                # pybullet's solver cannot hold within a coarse step, an arm driving a box along
                # its face), or a free body and a link, was not held over this piece:
                # the next are half as long; after a piece in which none was, twice as long again
                # (up to the step), as an adaptive step takes it.
                if self._pressed_again:
                    hold = 0.5 * piece
                    self._pressed_again = False
                else:
                    hold = min(2.0 * hold, h)
                piece = self._piece(h - elapsed, hold) if back else h - elapsed
                self.stats.partial_steps += 1
                self._spent += 1
                self._take(piece, h, elapsed)
                t_start = time.perf_counter()
                k += 1
        finally:
            if self._partial:
                if self._motors:
                    self._motors_back()
                j = self.world.journal
                raw.setPhysicsEngineParameter(fixedTimeStep=h, contactERP=j.contact_erp, erp=j.erp,
                                              frictionERP=j.friction_erp, physicsClientId=self.cid)
                self._partial = False
        self._name_clamped()
        return events

    def _simulate(self, impacts):
        """``stepSimulation``, resolving ``impacts`` (pairs of frames met inside the step,
        which the world was just taken back to) as pybullet's converged physics does. At a
        step of h, pybullet's solver adds to a contact's rebound its position correction,
        contact ERP x the overlap it first sees the contact at / h; at a fine step a touch
        falls at a uniform phase of the step, so the overlap is phase x approach speed x h,
        and the converged engine's rebound is its restitution plus ERP x phase of the
        approach speed: ERP / 2 more on average (4 % of the approach speed with the default
        ERP of 0.08, whatever the step). The world went back to the touch, where that
        overlap is nil, so for this solve the pair's combined restitution (the product of
        its bodies') is raised by ERP / 2: each body's set to sqrt(e_a e_b + ERP / 2), then
        put back. A body has one restitution for all its contacts: one whose pairs want
        different values (a wall struck at once by boxes of different restitutions) keeps
        its own, and so do its partners in them. Not for a pair with a maximal-coordinate
        body either: pybullet's solve treats it alike, but in crowds of such bodies the
        raised solves left more boxes standing still against walls and deep in them (see
        docs/design.md). Such impacts are resolved from the touch."""
        cid, lift = self.cid, 0.5 * self.world.journal.contact_erp
        keys, maximal = self.world.tables.keys, self.world.maximal
        pairs = [(keys[fa], keys[fb]) for fa, fb in impacts if not maximal(keys[fa][0]) and not maximal(keys[fb][0])] \
            if lift > 0.0 else []
        if not pairs:
            raw.stepSimulation(physicsClientId=cid)
            return
        own = {k: raw.getDynamicsInfo(*k, physicsClientId=cid)[5] for k in {k for pair in pairs for k in pair}}
        want = {k: set() for k in own}
        for a, b in pairs:
            e = math.sqrt(own[a] * own[b] + lift)
            want[a].add(e)
            want[b].add(e)
        raised = {k: next(iter(want[k])) for pair in pairs if all(len(want[k]) == 1 for k in pair) for k in pair}
        try:
            for (b, link), e in raised.items():
                raw.changeDynamics(b, link, restitution=e, physicsClientId=cid)
            raw.stepSimulation(physicsClientId=cid)
        finally:
            for b, link in raised:
                raw.changeDynamics(b, link, restitution=own[b, link], physicsClientId=cid)

    def _take(self, piece, h, start):
        """Set the world to take a partial step of ``piece`` seconds from ``start`` into the
        user's step of h: its ERPs scaled by piece / h, so that the speed at which pybullet's
        solver pushes an overlap out, or brings a constraint, a joint limit or a friction
        anchor back to where it holds (ERP times the error over the step), is the user's
        step's, not larger by h / piece (a box a constraint held 0.1 m off its pivot was
        pulled at the velocity clamp in the partial step of an impact elsewhere); the
        user's forces, which pybullet cleared, given again; and the user's position motors
        given again so that each asks for the velocity it asked for over the step.
        pybullet's position motor drives its joint at gain x error / step (a tenth of the
        step: ten times as fast), and fixes its largest impulse at force x step when the
        command is given: a joint that followed the step's motion from its start is at
        error x (1 - gain x s) a share s into it, so the gain is scaled by (piece / h) / (1 -
        gain x s) (by piece / h where that is not above 0), the force by the user's step /
        piece."""
        self._partial = True
        cid = self.cid
        j = self.world.journal
        raw.setPhysicsEngineParameter(fixedTimeStep=piece, contactERP=j.contact_erp * piece / h, erp=j.erp * piece / h,
                                      frictionERP=j.friction_erp * piece / h, physicsClientId=cid)
        self._motors = position_motors(cid)
        s = start / h
        for (b, joint), kw in self._motors.items():
            gain = kw.get("positionGain", _POSITION_GAIN)
            left = 1.0 - gain * s
            raw.setJointMotorControl2(b, joint, pybullet.POSITION_CONTROL, physicsClientId=cid, **dict(
                kw, positionGain=gain * piece / h / (left if left > 1e-6 else 1.0),
                force=kw.get("force", _MOTOR_FORCE) * self._dt / piece))
        replay_impulses(cid, self.world.journal.impulses)

    def _motors_back(self):
        """The user's position motors given again as the user gave them, at the user's step
        (which fixes their largest impulse), once a step taken in partial steps is done."""
        cid = self.cid
        raw.setPhysicsEngineParameter(fixedTimeStep=self._dt, physicsClientId=cid)
        for (b, joint), kw in self._motors.items():
            raw.setJointMotorControl2(b, joint, pybullet.POSITION_CONTROL, physicsClientId=cid, **kw)
        self._motors = {}

    def _piece(self, rest, hold):
        """The next partial step's length: the rest of the step, or an even share of it, so
        that no body of the contact the world was taken back to turns by more than its limit
        in it (``_turn_limits``: at most ``max_turn``, under Bullet's clamp of pi/4 a step:
        above it, the turn Bullet integrates is slower than the spin its contact solver
        sees, and a spinning box would press on into what it strikes), and that no piece is
        longer than ``hold``."""
        turns = self._turn_rate() * rest
        n = max(math.ceil(turns - 1e-9) if turns > 1.0 else 1, math.ceil(rest / hold - 1e-9))
        return rest / n

    def _turn_rate(self):
        """The fastest turn of the frames of the contact the world was taken back to, in
        their turn limits a second."""
        return max((self._turns(f) for f in self._acted), default=0.0)

    def _turns(self, f):
        """Frame f's spin, in its turn limits (``_turn_limits``) a second."""
        x, y, z = self._state.rows[f, ANGULAR_VELOCITY].tolist()
        return math.sqrt(x * x + y * y + z * z) / self._turn_limit[f]

    def _within_clamp(self, piece, h, start, impacts):
        """After a partial step of ``piece`` seconds: if the impact at its start spun a body of
        the contact past its turn limit in it, the world goes back to the partial step's
        start (every body where its path has it then, with the velocities it started with)
        and takes a partial step short enough for that spin, once (its velocities read; the
        ``impacts`` it began with resolved again as ``_simulate`` does; ``start``: when it
        began, seconds into the step of h). Returns its length."""
        st = self._state
        turns = self._turn_rate() * piece
        if turns <= 1.0 + 1e-9 or st.twist0 is None:
            return piece
        self._chains.read(piece, st, True)
        self.contacts.world_to_start(self.world.tables, st, piece)
        self._chains.stop_all(0.0, st)
        self._others.back(piece, 0.0, self._gravity)
        piece /= math.ceil(turns)
        self._take(piece, h, start)
        st.begin(True)
        self._simulate(impacts)
        st.fresh = set()  # the poses read or placed before this step are not its end
        st.read_velocities()
        self.stats.partial_steps += 1
        return piece

    def _sweep(self, h, t0, user_moved, back, stepped=False, fast=None, sw=None):
        """Sweep the (partial) step of h seconds just taken (the moving frames' velocities
        read) and resolve its contacts: with
        ``back``, the world goes back to the earliest contact pybullet would resolve
        wrongly (returns (events, its time)); without, each such contact's bodies go back
        on their own (returns (events, 1))."""
        t = self.world.tables
        self.contacts.met, self._links_met = set(), set()
        if not len(t.half):
            return [], 1.0
        st = self._state
        self._chains.read(h, st, self._known)
        self._known = True
        st.end_kinematic(h, self.world.journal.contact_erp)
        if sw is None and not (stepped and fast is None):
            sw = sweep(self.cid, t, st, h, self.fit_tolerance, self.tolerances, self.penetration, self.stats, t0, fast,
                       self._seen_fast, self._near_unswept if self._unswept else None)
        jw = jump_sweep(self.cid, t, st, h, self.fit_tolerance, self.tolerances, self.penetration, self.stats,
                        self._near_unswept if self._unswept else None)
        found = self._chains_find(h)
        if sw is None and jw is None and not found:
            return [], 1.0
        # A link's contact met inside the step and left to pybullet that ends it overlapping is
        # an impact pybullet resolves as the next step begins, as a free pair's (``contacts.met``).
        self._links_met = {x for touch, act, _, initial, _, _, f, g, (a, b) in found
                           if act is None and not initial and _core.paths_depth(a, b, 1.0) >= 0.0
                           for x in (f, g)}
        t3 = time.perf_counter()
        if back:
            # One time order: the free bodies' contacts up to the earliest articulated one
            # that needs the world back; the world then goes back to the earlier of the two.
            # A link pair (or a free body and a link) pressing in again after the world went
            # back to it is one pybullet's solver did not hold over that piece: the next pieces
            # are half as long (``_step``).
            tau_links, links_acted = self._chains.act_at(found)
            events, tau = self.contacts.resolve(sw, jw, t, st, h, user_moved, self._gravity, True, tau_links,
                                                self._struck, self._presses, jump_time=self._dt)
            if tau < 1.0:
                self._chains.stop_all(tau, st, self._struck)
                self._others.back(h, tau, self._gravity)
                if self.contacts.acted:
                    self._acted, self._struck = self.contacts.acted, self.contacts.struck
                    self._pressed_again = self.contacts.link_pressed_again
                else:
                    # A link's impact on a free body (met inside the step) is struck as a free
                    # pair's is: its bodies keep its impulse whole where the world goes back
                    # within the partial step it begins. A press is not, nor a robot's landing on
                    # what does not move (kept whole, its motors' and joints' solve pumps it).
                    first = min((x for x in found if x[1] == tau_links), key=lambda x: x[0])
                    impact = not first[3] and t.kind[first[7]] == FREE
                    self._acted, self._struck = links_acted, links_acted if impact else set()
                    if first[3]:
                        key = (first[6], first[7])
                        self._presses[key] = self._presses.get(key, 0) + 1
                        self._pressed_again = self._presses[key] > 1
                self.stats.rewinds += 1
            events = self._chains.events(found, tau, tau if tau < 1.0 else None) + events
        else:
            # Articulated bodies first, on Bullet's paths of everything (their stops change
            # no free body's path); then the free bodies' contacts, less those of free boxes
            # a link pushed (their paths are no longer Bullet's).
            events = self._chains.events(found)
            _, pushed = self._chains.stop_each(found, st, h, self.stats)
            more, tau = self.contacts.resolve(_without(sw, pushed, t), jw, t, st, h, user_moved, self._gravity,
                                              False, struck=self._struck, jump_time=self._dt)
            self._struck_next = self.contacts.struck | self._links_met
            events += more
        self.stats.seconds["rewind"] += time.perf_counter() - t3
        self.stats.contacts += len(events)
        return sorted(events, key=lambda e: e.tau), tau

    def _loose_unswept(self, t):
        """Bodies with no box that moves whose base is free (a single body, or one with links
        on a base of mass), with shapes left to pybullet, not yet named as fast: {body: (half
        the smallest extent of those shapes, what they are)}. A shape whose size pybullet
        does not report (a mesh) counts as its link's bounding box."""
        left = {}  # body -> {link: what} of its shapes left to pybullet
        for (b, link), what in t.unswept.items():
            left.setdefault(b, {})[link] = what
        out = {}
        for b in t.other_rigid + [b for b in t.other_chains if not self.world.fixed_base(b)]:
            if b in left and ("fast unswept", b) not in self._warned:
                half = min(self._smallest_extent(t, (b, link)) for link in left[b]) / 2.0
                out[b] = (half, ", ".join(sorted(set(left[b].values()))))
        return out

    def _unswept_with_boxes(self, t):
        """Free frames with shapes left to pybullet beside their boxes, not yet named: {frame:
        (half the smallest extent of those shapes, what they are)}."""
        return {f: (self._smallest_extent(t, t.keys[f]) / 2.0, t.unswept[t.keys[f]]) for f in t.free_frames
                if t.keys[f] in t.unswept and ("own unswept", *t.keys[f]) not in self._warned}

    def _smallest_extent(self, t, key):
        """The smallest extent of the shapes of frame key (body, link) left to pybullet; of its
        bounding box where pybullet does not report a shape's size (a mesh)."""
        known = t.unswept_thickness[key]
        sizes = [s for s in known if s is not None]
        if None in known:
            lo, hi = raw.getAABB(*key, physicsClientId=self.cid)
            sizes.append(min(y - x for x, y in zip(lo, hi)))
        return min(sizes)

    def _name_fast_unswept(self):
        """Free bodies with no box whose base moved farther in the (sub)step just taken than
        half the smallest extent of their shapes (far enough to cross a shape of no
        thickness): named once each."""
        h = self._dt / self._substeps
        for b, (half, what) in list(self._fast_unswept.items()):
            move = math.hypot(*raw.getBaseVelocity(b, physicsClientId=self.cid)[0]) * h
            if move > half:
                del self._fast_unswept[b]
                self._warn(("fast unswept", b),
                           f"body {b} ({what}) moves {move:.3g} m a step, more than half the smallest extent of its "
                           f"shapes ({half:.3g} m): BoxCCD sweeps boxes only, so pybullet alone meets its contacts "
                           "and it can pass through what it meets")

    def _seen_fast(self, frames):
        """The frames a sweep found fast, their velocities after pybullet's (partial) step
        read: candidates for the velocity clamp's warning (``_name_clamped``), and for
        ``_name_own_unswept``."""
        self._clamp_candidates.update(frames)
        if self._own_unswept:
            self._name_own_unswept(frames)

    def _name_own_unswept(self, frames):
        """Of fast free frames, those with shapes left to pybullet beside their boxes that
        move farther in a step than half the smallest extent of those shapes: named once
        each (the world going back to a contact of the boxes can leave such a shape inside
        what it passed)."""
        h, keys = self._dt / self._substeps, self.world.tables.keys
        for f in sorted(set(frames).intersection(self._own_unswept)):
            half, what = self._own_unswept[f]
            x, y, z = self._state.rows[f, VELOCITY].tolist()
            move = math.sqrt(x * x + y * y + z * z) * h
            if move > half:
                del self._own_unswept[f]
                b, link = keys[f]
                self._warn(("own unswept", b, link),
                           f"body {b} link {link} ({what}) moves {move:.3g} m a step with its boxes, more than half "
                           f"the smallest extent of its shapes that are not boxes ({half:.3g} m): BoxCCD sweeps "
                           "boxes only, so those shapes can pass through what they meet, and where the world goes "
                           "back to a contact of the boxes they can be left inside it")

    def _near_unswept(self, keys):
        """Shapes left to pybullet that a fast box came near: named once each."""
        for key in keys:
            what = self._unswept.pop(key, None)
            if what is not None:
                b, link = key
                self._warn(("unswept", b, link), f"body {b} link {link} ({what}) is in the reach of a fast box: "
                                                  "BoxCCD sweeps boxes against boxes only, so pybullet alone meets "
                                                  "that contact and the box can pass through it")

    def _not_finite(self, frames):
        """Frames whose state pybullet left not finite: their bodies named once each."""
        for f in frames:
            b = self.world.tables.keys[f][0]
            self._warn(("not finite", b), not_finite_message(b))

    def _clamped(self, frames):
        """Those of the free frames whose velocity or spin pybullet's velocity clamp cut in the
        (partial) step just taken: a component of it, read after the step, at the body's
        clamp (its maxJointVelocity; a body in maximal coordinates has none)."""
        w = self.world
        out = set()
        for f in frames:
            b, link = w.tables.keys[f]
            clamp = w.velocity_clamp(b) if link == -1 else None
            if clamp is not None:
                out.update(self._state.sweeper.at_speed([f], clamp, 1e-9))
        return out

    def _name_clamped(self):
        """Of the frames swept as fast or read at the clamp in the (sub)step just ended, those
        whose velocity or spin pybullet's default velocity clamp holds where it leaves the
        world (a component at it: pybullet cuts each on its own): their bodies named once
        each; and so for joints. (A pybullet step the world went back from is not the world
        the user gets.)"""
        if self._chains.clamp_seen:
            self._chains.name_clamped(self._name_clamp)
        if not self._clamp_candidates:
            return
        frames = sorted(self._clamp_candidates)
        self._clamp_candidates.clear()
        w, by_clamp = self.world, {}
        for f in frames:
            clamp = w.velocity_clamp(w.tables.keys[f][0])
            if clamp is not None:
                by_clamp.setdefault(clamp, []).append(f)
        for clamp, group in by_clamp.items():
            for f in self._state.sweeper.at_speed(group, clamp, 1e-9):
                self._name_clamp(w.tables.keys[f][0], clamp)

    def _name_clamp(self, b, clamp=MAX_VELOCITY):
        """Name body b at its velocity clamp ``clamp``, unless pybullet does not clamp it
        there: in maximal coordinates, or with its clamp changed to another
        (changeDynamics(maxJointVelocity=...))."""
        if self.world.velocity_clamp(b) != clamp:
            return
        if clamp == MAX_VELOCITY:
            self._warn(("clamp", b), f"body {b} moves or turns at {MAX_VELOCITY:g} (m/s, rad/s) along a world axis, "
                                     "pybullet's default velocity clamp: if it was given more, pybullet cut it to "
                                     f"that (p.changeDynamics({b}, -1, maxJointVelocity=...) lifts it)")
        else:
            self._warn(("clamp", b), f"body {b} moves or turns at {clamp:g} (m/s, rad/s) along a world axis, the "
                                     "velocity clamp it was given (maxJointVelocity): pybullet cuts each component "
                                     "of its velocity and spin to that")

    def _chains_find(self, h):
        if not self._chains.bodies:
            return []
        t0 = time.perf_counter()
        found = self._chains.find(h, self._state, self.fit_tolerance, self.tolerances,
                                  self.penetration, self.stats, self._near_unswept if self._unswept else None,
                                  (self.depth_tolerance, self.contacts.box_impact_depth))
        self.stats.seconds["solve"] += time.perf_counter() - t0
        return found

    # --------------------------------------------------------- declarations
    def register_box(self, body: int, link: int, half_extents, position=(0.0, 0.0, 0.0),
                     orientation=(0.0, 0.0, 0.0, 1.0)) -> None:
        """Declare a box on a frame whose shapes cannot be read (BoxCCD warns which).
        ``position``/``orientation`` place the box in the link's centre-of-mass frame, as
        ``getCollisionShapeData`` would."""
        body, link = _body_link(self.cid, body, link)
        half = as_float_array("half_extents", half_extents, (3,), finite=True)
        if not np.all(half > 0):
            raise InvalidInputError(f"half_extents is {half.tolist()}; expected three numbers > 0")
        pos = as_float_array("position", position, (3,), finite=True)
        q = as_float_array("orientation", orientation, (4,), finite=True)
        if not np.dot(q, q) > 0:
            raise InvalidInputError("orientation is (0, 0, 0, 0); expected a quaternion (x, y, z, w)")
        if self.world.frame_readable(body, link):
            raise InvalidInputError(f"body {body} link {link}: its shapes are readable; register_box is for "
                                    "frames whose boxes BoxCCD cannot read")
        X = pose_matrix(pos, q)
        for h, X_old in self.world.registered.get((body, link), (0, []))[1]:
            if np.array_equal(h, half) and np.array_equal(X, X_old):
                raise InvalidInputError(f"body {body} link {link}: this box is registered already")
        self.world.register(body, link, (half, X))
        self._sync()

    def set_collision_filter_pair(self, body_a: int, body_b: int, link_a: int, link_b: int, enable: bool) -> None:
        """``p.setCollisionFilterPair`` (which BoxCCD also sees when called directly)."""
        body_a, link_a = _body_link(self.cid, body_a, link_a)
        body_b, link_b = _body_link(self.cid, body_b, link_b)
        # pybullet's (wrapped) function, not raw's, so that the journal records the rule
        pybullet.setCollisionFilterPair(body_a, body_b, link_a, link_b, int(_flag("enable", enable)),
                                        physicsClientId=self.cid)

    def summary(self) -> str:
        """What is tracked, and what is left to pybullet."""
        return self.world.summary()


# ------------------------------------------------------------------ checks
def _client(cid):
    if isinstance(cid, bool) or not isinstance(cid, numbers.Integral) or not 0 <= cid < 2 ** 31:
        raise InvalidInputError(f"physics_client_id is {cid!r}; expected an int >= 0 (p.connect's result)")
    if not raw.getConnectionInfo(int(cid))["isConnected"]:
        raise InvalidInputError(f"physics_client_id is {cid!r}; it is not connected (p.connect)")
    return int(cid)


def _number(name, value, low, high, open_low=False):
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InvalidInputError(f"{name} is {value!r}; expected a number")
    v = float(value)
    if not (math.isfinite(v) and (v > low if open_low else v >= low) and v <= high):
        span = f"{'(' if open_low else '['}{low:g}, {high:g}]"
        raise InvalidInputError(f"{name} is {value!r}; expected a finite number in {span}")
    return v


def _flag(name, value):
    if not isinstance(value, (bool, np.bool_)):
        raise InvalidInputError(f"{name} is {value!r}; expected True or False")
    return bool(value)


def _count(name, value):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise InvalidInputError(f"{name} is {value!r}; expected an int >= 0")
    return int(value)


def _body_exists(cid, b):
    return any(raw.getBodyUniqueId(i, physicsClientId=cid) == b for i in range(raw.getNumBodies(physicsClientId=cid)))


def _bodies(cid, bodies, name):
    try:
        bodies = list(bodies)
    except TypeError:
        raise InvalidInputError(f"{name} is {bodies!r}; expected body ids (a list, tuple or set of ints)") from None
    out = set()
    for b in bodies:
        if isinstance(b, bool) or not isinstance(b, numbers.Integral) or not _body_exists(cid, int(b)):
            raise InvalidInputError(f"{name}: {b!r} is not a body of physics client {cid}")
        out.add(int(b))
    return out


def _body_link(cid, body, link):
    (body,) = _bodies(cid, [body], "body")
    if isinstance(link, bool) or not isinstance(link, numbers.Integral) or not (
            -1 <= link < raw.getNumJoints(body, physicsClientId=cid)):
        raise InvalidInputError(f"link {link!r} is not a link of body {body} (-1 is the base)")
    return body, int(link)


def _without(sw, frames, tables):
    """The sweep without the contacts of ``frames`` (free boxes an articulated body's link
    pushed: their paths are no longer Bullet's); None if none is left."""
    if sw is None or not frames:
        return sw
    box_frame = tables.box_frame[sw.boxes]
    sw.hits = [h for h in sw.hits if box_frame[h[0]] not in frames and box_frame[h[1]] not in frames]
    return sw if sw.hits else None


def _shifted(e: CCDEvent, elapsed: float, dt: float) -> CCDEvent:
    """An event of a partial step or substep, timed from the start of the whole step."""
    if not elapsed:
        return e
    t = e.time + elapsed  # (dataclasses.replace costs several times this)
    return CCDEvent(e.body_a, e.link_a, e.body_b, e.link_b, t / dt, t, e.point, e.normal, e.feature, e.rewound,
                    e.initial)
