"""The step's contacts, in one time-ordered pass: which ones pybullet's own solver
resolves as they are, and, for the others, the time the world is taken back to.

pybullet resolves a pair from where its step leaves it. That is the engine's answer
when the pair touched as the step began (its solver saw the contact), or when the pair
meets during the step and ends it barely overlapping (the next step sees it, as a fine
step would). It goes wrong when a box meets its partner inside the step and ends the
step deep in it or past it: the rebound then comes from the overlap, not from the
impact (a deep overlap is pushed out along its least axis, a body gone past the middle
is pushed out the far side, and one that went through is never seen). For every
contact the sweep found (the first touch, on conservatively fitted motions), the pair's
state at the end of the step decides:

* Left to pybullet: the pair touched when the window began and ends less than
  ``depth_tolerance`` deeper without going wrong, or it met inside the window and ends
  it overlapping by less than ``depth_tolerance`` on the right side, no shallower than
  it was on the way (a turning box's corner that dipped in and is leaving would be seen
  leaving); in either case without going past the thinner box's middle on the way
  (``_core.judge_contact``). Such an impact, met inside the step, is pybullet's as the
  next step begins: its bodies are struck there (below).
* Otherwise the world is taken back to the time the pair first overlaps by the impact
  depth on Bullet's own path (``impact_depth``, at most a quarter of the thinner box's
  smallest half extent: Bullet's box-box detector then sees every corner of an edge or
  face arriving within it, as at a fine step; against a plane, whose contact takes one
  point, ``penetration``), a pair already touching by a creep more than it began with,
  and ``BoxCCD`` simulates the rest of the step from there, so that pybullet's solver
  sees the contact as it begins. Every free body goes where its path has it at that
  time, with the velocity it had there. A pair touching as a window began at its impact
  whose other corner strikes (one that was apart then reaches the impact depth before
  the pair presses in by the creep) is an impact of its own, not a press: the next
  corner of a turning box. Impacts that reach their impact depth while the first is
  still shallower than a quarter of the thinner box's half extent go back with it, to
  the latest of their times: one partial step resolves them all, each from an overlap at
  which pybullet's position correction adds less than it can at a fine step (contact ERP
  times the depth over the step, at most ERP times the approach speed), where a crowd
  would otherwise spend a partial step on each.
* A pair still pressing in after the world went back to it twice in the step, and every
  such pair once the step's partial steps are used up (``max_partial_steps``), stops on
  its own at that time instead, with its velocity there; pybullet resolves it as the
  next step begins, where a pair stopped at an impact is struck (its impulse acts whole
  then, as for the pair a partial step begins at). Where Bullet clamps the turn of a body
  of a pair that was touching as the window began, pybullet's solver sees the whole spin
  and would never resolve the contact: the pair's centres of mass are parted as it stops
  (``Contacts._part``). A body stops earlier where its path
  takes it by then more than ``depth_tolerance`` deeper into a box it was left to pybullet
  with (a turning box's corner dipping into a face and out again by the step's end).
* A body's velocity where the world goes back to is in proportion between its velocities
  before and after the (partial) step, as the rest of the step adds its share of the
  solve again; but whole (after the step, less the rest's gravity) for a pair that the
  step began at an impact of, and for a pair pressing in while touching whose solve
  pybullet's velocity clamp cut: the clamp cuts the next solve from the same velocities,
  and only kept do successive solves take its approach, as a fine step's do. A body
  stopped against another free body keeps its whole too, and so does every free body the
  solve pushed on through one kept whole (``_Solve``): an impulse acts on both bodies
  alike.

Kinematic bodies (a fixed base the user teleports) cannot be taken back: a free body a
teleport swept into is carried with it from the touch and leaves with the velocity of
a collision with an immovable body moving as the kinematic one did: without restitution
(pybullet gives a body it only teleports no velocity to rebound from, and at a fine step
pushes what it moves into out of the overlap at its speed), with the pair's combined
restitution where the user gave it a velocity too, and where a body riding with it
strikes another (a row pushed). Changing one body's path can make it meet another: the
contacts are taken in time order, and every pair of a body whose path changed is swept
again from the change on, as in Box2D's time-of-impact loop.
"""

from __future__ import annotations

import heapq
import itertools
import math
from dataclasses import dataclass

import numpy as np

from .. import _core
from ..motion import axis_angle_matrix, pose7, pose_matrix
from ..solver import Outcome
from ._hooks import journal, raw
from .events import CCDEvent
from .layout import ANGULAR_VELOCITY, PATH_ROW, POSE, VELOCITY
from .shapes import PLANE_HALF
from .sweep import CREEP, ride_near
from .world import FREE, LINK, MAXIMAL_TYPE, restitution

__all__ = ["Contacts", "place", "bounce"]

_MOVING, _STOPPED, _CARRIED = 0, 1, 2
# Times in a step the world goes back to a pair that was touching and pressed in anyway.
PRESSES = 2
# The window (a step fraction) before a contact's touch that the reported contact is solved
# over: short enough that one fit's allowance is far below the boxes' approach in it.
_EVENT_WINDOW = 1e-6

# Impacts that begin while an earlier one of the step overlaps by less than this fraction of
# the thinner box's half extent (at that depth pybullet's box contact still pushes out along
# the face the box came through), and by less than COALESCE_CAP times the impact depth, are
# taken back to together: the earlier one is resolved from that overlap (a cube struck into a
# pile, joined by the slow impacts of the cubes it pushes, was resolved from 1 cm deep).
COALESCE = 0.25
COALESCE_CAP = 4.0
# An impact is resolved from an overlap of at most this fraction of the thinner box's half
# extent: far from its middle, where pybullet's box contact would push it on through, and
# deep enough that a face pybullet's coarse sliding contact tipped (about 6 mrad after 10
# sliding steps at 240 Hz: 0.6 mm across a 0.1 m face) strikes a 1 cm wall whole.
IMPACT_SHARE = 0.25
_IDENTITY = np.eye(4).reshape(-1)


@dataclass
class _Track:
    """One frame of a sweep on its effective path through the step: Bullet's, stopped at
    a time, or carried from a time by another frame's motion."""

    rows: list  # its path rows in the sweep
    status: int = _MOVING
    version: int = 0  # bumped at each change of path (a queued contact of an older path is stale)
    since: float = 0.0  # when its path last changed (tau)
    stop_time: float = 1.0
    frozen: np.ndarray = None  # (4, 4) centre-of-mass pose once stopped
    carry: tuple = None  # (carrier's frame row (42,), CoM in the carrier's frame (4, 4)) once carried
    carrier: int = -1  # the frame that carries it
    velocity: tuple = None  # (v, w) it leaves the step with, where the plugin changed them


class _Solve:
    """Which free frames pybullet's solver pushed on each other in the (partial) step just
    taken: its contacts that bore a force, between free frames (read once asked for).

    The solve's impulses all act as the step begins, an impulse between two bodies on both
    alike. Where the plugin gives a body its velocity after the step whole (struck by the
    impact the step began at, or stopped against another free body), every body it pushed
    on in the solve, and every body those pushed on, keeps its whole too: a body whose
    impulse from a struck one is kept whole while its own is kept in share (a struck cube
    at the head of a row, the cube behind it pressing on) leaves the pair with momentum
    that no force gave it."""

    def __init__(self, cid, tables):
        self.cid, self.tables, self._partners = cid, tables, {}

    def partners(self, f) -> set:
        """The other free frames a contact of frame f bore a force with."""
        out = self._partners.get(f)
        if out is None:
            t, out = self.tables, set()
            if t.kind[f] == FREE:
                b, link = t.keys[f]
                for c in raw.getContactPoints(bodyA=b, linkIndexA=link, physicsClientId=self.cid):
                    if c[9] > 0.0:
                        out.update(g for g in t.frames_of.get(c[2], ()) if t.keys[g][1] == c[4] and g != f
                                   and t.kind[g] == FREE)
            self._partners[f] = out
        return out

    def through(self, frames) -> set:
        """``frames`` and every free frame reached from them over ``partners``."""
        out, todo = set(frames), list(frames)
        while todo:
            for g in self.partners(todo.pop()):
                if g not in out:
                    out.add(g)
                    todo.append(g)
        return out


class _Paths:
    """The frames of a sweep on their effective paths (``_Track``). Rows are the sweep's
    path rows, rewritten as paths change; all are over the whole step (tau in [0, 1]),
    valid from the frame's last change on."""

    def __init__(self, sw, tables, state, dt, kinematic, struck, gravity, solve):
        self.tables, self.state, self.dt = tables, state, dt
        self.struck, self.gravity, self.solve = struck, gravity, solve
        self._kept = None  # the frames kept whole with the struck ones, once asked for
        self.rows = sw.rows.copy()
        self.box = sw.boxes
        self.frame = tables.box_frame[sw.boxes]
        self.pairs = sw.pairs
        half = tables.half[self.box]
        self.thin = half.min(axis=1).tolist()  # each row's box's smallest half extent
        self.plane = (half.max(axis=1) >= PLANE_HALF).tolist()  # each row's box stands for a plane
        self.track = {}  # in the order of the frames' first rows (the order pybullet is given their bodies)
        for r, f in enumerate(self.frame.tolist()):
            tr = self.track.get(f)
            if tr is None:
                self.track[f] = _Track([r])
            else:
                tr.rows.append(r)
        self._by_frame = None  # the pairs' indices grouped by frame, once pairs_of is asked
        self.kinematic = kinematic

    def pairs_of(self, f):
        """Indices of the pairs with a box of frame f, ascending."""
        if self._by_frame is None:  # each pair under both its frames
            pf = self.frame[self.pairs]
            two = pf[:, 0] != pf[:, 1]
            keys = np.concatenate((pf[:, 0], pf[two, 1]))
            index = np.concatenate((np.arange(len(pf)), np.flatnonzero(two)))
            order = np.lexsort((index, keys))
            self._by_frame = keys[order], index[order]
        keys, index = self._by_frame
        lo, hi = np.searchsorted(keys, [f, f + 1])
        return index[lo:hi]

    def driver(self, f):
        """The kinematic frame that moves f (f itself, or its carrier's driver)."""
        while f in self.track and self.track[f].carrier >= 0:
            f = self.track[f].carrier
        return f

    def status(self, f):
        tr = self.track.get(f)
        return _MOVING if tr is None else tr.status

    def pushes(self, f) -> bool:
        """f moves on regardless: a kinematic frame, or one carried by it."""
        return f in self.kinematic or self.status(f) == _CARRIED

    def drives(self, f) -> bool:
        """f moves on along its path whatever this pass does to the free bodies: a kinematic
        frame, one carried by it, or a link (an articulated body is stopped by its own pass)."""
        return self.pushes(f) or self.link(f)

    def link(self, f) -> bool:
        return bool(self.tables.kind[f] == LINK)

    def free(self, f) -> bool:
        """A free body that the plugin may stop or push (not carried already)."""
        return bool(self.tables.kind[f] == FREE) and f not in self.kinematic and self.status(f) != _CARRIED

    def stoppable(self, f) -> bool:
        return self.free(f) and self.status(f) == _MOVING

    def twist(self, f):
        """(v, w) of frame f from now on (what it leaves the step with)."""
        tr = self.track.get(f)
        if tr is not None and tr.velocity is not None:
            return tr.velocity
        row = self.state.rows[f]
        return row[VELOCITY].copy(), row[ANGULAR_VELOCITY].copy()

    def com(self, f, tau) -> np.ndarray:
        """(4, 4) centre-of-mass pose of frame f at tau on its effective path."""
        tr = self.track.get(f)
        if tr is not None and tr.status == _CARRIED:
            carrier, rel = tr.carry
            return _core.row_poses(carrier[None], np.array([tau]))[0] @ rel
        if tr is not None and tr.status == _STOPPED and tau >= tr.stop_time:
            return tr.frozen
        p = _core.frame_poses(self.state.rows[f][None], self.dt, np.zeros(1, dtype=np.int64), np.array([tau]))[0]
        return pose_matrix(p[:3], p[3:])

    def stop(self, f, tau, whole=False):
        """Frame f stands still from tau on, with the velocity it had at tau, as the world
        going back there would give it (``Contacts._world_to``; ``whole``: its velocity after
        the step, less the rest's gravity, as for a struck body; so too for one the solve
        pushed on another free body with: ``_Solve``): kept from after the step whatever
        its contact, a stopped body would gain a step's gravity every step it stands."""
        tr = self.track[f]
        tr.frozen = self.com(f, tau)
        if tr.velocity is None:
            st = self.state
            if self._kept is None:
                self._kept = self.solve.through(self.struck)
            mode = 2 if st.twist0 is None or whole or f in self._kept or self.solve.partners(f) else 1
            v, w, _ = st.sweeper.velocities_at(self.dt, tau, [f], [mode], st.twist0, self.gravity, self.tables.damping)
            tr.velocity = (v[0], w[0])
        for r in tr.rows:
            X = _core.row_poses(self.rows[[r]], np.array([tau]))[0]
            self.rows[r] = _still_row(X, self.rows[r])
        tr.stop_time = tau
        self._changed(tr, _STOPPED, tau)

    def carried_by(self, f, k, row_k, tau, com=None):
        """Frame f moves with frame k, of path row ``row_k``, from tau on (from centre-of-mass
        pose ``com`` (4, 4) at tau, if given, rather than where its path has it)."""
        tr = self.track[f]
        carrier, rel = _rider(row_k, tau, self.com(f, tau) if com is None else com)
        for r in tr.rows:
            X_CS = self.tables.X_CS[self.box[r]]
            self.rows[r, PATH_ROW["pose_after"]] = carrier[PATH_ROW["pose_after"]]
            for name in ("displacement", "axis", "angle"):
                self.rows[r, PATH_ROW[name]] = carrier[PATH_ROW[name]]
            self.rows[r, PATH_ROW["box_in_frame"]] = (rel @ X_CS).reshape(-1)
        tr.carry, tr.carrier = (carrier, rel), k
        self._changed(tr, _CARRIED, tau)

    @staticmethod
    def _changed(tr, status, tau):
        tr.status = status
        tr.version += 1
        tr.since = tau


class Contacts:
    """The step's contacts in time order (see the module docstring)."""

    def __init__(self, cid, penetration, impact_depth, depth_tolerance, fit_tolerance, tolerances, stats, clamped,
                 velocity_clamp):
        """``clamped(frames)``: those of the frames whose velocity pybullet's velocity clamp cut
        in the (partial) step just taken; ``velocity_clamp(body)``: that clamp (``World``)."""
        self.cid, self.penetration, self.depth_tolerance = cid, penetration, depth_tolerance
        self.impact_depth = impact_depth
        self.fit_tolerance, self.tolerances, self.stats = fit_tolerance, tolerances, stats
        self.clamped, self.velocity_clamp = clamped, velocity_clamp
        self.met = set()

    def resolve(self, sw, jw, tables, state, dt, user_moved, gravity, back=True, horizon=1.0, struck=(), presses=None,
                jump_time=None):
        """Events of the step's sweep ``sw`` and of the kinematic jumps' sweep ``jw`` (either
        may be None), with what they need applied to pybullet. Returns (events, tau): with
        ``back``, tau is the earliest time the world is taken back to (1 if none; at most
        ``horizon``, another contact's such time), every free body is put where its path has
        it then, and the events are those up to it; without, the bodies of each such contact
        go back on their own and tau is 1. ``user_moved``: frames the user teleported since
        the last step (never pushed: their pose is the user's); ``struck``: frames whose
        contact the world was taken back to at the start of this (partial) step; ``presses``:
        {pair of frames: times the world went back to it pressing in this step}. The frames
        of the contact the world goes back to are left in ``self.acted`` (and in ``self.struck``
        if it is an impact: met inside the step); without ``back``, the frames stopped at an
        impact are left in ``self.struck``. With ``back``, the pairs of frames of the impacts
        the world goes back to are left in ``self.impacts``. The frames of contacts met inside
        the step and left to pybullet, which end it overlapping, are left in ``self.met``:
        pybullet resolves those impacts as the next step begins."""
        kinematic = set(state.kinematic)
        events, self.struck, self.acted, self._cut, self.impacts = [], set(), set(), set(), []
        self.link_pressed_again = False
        self.met = set()
        self._presses = {} if presses is None else presses
        pushed = self._jumps(jw, tables, state, dt, dt if jump_time is None else jump_time, kinematic, user_moved,
                             events) if jw is not None else {}
        solve = _Solve(self.cid, tables)
        paths = _Paths(sw, tables, state, dt, kinematic, struck, gravity, solve) \
            if sw is not None and sw.hits else None
        for d, (k, start, v) in pushed.items():  # then it rides its kinematic body through the step
            row_k = self._frame_row(tables, state, dt, k)
            if paths is not None and d in paths.track:
                paths.carried_by(d, k, row_k, 0.0, com=start)
                paths.track[d].velocity = (v, np.zeros(3))
            else:
                place(self.cid, tables, state, d, pose7(_carry(row_k, 0.0, start)), v, np.zeros(3))
        tau = horizon if back else 1.0
        if paths is not None:
            tau = min(tau, self._time_order(paths, sw, user_moved, events, back, tau))
        if back and tau < 1.0:
            self._world_to(paths, tables, state, dt, gravity, tau, set(struck) | self._cut, solve)
        elif paths is not None:
            self._apply(paths, tables, state)
        return events, tau

    def _apply(self, paths, tables, state):
        """Put the frames whose paths changed where their paths end, with their velocities."""
        for f, tr in paths.track.items():
            if tr.version:
                v, w = paths.twist(f)
                place(self.cid, tables, state, f, pose7(paths.com(f, 1.0)), v, w)
                self.stats.rewinds += tr.status == _STOPPED

    def world_to_start(self, tables, state, dt):
        """Every free body back where the (partial) step of dt began, with the velocities it
        began with (``state.twist0``)."""
        self._world_to(None, tables, state, dt, np.zeros(3), 0.0, (), _Solve(self.cid, tables))

    def _world_to(self, paths, tables, state, dt, gravity, tau, struck, solve):
        """Every free body where its path has it at tau, and every kinematic frame with a
        velocity where Bullet's path has it; carried bodies where their ride ends (the rest
        of the step would carry them no further), stopped ones where they stopped.

        The rest of the step is simulated again and adds its share of gravity, contacts and
        friction again, so a free body leaves tau with the velocity between its velocities
        before and after the step, in proportion; but one ``struck`` at the start of the
        step took its impact's impulse whole there, and leaves with its velocity after the
        step less the rest of the step's gravity (as does any whose velocity before the
        step is not known), and so does every free body the solve pushed on one of those or
        on a body stopped against another free body (``_Solve``)."""
        track = paths.track if paths is not None else {}
        carried = [f for f, tr in track.items() if tr.status == _CARRIED]
        stopped = [f for f, tr in track.items() if tr.status == _STOPPED and tr.stop_time <= tau]
        struck = solve.through(set(struck).union(f for f in stopped if solve.partners(f)))
        # Every other frame is on Bullet's path (a fixed base the user gave a velocity too).
        off = set(carried + stopped)
        free = [f for f in tables.free_frames if f not in off]
        frames = free + [f for f in state.with_velocity if f in state.kinematic]
        whole = state.twist0 is None
        modes = [2 if whole or f in struck else 1 for f in free] + [0] * (len(frames) - len(free))
        v, w, still = state.sweeper.velocities_at(dt, tau, frames, modes, state.twist0, gravity, tables.damping)
        # A body standing still before and after the step stays where it is (placing it
        # would wake a sleeping one).
        keep = [k for k, s in enumerate(still) if not s]
        frames = [frames[k] for k in keep]
        state.read_poses(state.stale(frames))
        poses = _core.frame_poses(state.rows, dt, np.array(frames, dtype=np.int64), np.full(len(frames), tau))
        _place_all(self.cid, tables, state, frames, poses, v[keep], w[keep])
        for f in carried + stopped:
            vf, wf = paths.twist(f)
            place(self.cid, tables, state, f, pose7(paths.com(f, 1.0)), vf, wf)

    # -------------------------------------------------------- time order
    def _time_order(self, paths, sw, user_moved, events, back, horizon):
        """Take the contacts in time order up to ``horizon``, acting on those pybullet would
        resolve wrongly, and sweep again the pairs of every body whose path changed. With
        ``back``, stop at the first one and return its time; else 1."""
        # The sweep's first touches are queued at their touch and judged when they come up
        # (a contact's action is never before its touch): those after the step's first
        # action are not judged at all when the world goes back there.
        heap = [(tau, k, i, j, (0, 0), None) for k, (i, j, tau) in enumerate(sw.hits)]
        heapq.heapify(heap)
        order = itertools.count(len(heap))  # ties in time go in the order queued
        budget = 8 * len(paths.track) + 8  # a cap on actions: each one changes a path
        while heap:
            if back and heap[0][0] > horizon:
                break
            ripe = self._pop_ripe(heap, order, paths, back)
            if ripe is None:
                continue
            tau_r, i, j, info = ripe
            if info is None:  # its paths changed since it was queued: swept again from the change
                ta, tb = paths.track[paths.frame[i]], paths.track[paths.frame[j]]
                since = max(ta.since, tb.since)
                touch = self._first_touches(paths, [(i, j)], since)[0]
                if touch is not None:
                    self._queue(heap, order, paths, i, j, since, touch, back)
                continue
            if info["action"] is not None and budget <= 0:
                info["action"] = None  # out of budget: pybullet's, from here on
            if back and info["action"] == "back":
                self._report(paths, i, j, info, True, events)
                # A contact met inside the step is an impact: its impulse acts whole as the
                # partial step begins. The next press of a pair already touching is not (its
                # impulse kept whole at every go back would pump energy into the pair), unless
                # the clamp cut it (``_clamp_cut``).
                key = (int(paths.frame[i]), int(paths.frame[j]))
                if not info["impact"]:
                    self._presses[key] = self._presses.get(key, 0) + 1
                    self.link_pressed_again = self._presses[key] > 1 and (paths.link(key[0]) or paths.link(key[1]))
                    self._cut = self._clamp_cut(key)
                self.acted = set(key)
                self.struck = self.acted if self._cut or info["impact"] else set()
                if not info["impact"]:
                    return tau_r
                self.impacts = [key]
                return self._coalesce(paths, heap, order, i, j, tau_r, events)
            changed = self._act(paths, i, j, tau_r, info, user_moved)
            self._report(paths, i, j, info, bool(changed), events)
            if info["action"] is None and not info["initial"] and info["depth_end"] >= 0.0:
                self.met.update((int(paths.frame[i]), int(paths.frame[j])))
            budget -= bool(changed)
            again = [sw.pairs[paths.pairs_of(f)].tolist() for f in changed]
            again = [(i2, j2) for pairs in again for i2, j2 in pairs  # two bodies standing still: nothing more happens
                     if paths.status(paths.frame[i2]) != _STOPPED or paths.status(paths.frame[j2]) != _STOPPED]
            touches = self._first_touches(paths, again, tau_r)
            for (i2, j2), touch in zip(again, touches):
                if touch is not None:
                    self._queue(heap, order, paths, i2, j2, tau_r, touch, back)
        return 1.0

    def _pop_ripe(self, heap, order, paths, back):
        """Pop the earliest queued contact. A first touch of the sweep is judged now, on
        Bullet's paths unless one changed since, and queued again at its time to act if that
        is later (a contact's action is never before its touch): None. Else (tau, i, j,
        info), info None where the pair's paths changed since it was queued or judged."""
        tau_r, _, i, j, versions, info = heapq.heappop(heap)
        ta, tb = paths.track[paths.frame[i]], paths.track[paths.frame[j]]
        if info is None and (ta.version, tb.version) == (0, 0):
            info = self._judge(paths, i, j, 0.0, tau_r, back)
            if info["act_at"] > tau_r:
                heapq.heappush(heap, (info["act_at"], next(order), i, j, versions, info))
                return None
        elif versions != (ta.version, tb.version):
            info = None
        return tau_r, i, j, info

    def _coalesce(self, paths, heap, order, i, j, tau, events):
        """The impacts that begin after the one of rows (i, j) at tau, while it is still
        shallower than COALESCE (and each one that joins, too), join it: the world goes back to
        the latest of them, where every one has begun, and one partial step resolves them all
        (each from an overlap of at most that depth). Returns the time to go back to."""
        if not heap:
            return tau
        limit, passed = self._depth_time(paths, i, j, tau), []
        while heap and heap[0][0] <= limit:
            ripe = self._pop_ripe(heap, order, paths, True)
            if ripe is None:
                continue
            tau_r, i2, j2, info = ripe
            if info is None:
                break
            if info["action"] is None:  # pybullet's: reported if the world goes back past it
                passed.append((tau_r, i2, j2, info))
                continue
            if info["action"] != "back" or not info["impact"]:
                break
            self._report(paths, i2, j2, info, True, events)
            key = (int(paths.frame[i2]), int(paths.frame[j2]))
            self.acted.update(key)
            self.struck.update(key)
            self.impacts.append(key)
            tau = tau_r
            limit = min(limit, self._depth_time(paths, i2, j2, tau_r))
        for tau_r, i2, j2, info in passed:
            if tau_r <= tau:
                self._report(paths, i2, j2, info, False, events)
        return tau

    def _depth_time(self, paths, i, j, tau):
        """When the boxes of rows (i, j) on their paths overlap by COALESCE of the thinner one's
        half extent (at most COALESCE_CAP impact depths), from tau on; 1 if never."""
        depth = min(COALESCE * min(paths.thin[i], paths.thin[j]), COALESCE_CAP * self.impact_depth)
        t = _core.paths_first_depth(_core.RowBoxPath(paths.rows[i]), _core.RowBoxPath(paths.rows[j]), tau, depth)
        return 1.0 if math.isnan(t) else t

    def _first_touches(self, paths, pairs, lo):
        """The first touch (a step fraction) of each pair of rows over [lo, 1], or None."""
        if lo >= 1.0 or not pairs:
            return [None] * len(pairs)
        w = _core.window_rows(paths.rows[np.ravel(pairs)], lo, 1.0)
        tau, states, solves = _core.first_touches(w, np.arange(w.shape[0], dtype=np.int64).reshape(-1, 2),
                                                  self.fit_tolerance, self.tolerances._core, self.penetration, CREEP,
                                                  states=True)
        self.stats.solver_rows += solves
        self.stats.count(states)
        return [None if math.isnan(t) else lo + t * (1.0 - lo) for t in tau.tolist()]

    def _queue(self, heap, order, paths, i, j, lo, touch, back):
        """Judge the pair's contact (first touch ``touch`` in the window [lo, 1]) and queue
        it at the time to act (or at its touch, to be reported only)."""
        ta, tb = paths.track[paths.frame[i]], paths.track[paths.frame[j]]
        info = self._judge(paths, i, j, lo, touch, back)
        heapq.heappush(heap, (info["act_at"], next(order), i, j, (ta.version, tb.version), info))

    def _impact_depth(self, paths, i, j):
        """The overlap at which an impact of rows (i, j) is resolved: ``impact_depth``, at most
        ``IMPACT_SHARE`` of the thinner box's smallest half extent, at least ``penetration``;
        against a plane ``penetration`` (Bullet's plane contact takes one point, however
        deep)."""
        if paths.plane[i] or paths.plane[j]:
            return self.penetration
        return self._depth_of(min(paths.thin[i], paths.thin[j]))

    def box_impact_depth(self, half, other_half):
        """The impact depth of two boxes (not planes) of half extents ``half``, ``other_half``."""
        return self._depth_of(min(min(half), min(other_half)))

    def _depth_of(self, thin):
        return max(self.penetration, min(self.impact_depth, IMPACT_SHARE * float(thin)))

    def _judge(self, paths, i, j, lo, touch, back):
        """What the pair (rows i, j) needs: {"act_at": tau, "action": None | "back" | "stop"
        | "push", "initial", "impact", "window", "contact", "depth_end"}: "back" takes the world
        back to act_at, "stop" the pair's free bodies, "push" carries a free body with the
        kinematic one; "impact": met inside the window, or another corner of a pair touching as
        it began; "depth_end": the pair's depth at the step's end where judged (else NaN).

        A pair touching as the window began (pybullet's solver saw it) is acted on only if
        it ends deeper by more than depth_tolerance (the next corner of a turning box
        striking, or a body driven through): if it comes apart first, its next touch is
        judged as a contact met inside the window; if the window began at its impact and
        another corner strikes, from that corner's impact depth, as an impact; else from the
        time it presses in by more than a creep (a box pivoting on a corner sinks that
        corner slowly); one met inside the window, if pybullet would resolve it wrongly
        (``_core.judge_contact``), from the time it overlaps by the impact depth."""
        fa, fb = paths.frame[i], paths.frame[j]
        s_touch = (touch - lo) / (1.0 - lo)
        initial = s_touch == 0.0
        carried = paths.status(fa) == _CARRIED or paths.status(fb) == _CARRIED
        push_a = paths.pushes(fa) and paths.free(fb)
        push_b = paths.pushes(fb) and paths.free(fa)
        pushing = (push_a or push_b) and (carried or not back)
        if pushing:
            # A body carried by a kinematic teleport, or no partial step left: the
            # kinematic body cannot be taken back, so the free one is pushed ahead of it.
            action = "push"
        elif paths.stoppable(fa) or paths.stoppable(fb) or (back and (push_a or push_b)):
            action = "back" if back else "stop"
        else:
            action = None
        after_impact = fa in paths.struck and fb in paths.struck
        c, wrong, s_act, normal, parted, again, fresh, depth_end = _core.judge_contact(
            paths.rows[i], paths.rows[j], lo, s_touch, action is not None, pushing, after_impact, self.penetration,
            self._impact_depth(paths, i, j), self.depth_tolerance, CREEP, self.tolerances._core)
        self.stats.outcomes[Outcome.SEPARATED if c is None else c.outcome] += 1
        # A corner that was apart as the window began striking (``fresh``) is an impact of a
        # pair touching as it began.
        info = {"act_at": touch, "action": None, "initial": initial, "impact": not initial or fresh,
                "window": (lo, 1.0), "contact": c, "depth_end": depth_end}
        if parted and not pushing:
            # pybullet's solver parted the pair: where it meets again (another corner of a
            # turning box striking) is an impact of its own, judged from its touch.
            return info if math.isnan(again) else self._judge(paths, i, j, lo, lo + again * (1.0 - lo), back)
        if c is None or action is None:  # c None: the fit's allowance touched, the boxes did not
            return info
        if pushing:
            w = _core.window_rows(paths.rows[[i, j]], lo, 1.0)
            if not _overtaken(w if push_a else w[::-1], normal if push_a else -normal, self.penetration):
                return info
            if math.isnan(s_act):
                s_act = s_touch
        elif not wrong or math.isnan(s_act):  # resolved by pybullet, or never that deep: a graze
            return info
        elif action == "back" and not info["impact"] and self._presses.get((int(fa), int(fb)), 0) >= PRESSES \
                and not paths.link(fa) and not paths.link(fb):
            # A pair still pressing in after the world went back to it twice in this step is
            # one pybullet's solver does not hold: going back again would only repeat that.
            # A link's press is taken back to again, in shorter pieces (``BoxCCD._step``).
            action = "stop"
        if action == "stop":
            # A free body stopped where a link or a kinematic body drives on into it would only
            # be overlapped deeper: a kinematic body pushes it ahead; a link's press is left to
            # pybullet's solver, which has the link's mass and motors (pushed, a heavy box left
            # a weak arm faster than the converged engine's; stopped, 3 cm deep in it).
            drive_a, drive_b = paths.drives(fa) and paths.free(fb), paths.drives(fb) and paths.free(fa)
            if drive_a or drive_b:
                w = _core.window_rows(paths.rows[[i, j]], lo, 1.0)
                if _overtaken(w if drive_a else w[::-1], normal if drive_a else -normal, self.penetration):
                    if paths.link(fa if drive_a else fb):
                        return info
                    action, push_a = "push", drive_a
        info.update(action=action, act_at=lo + s_act * (1.0 - lo), pusher_first=push_a)
        return info

    def _act(self, paths, i, j, tau, info, user_moved):
        """Act on a contact ("stop" or "push"); returns the frames whose paths changed."""
        fa, fb = paths.frame[i], paths.frame[j]
        c = info["contact"]
        if c is None or info["action"] is None:
            return []
        if info["action"] == "push":
            k, d = (fa, fb) if info["pusher_first"] else (fb, fa)
            if d in user_moved:
                return []
            row_k = paths.rows[i if info["pusher_first"] else j]
            normal = _moved_with(row_k, tau, c.normal if info["pusher_first"] else -c.normal)
            paths.carried_by(d, k, row_k, tau)
            com1 = paths.com(d, 1.0)[:3, 3]
            v = self._push_velocity(paths.tables, paths.state, paths.dt, d, paths.driver(k), com1, normal,
                                    paths.twist(d)[0])
            paths.track[d].velocity = (v, paths.twist(d)[1])
            return [d]
        changed = [f for f in (fa, fb) if paths.stoppable(f)]
        whole = not info["impact"] and bool(self._clamp_cut((fa, fb)))
        for f in changed:
            paths.stop(f, self._stop_time(paths, f, tau), whole)
        if info["initial"] and changed:
            self._part(paths, i, j, min(paths.track[f].stop_time for f in changed))
        if info["impact"]:  # pybullet's solver meets it as the next step begins
            self.struck.update(changed)
        return changed

    def _part(self, paths, i, j, tau):
        """A pair touching as the window began that still goes in, stopped at tau, where Bullet
        clamps the turn of one of its bodies (by more than pi/4 in the window): pybullet's
        solver sees the whole spin, its integrator turns the body slower, so a corner the
        solver sees leaving is driven in on the integrated path (a rod moving into a wall at
        37 m/s, spinning at 450 rad/s: its touching corner leaves at 1 m/s), and given the same
        contact as the next step begins, pybullet leaves it going in, step after step. Where
        the points at which an edge of one box is within ``depth_tolerance`` of the other
        approach on the motion Bullet integrates, along the pair's axis of least overlap, the
        pair's centres of mass part along it as a collision of two particles parts them: the
        approach of the centres turned into a parting at the pair's combined restitution (at
        most 1; none where one is not known: ``world.restitution``), shared between the
        masses of its free bodies stopped in this pass (what else it touches does not move),
        their spins kept, so that no kinetic energy is made (nothing is done where the
        centres do not approach)."""
        frames = (int(paths.frame[i]), int(paths.frame[j]))
        (va, wa), (vb, wb) = twists = [paths.twist(f) for f in frames]
        sa, sb = (_turned(w, paths.dt) for _, w in twists)
        if min(sa, sb) >= 1.0:
            return
        rows = paths.rows[[i, j]]
        _, n = _core.paths_separation(_core.RowBoxPath(rows[0]), _core.RowBoxPath(rows[1]), tau)
        closing = -float((vb - va) @ n)  # the centres' approach
        if not closing > 0.0 or not np.all(np.isfinite(n)):
            return
        X = _core.row_poses(rows, np.array([tau, tau]))
        half = rows[:, PATH_ROW["half_extents"]]
        points = np.concatenate((_edges_in(X[0], half[0], X[1], half[1], self.depth_tolerance),
                                 _edges_in(X[1], half[1], X[0], half[0], self.depth_tolerance)))
        ca, cb = (paths.com(f, tau)[:3, 3] for f in frames)
        moving = (vb - va) + np.cross(sb * wb, points - cb) - np.cross(sa * wa, points - ca)
        if not len(points) or float((moving @ n).min()) >= 0.0:
            return
        dynamics = [raw.getDynamicsInfo(*paths.tables.keys[f], physicsClientId=self.cid) for f in frames]
        inverse = [1.0 / d[0] if d[0] > 0.0 and paths.free(f) and paths.status(f) == _STOPPED else 0.0
                   for f, d in zip(frames, dynamics)]
        if sum(inverse) == 0.0:
            return
        e = [restitution(self.cid, paths.tables.keys[f], d) for f, d in zip(frames, dynamics)]
        change = (1.0 + (0.0 if None in e else min(1.0, e[0] * e[1]))) * closing / sum(inverse)
        for f, (v, w), m, sign in zip(frames, twists, inverse, (-1.0, 1.0)):
            if m > 0.0:
                paths.track[f].velocity = (v + sign * m * change * n, w)

    def _stop_time(self, paths, f, tau):
        """When frame f stops for a contact at tau: then, unless its path takes it by then more
        than depth_tolerance deeper into another box than it was when their paths last
        changed (a turning box's corner dips into a face it rests on and comes out again by
        the step's end, which pybullet resolves; stopped on the way, it would stay in): then
        the first time it is that deep."""
        rows = paths.track[f].rows
        for r, r2 in paths.pairs[paths.pairs_of(f)].tolist():
            if r not in rows:
                r, r2 = r2, r
            if paths.frame[r2] == f:
                continue
            lo = max(paths.track[f].since, paths.track[paths.frame[r2]].since)
            if lo >= tau:
                continue
            a, b = _core.RowBoxPath(paths.rows[r]), _core.RowBoxPath(paths.rows[r2])
            allowed = max(_core.paths_depth(a, b, lo), 0.0) + self.depth_tolerance
            if _core.paths_depth(a, b, tau) > allowed:
                t = _core.paths_first_depth(a, b, lo, allowed)
                if not math.isnan(t):
                    tau = min(tau, t)
        return tau

    def _clamp_cut(self, pair):
        """The frames of a pair pressing in while touching whose velocities stay whole where it
        is taken back to (its bodies', if pybullet's velocity clamp cut one of them in the
        step; else none). Taken in proportion, the solve of the step would be undone there,
        and the clamp cuts it again from the same velocities at the next solve: the pair would
        press in again from the same state, step after step. Kept, each solve takes more of the
        approach, as at the successive solves of a fine step."""
        return set(pair) if self.clamped(pair) else set()

    def _report(self, paths, i, j, info, acted, events):
        c = info["contact"]
        if c is None:
            return
        lo, hi = info["window"]
        t_event = lo + c.t * (hi - lo)
        # The judgement's contact is the solve's on boxes grown by the allowance of one fit
        # over the rest of the window (centimetres for a box spinning fast, a metre for a rod
        # at 1,000 rad/s): the event is the boxes' own first touch on Bullet's path (the
        # window's start for a pair pressing in from there), and the contact there. (That of
        # another corner of a pair touching as the window began, striking, is its own already.)
        a, b = _core.RowBoxPath(paths.rows[i]), _core.RowBoxPath(paths.rows[j])
        if info["initial"] and not info["impact"]:
            exact = _core.paths_window_contact(a, b, t_event, min(1.0, t_event + _EVENT_WINDOW), self.tolerances._core)
            if exact is not None:
                c = exact
        elif not info["initial"]:
            touch = _core.paths_first_depth(a, b, t_event, 0.0)
            if not math.isnan(touch):
                exact = _core.paths_window_contact(a, b, max(touch - _EVENT_WINDOW, t_event), touch,
                                                   self.tolerances._core)
                if exact is not None and exact.feature is not None:
                    c, t_event = exact, exact.t
        fa, fb = paths.frame[i], paths.frame[j]
        keys = paths.tables.keys
        events.append(CCDEvent(*keys[fa], *keys[fb], t_event, t_event * paths.dt, c.point, c.normal, c.feature,
                               acted, info["initial"]))

    # -------------------------------------------------------------- jumps
    def _jumps(self, jw, tables, state, dt, jump_time, kinematic, user_moved, events):
        """Free bodies a kinematic jump (the user's teleport before the step of dt, a move over
        ``jump_time``: the user's step) swept into, carried with it from the touch to where it
        stood when the step began: their path through the step (Bullet's, in a world where
        the kinematic body was already there) is replaced by a ride on it, and what a riding
        body meets in turn rides from that touch on, in time order (a paddle teleported into
        a row of cubes pushes the row). A body leaves with its velocity cut to pybullet's
        velocity clamp, as pybullet cuts it at every step, and one the clamp keeps slower
        along the contact's normal than the kinematic body is not carried: pybullet at a fine
        step cannot push it so fast, and the kinematic body passes it (an obstacle a reset
        puts elsewhere, moved 4 m in a step, through a resting cube). Returns {frame:
        (kinematic frame, centre-of-mass pose (4, 4) at the step's start, velocity)}."""
        pushed = {}
        order = itertools.count()
        # (touch, order, pair of path rows (pusher's first), pusher frame, met frame, driver, contact)
        queue = []
        for i, j, tau in jw.hits:
            k, d = tables.box_frame[jw.boxes[[i, j]]].tolist()
            queue.append((tau, next(order), jw.rows[[i, j]], k, d, k, None))
        heapq.heapify(queue)
        while queue:
            tau, _, pair, pusher, d, k, c = heapq.heappop(queue)
            if d in pushed:  # it rides on from an earlier touch
                continue
            c = self._contact(pair, tau, 1.0) if c is None else c
            if c is None:
                continue
            act = tables.kind[d] == FREE and d not in kinematic and d not in user_moved
            if act:
                start = pose_matrix(*np.split(_core.frame_poses(state.rows, dt, np.array([d], dtype=np.int64),
                                                                np.zeros(1))[0], [3]))
                X = _carry(pair[0], tau, start)
                normal = _moved_with(pair[0], tau, c.normal)
                v = self._push_velocity(tables, state, jump_time, d, k, X[:3, 3], normal, state.rows[d, VELOCITY],
                                        pusher, jump=True)
                clamp = self.velocity_clamp(tables.keys[d][0])
                if clamp is not None:  # pybullet cuts each component to the clamp: can it keep ahead?
                    v = np.clip(v, -clamp, clamp)
                    ahead = float(self._kinematic_velocity(*state.jumps[k], jump_time, X[:3, 3]) @ normal)
                    act = float(v @ normal) >= ahead - 1e-9 * max(abs(ahead), 1.0)
            events.append(CCDEvent(*tables.keys[pusher], *tables.keys[d], 0.0, 0.0, c.point, c.normal, c.feature,
                                   bool(act), False))
            if act:
                pushed[d] = (k, X, v)
                for t, rows, met, contact in self._ride_touches(tables, state, dt, pair[0], tau, d, start,
                                                                kinematic | set(pushed)):
                    heapq.heappush(queue, (t, next(order), rows, d, met, k, contact))
        return pushed

    def _ride_touches(self, tables, state, dt, row, tau, d, start, exclude):
        """The first touches of frame d riding from tau on with the frame of path row ``row``
        (its centre of mass at pose ``start`` then) with the free frames standing where the
        step began, not in ``exclude``: [(touch, pair of path rows, met frame, contact)]."""
        carrier, rel = _rider(row, tau, start)
        boxes = tables.frame_boxes[d]
        rides = np.repeat(carrier[None], len(boxes), axis=0)
        for r, b in enumerate(boxes):
            rides[r, PATH_ROW["box_in_frame"]] = (rel @ tables.X_CS[b]).reshape(-1)
            rides[r, PATH_ROW["half_extents"]] = tables.half[b]
        near = ride_near(self.cid, tables, state, dt, rides, boxes, exclude | {d})
        if near is None:
            return []
        rows, met, pairs = near
        touches = []
        for i, j in pairs.tolist():
            c = self._contact(rows[[i, j]], tau, 1.0)
            if c is not None:
                touches.append((c.t, rows[[i, j]], int(tables.box_frame[met[j]]), c))
        return touches

    @staticmethod
    def _frame_row(tables, state, dt, k):
        """Path row of kinematic frame k's own motion through the step (box = the frame)."""
        box = tables.frame_boxes[k][0]
        row = _core.path_rows(state.rows, dt, np.array([box], dtype=np.int64), tables.box_frame, tables.X_CS,
                              tables.half)[0]
        row[PATH_ROW["box_in_frame"]] = _IDENTITY
        return row

    # -------------------------------------------------------------- pushes
    def _push_velocity(self, tables, state, dt, d, k, point, normal, v, by=None, jump=False):
        """Frame d's velocity after a collision, at ``point`` along ``normal`` (from the
        pusher), with an immovable body moving as kinematic frame k moved over the step (its
        jump and the step's own motion; with ``jump``, its jump alone, taken in dt: a user who
        teleports a body to its next pose and gives it its velocity too moves it twice in
        the step the teleport begins), its own velocity v before. The collision is with
        frame ``by`` (k if None; a body riding with k), with the pair's restitution, but
        none with k itself if the user only teleports it: pybullet gives it no velocity to
        rebound from, and at a fine step pushes what it moves into out of the overlap, at
        its speed."""
        self.stats.pushes += 1
        by = k if by is None else by
        elastic = by != k or k in state.with_velocity
        ends = state.jumps[k] if jump else (state.pose0.get(k, state.rows[k, POSE]), state.rows[k, POSE])
        return bounce(self.cid, tables, d, by, v, self._kinematic_velocity(*ends, dt, point), normal, elastic)

    @staticmethod
    def _kinematic_velocity(e0, e1, dt, point):
        """Velocity at world point ``point`` (at pose e1) of a kinematic frame's move from pose
        e0 to pose e1, taken in dt."""
        one = np.zeros(1, dtype=np.int64)
        move = _core.path_rows_between(e0[None], e1[None], one, one, np.eye(4)[None], np.zeros((1, 3)))[0]
        omega = move[PATH_ROW["axis"]] * move[PATH_ROW["angle"]][0] / dt
        return move[PATH_ROW["displacement"]] / dt + np.cross(omega, point - e1[:3])

    def _contact(self, pair, lo, hi):
        """The first touch of a pair (path rows) in [lo, hi] (step fractions): one solve on
        a quadratic refit of the exact path over that window, the boxes inflated by the
        refit's error bound so that a touch cannot be missed; None if they stay apart
        (the first touch found on the step's fit was within that fit's allowance only). Its
        outcome is counted in the stats."""
        c = _core.paths_window_contact(_core.RowBoxPath(pair[0]), _core.RowBoxPath(pair[1]), lo, hi,
                                       self.tolerances._core)
        self.stats.outcomes[Outcome.SEPARATED if c is None else c.outcome] += 1
        return c


def _place_all(cid, tables, state, frames, poses, v, w):
    """Put free frames' bodies at ``poses`` (n, 7: centre of mass position, quaternion)
    with velocities v, w (n, 3), in pybullet and in the frame-state rows."""
    keys, reset_pose, reset_velocity = tables.keys, raw.resetBasePositionAndOrientation, raw.resetBaseVelocity
    for f, pose, vf, wf in zip(frames, poses.tolist(), v.tolist(), w.tolist()):
        b = keys[f][0]
        reset_pose(b, pose[:3], pose[3:], physicsClientId=cid)
        reset_velocity(b, vf, wf, physicsClientId=cid)
    state.rows[frames] = np.concatenate((poses, v, w), axis=1)  # a row: pose, velocity, angular velocity


# ------------------------------------------------------- shared with articulated.py
def place(cid, tables, state, f, pose, v, w):
    """``_place_all`` of one frame f: pose (7,), velocities v, w (3,)."""
    _place_all(cid, tables, state, [f], np.asarray(pose, float)[None], np.asarray(v, float)[None],
               np.asarray(w, float)[None])


def bounce(cid, tables, d, k, v, v_k, normal, elastic=True):
    """Frame d's velocity (v before) after a collision along ``normal`` (from the pusher)
    with an immovable body moving at v_k there, of frame k's restitution: pybullet's
    combined restitution on the approach, raised by half the contact ERP as the converged
    engine's rebound is on average (``BoxCCD._simulate``; not with a maximal-coordinate body,
    as there), none unless ``elastic`` or where a restitution is not known
    (``world.restitution``); nothing if they part already."""
    v = np.array(v, float)
    if np.all(np.isfinite(normal)):
        approach = float(np.dot(v - v_k, normal))
        if approach < 0.0:
            e = 0.0
            if elastic:
                a, b = (raw.getDynamicsInfo(*tables.keys[f], physicsClientId=cid) for f in (d, k))
                ea, eb = restitution(cid, tables.keys[d], a), restitution(cid, tables.keys[k], b)
                lift = 0.5 * journal(cid).contact_erp if MAXIMAL_TYPE not in (a[10], b[10]) else 0.0
                e = 0.0 if ea is None or eb is None else ea * eb + lift
            v = v - (1.0 + e) * approach * normal
    return v


# ---------------------------------------------------------------- geometry
def _overtaken(wk, n, penetration):
    """Whether the pusher's box (row wk[0]) ends the step into or past the box it touched
    (wk[1]): their separation along the contact normal at the end (n, from the pusher),
    below ``penetration``."""
    if not np.all(np.isfinite(n)):
        return True
    (cp, Rp, hp), (cd, Rd, hd) = (_box_at_end(row) for row in wk)
    gap = float(np.dot(cd - cp, n)) - np.abs(Rp.T @ n) @ hp - np.abs(Rd.T @ n) @ hd
    return gap < penetration


def _moved_with(row, s, v):
    """Direction v at s, turned with the row's frame to the end of its path."""
    return axis_angle_matrix(row[PATH_ROW["axis"]], (1.0 - s) * row[PATH_ROW["angle"]][0]) @ v


def _frame_of(row):
    """The frame of path row ``row`` as a path row of its own (its box at the frame)."""
    frame = row.copy()
    frame[PATH_ROW["box_in_frame"]] = _IDENTITY
    return frame


def _rider(row, tau, com):
    """(the frame of path row ``row`` as a path row of its own, centre-of-mass pose ``com``
    (4, 4) at tau in that frame): what a body riding with the frame from tau on needs."""
    frame = _frame_of(row)
    return frame, np.linalg.inv(_core.row_poses(frame[None], np.array([tau]))[0]) @ com


def _carry(row, tau, X):
    """Pose X (4, 4) at tau moved rigidly with the frame of path row ``row`` to its end."""
    frame = _frame_of(row)
    F_tau, F_1 = _core.row_poses(np.stack([frame, frame]), np.array([tau, 1.0]))
    return F_1 @ np.linalg.solve(F_tau, X)


_EDGES = np.array([(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1])
_CORNERS = np.array([[(k >> 2) & 1, (k >> 1) & 1, k & 1] for k in range(8)], float) * 2.0 - 1.0


def _edges_in(XA, ha, XB, hb, margin):
    """The middles of the parts of box A's 12 edges inside box B grown by ``margin`` (boxes:
    poses (4, 4), half extents (3,)), world: where two overlapping boxes touch (any overlap
    of two boxes has an edge of one through the other)."""
    corners = (_CORNERS * ha) @ XA[:3, :3].T + XA[:3, 3]
    local = (corners - XB[:3, 3]) @ XB[:3, :3]  # in B's frame
    p0, d = local[_EDGES[:, 0]], local[_EDGES[:, 1]] - local[_EDGES[:, 0]]
    lim = hb + margin
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-lim - p0) / d, (lim - p0) / d
    flat = d == 0.0
    inside = np.abs(p0) <= lim
    t_lo = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
    t_hi = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
    lo = np.maximum(0.0, t_lo.max(axis=1))
    hi = np.minimum(1.0, t_hi.min(axis=1))
    keep = lo <= hi
    mid = p0[keep] + 0.5 * (lo[keep] + hi[keep])[:, None] * d[keep]
    return mid @ XB[:3, :3].T + XB[:3, 3]


def _turned(w, dt):
    """The share of a spin w (3,) that Bullet turns a body by in a step of dt: all of it up to
    pi/4, above which Bullet clamps the angle a to 2 atan(a / (pi/4) tan(pi/8))
    (``_core/paths/step_path.hpp``)."""
    angle, quarter = float(np.linalg.norm(w)) * dt, 0.25 * math.pi
    return 1.0 if angle <= quarter else 2.0 * math.atan(angle / quarter * math.tan(0.5 * quarter)) / angle


def _still_row(X, row):
    """A row of the same box standing at pose X (its box's pose) through the step."""
    out = row.copy()
    out[PATH_ROW["pose_after"]] = X.reshape(-1)
    out[PATH_ROW["displacement"]] = 0.0
    out[PATH_ROW["axis"]] = 0.0
    out[PATH_ROW["angle"]] = 0.0
    out[PATH_ROW["box_in_frame"]] = _IDENTITY
    return out


def _box_at_end(row):
    """(centre, axes (3, 3) columns, half extents) of a path row's box after the step."""
    X = _core.row_poses(row[None], np.ones(1))[0]
    return X[:3, 3], X[:3, :3], row[PATH_ROW["half_extents"]]
