"""What the plugin does about the contacts a sweep found: events, rewinds, pushes.

The principle is to step in only where pybullet would go wrong. pybullet's next step
resolves a pair from where it ends this step: it pushes an overlap out along the axis
of least overlap. That goes wrong when a box has gone past the plane in which it met
its partner (it passed through, or the least overlap now points out of the far side:
tunneling), and for boxes a kinematic body overtook (pybullet sees that body still). For
every contact found (the first touch, on conservatively fitted motions), the pair's
state at the end of the step is checked against those; only then does the plugin act:

* Rewind. A free body (``FREE``) goes back to where the pair first overlaps by
  ``penetration`` on Bullet's own path (Bullet's box-box detector makes a contact only
  from the touch on), with its post-solve velocity; pybullet's contact solver handles
  the impact in the next step.
* Push. A kinematic body or a body it carries cannot be rewound: a free body it
  overtakes is carried with it from where they met to where it ends, and its velocity
  along the contact normal becomes that of a collision with an immovable body moving
  as the kinematic one does (pybullet's combined restitution; spin left to pybullet).
* A pair that already touched when the step began is checked the same way, from the
  step's start. When it must be stopped almost at once (pybullet's solver left it
  approaching), the approach along the normal is resolved as a 1-D collision of the
  two centres of mass, so that it cannot stay stuck.

Changing one body's path can make it meet another (a rewound body now stands where
another one passes): the contacts are taken in time order, and every pair of a body
whose path changed is swept again from the change on (as in Box2D's time-of-impact
loop), so the step ends with no pair left in a state pybullet would resolve wrongly.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from .. import _core
from ..solver import Outcome
from ._hooks import raw
from .events import CCDEvent
from .layout import ANGULAR_VELOCITY, PATH_ROW, POSE, VELOCITY
from .sweep import CREEP
from .world import FREE, STATIC

__all__ = ["Impacts"]

_MOVING, _STOPPED, _CARRIED = 0, 1, 2
# A pair pressing in again after this many collisions in one step is held where it is.
_LEAKS = 4
# Steps after an impact the plugin handled during which the pair's parting is bounded.
_WATCH_STEPS = 30
_CLAMP = 0.25 * np.pi  # Bullet clamps a body's turn above this angle a step
_IDENTITY = np.eye(4).reshape(-1)


@dataclass
class _Watch:
    """An impact the plugin handled: its normal (from A towards B), the pair's approach
    speed along it, pybullet's combined restitution, the parting speed their spin before
    the impact can honestly give, and the steps it is still watched."""

    normal: np.ndarray
    approach: float
    e: float
    spin: float
    steps: int = 0

    def __post_init__(self):
        self.steps = _WATCH_STEPS


class _Paths:
    """The frames of a sweep on their effective paths through the step: Bullet's; or a
    continuation from a time with new velocities (after a collision the plugin
    resolved); or stopped at a time; or carried from a time by another frame's motion.
    Rows are the sweep's path rows, rewritten as paths change; all are over the whole
    step (tau in [0, 1]), valid from the frame's last change on."""

    def __init__(self, sw, tables, state, dt, kinematic):
        self.tables, self.state, self.dt = tables, state, dt
        self.rows = sw.rows.copy()
        self.box = sw.boxes
        self.frame = tables.box_frame[sw.boxes]
        self.rows_of = {}
        for r, f in enumerate(self.frame.tolist()):
            self.rows_of.setdefault(f, []).append(r)
        self.status = dict.fromkeys(self.rows_of, _MOVING)
        self.version = dict.fromkeys(self.rows_of, 0)
        self.since = dict.fromkeys(self.rows_of, 0.0)
        self.motion = {}  # frame -> (13,) state after the step of its continuation (else Bullet's: state.rows)
        self.stop_time = {}  # stopped frame -> tau
        self.frozen = {}  # stopped frame -> (4, 4) centre-of-mass pose
        self.carry = {}  # carried frame -> (carrier's frame row (42,), rel (4, 4): CoM in carrier frame)
        self.carried_from = {}  # carried frame -> the frame that pushed it
        self.velocity = {}  # frame -> (v, w) it leaves the step with, where the plugin changed them
        self.collisions = {}  # (frame, frame) -> collisions resolved for the pair in this step
        self.kinematic = kinematic

    def driver(self, f):
        """The kinematic frame that moves f (f itself, or its carrier's driver)."""
        while f in self.carried_from:
            f = self.carried_from[f]
        return f

    def pushes(self, f) -> bool:
        """f moves on regardless: a kinematic frame, or one carried by it."""
        return f in self.kinematic or self.status.get(f) == _CARRIED

    def free(self, f) -> bool:
        """A free body that the plugin may stop, restart or push (not carried already)."""
        return self.tables.kind[f] == FREE and f not in self.kinematic and self.status.get(f) != _CARRIED

    def stoppable(self, f) -> bool:
        return self.free(f) and self.status.get(f) == _MOVING

    def state_row(self, f):
        return self.motion.get(f, self.state.rows[f])

    def twist(self, f):
        """(v, w) of frame f from now on (what it leaves the step with)."""
        if f in self.velocity:
            return self.velocity[f]
        row = self.state_row(f)
        return row[VELOCITY].copy(), row[ANGULAR_VELOCITY].copy()

    def com(self, f, tau) -> np.ndarray:
        """(4, 4) centre-of-mass pose of frame f at tau on its effective path."""
        if self.status.get(f) == _CARRIED:
            carrier, rel = self.carry[f]
            return _core.row_poses(carrier[None], np.array([tau]))[0] @ rel
        if self.status.get(f) == _STOPPED and tau >= self.stop_time[f]:
            return self.frozen[f]
        p = _core.frame_poses(self.state_row(f)[None], self.dt, np.zeros(1, dtype=np.int64), np.array([tau]))[0]
        return _pose4(p)

    def stop(self, f, tau):
        """Frame f stands still from tau on (with the velocity it had)."""
        self.frozen[f] = self.com(f, tau)
        self.velocity.setdefault(f, self.twist(f))
        for r in self.rows_of[f]:
            X = _core.row_poses(self.rows[[r]], np.array([tau]))[0]
            self.rows[r] = _still_row(X, self.rows[r])
        self.stop_time[f] = tau
        self._changed(f, _STOPPED, tau)

    def restart(self, f, tau, v, w):
        """Frame f moves on from tau with velocities v, w (Bullet's rule: linear, about a
        fixed axis)."""
        com = self.com(f, tau)
        end = _advance(com, v, w, self.dt, 1.0 - tau)
        self.motion[f] = np.concatenate([_pose7(end), v, w])
        self.velocity[f] = (np.asarray(v, float), np.asarray(w, float))
        boxes = np.array([self.box[r] for r in self.rows_of[f]], dtype=np.int64)
        self.rows[self.rows_of[f]] = _core.path_rows(self.motion[f][None], self.dt, boxes,
                                                     np.zeros(len(self.tables.box_frame), dtype=np.int64),
                                                     self.tables.X_CS, self.tables.half)
        self.stop_time.pop(f, None)
        self._changed(f, _MOVING, tau)

    def carried_by(self, f, row_k, tau, com=None):
        """Frame f moves with the frame of path row ``row_k`` from tau on (from centre-of-mass
        pose ``com`` (4, 4) at tau, if given, rather than where its path has it)."""
        carrier = row_k.copy()
        carrier[PATH_ROW["box_in_frame"]] = _IDENTITY
        Finv = np.linalg.inv(_core.row_poses(carrier[None], np.array([tau]))[0])
        com = self.com(f, tau) if com is None else com
        for r in self.rows_of[f]:
            X_CS = self.tables.X_CS[self.box[r]]
            self.rows[r, PATH_ROW["pose_after"]] = carrier[PATH_ROW["pose_after"]]
            for name in ("displacement", "axis", "angle"):
                self.rows[r, PATH_ROW[name]] = carrier[PATH_ROW[name]]
            self.rows[r, PATH_ROW["box_in_frame"]] = (Finv @ com @ X_CS).reshape(-1)
        self.carry[f] = (carrier, Finv @ com)
        self.stop_time.pop(f, None)
        self._changed(f, _CARRIED, tau)

    def _changed(self, f, status, tau):
        self.status[f] = status
        self.version[f] += 1
        self.since[f] = tau


class Impacts:
    """Resolution of a step's contacts (see the module docstring)."""

    def __init__(self, cid, penetration, fit_tolerance, tolerances, exact_time, stats):
        self.cid, self.penetration, self.tolerances = cid, penetration, tolerances
        self.fit_tolerance, self.exact_time, self.stats = fit_tolerance, exact_time, stats
        self.watch = {}  # (key a, key b) -> _Watch: the impacts the plugin handled, bounded for a while

    def resolve(self, sw, jw, tables, state, dt, user_moved, gravity):
        """Events of the step's sweep ``sw`` and of the kinematic jumps' sweep ``jw`` (either
        may be None), with the plugin's actions applied to pybullet. Returns (events,
        tau_world): tau_world is the earliest action (1 if none), where the exact-time mode
        stops the world. ``user_moved``: frames the user teleported since the last step
        (never pushed: their pose is the user's)."""
        kinematic = set(state.kinematic)
        events = []
        pushed = self._jumps(jw, tables, state, dt, kinematic, user_moved, events) if jw is not None else {}
        paths = _Paths(sw, tables, state, dt, kinematic) if sw is not None and sw.hits else None
        for d, (k, start, v) in pushed.items():  # then it rides its kinematic body through the step
            row_k = self._frame_row(tables, state, dt, k)
            if paths is not None and d in paths.rows_of:
                paths.carried_by(d, row_k, 0.0, com=start)
                paths.carried_from[d] = k
                paths.velocity[d] = (v, np.zeros(3))
            else:
                place(self.cid, tables, state, d, _pose7(_carry(row_k, 0.0, start)), v, np.zeros(3))
        tau_world = 1.0
        if paths is not None:
            tau_world = self._time_order(paths, sw, user_moved, events)
            self._apply(paths, tables, state, dt, gravity, tau_world)
        self.stats.contacts += len(events)
        return events, tau_world

    def _apply(self, paths, tables, state, dt, gravity, tau_world):
        """Put the frames whose paths changed where their paths end, with their velocities;
        in exact-time mode every free body at tau_world instead."""
        changed = [f for f in paths.status if paths.version[f] > 0]
        if self.exact_time and tau_world < 1.0:
            carried = set(paths.carry)
            free = [f for f in np.flatnonzero(tables.kind == FREE).tolist() if f not in carried]
            state.read_poses(state.stale(free))
            for f in free:
                in_paths = f in paths.status
                pose = _pose7(paths.com(f, tau_world)) if in_paths else _core.frame_poses(
                    state.rows, dt, np.array([f], dtype=np.int64), np.array([tau_world]))[0]
                v, w = paths.twist(f) if in_paths else (state.rows[f, VELOCITY], state.rows[f, ANGULAR_VELOCITY])
                # The rest of the step is simulated again and adds its gravity again.
                place(self.cid, tables, state, f, pose, v - gravity * (1.0 - tau_world) * dt, w)
            self.stats.rewinds += len(free)
            changed = [f for f in changed if f in carried]
        for f in changed:
            v, w = paths.twist(f)
            place(self.cid, tables, state, f, _pose7(paths.com(f, 1.0)), v, w)
            self.stats.rewinds += paths.status[f] == _STOPPED

    # -------------------------------------------------------- time order
    def _time_order(self, paths, sw, user_moved, events):
        """Take the contacts in time order, acting where pybullet would go wrong, and sweep
        again the pairs of every body whose path changed. Returns the first action's time
        (1 if none): exact-time mode stops there."""
        pairs_of = {}
        for q, (i, j) in enumerate(sw.pairs.tolist()):
            for r in (i, j):
                pairs_of.setdefault(paths.frame[r], []).append(q)
        index = sw.pair_index
        heap = []
        for i, j, tau in sw.hits:
            self._queue(heap, paths, index[(i, j)], i, j, 0.0, tau)
        first, budget = 1.0, 8 * len(paths.status) + 8  # a cap on actions: each one changes a path
        while heap:
            tau_r, _, q, i, j, versions, info = heapq.heappop(heap)
            fa, fb = paths.frame[i], paths.frame[j]
            if versions != (paths.version[fa], paths.version[fb]):
                since = max(paths.since[fa], paths.since[fb])
                touch = self._first_touch(paths, i, j, since)
                if touch is not None:
                    self._queue(heap, paths, q, i, j, since, touch)
                continue
            if info["action"] is not None and budget <= 0:
                info["action"] = None  # out of budget: pybullet's, from here on
            changed = self._act(paths, i, j, tau_r, info, user_moved, events)
            if info["action"] == "collide" and not changed and budget > 0:
                budget -= 1  # the pressing point was not approaching (yet): look again, from here on
                self._queue(heap, paths, q, i, j, tau_r, tau_r)
            if changed:
                budget -= 1
                first = min(first, tau_r)
                if self.exact_time:
                    break
            for f in changed:
                for q2 in pairs_of.get(f, ()):
                    i2, j2 = sw.pairs[q2]
                    if paths.status[paths.frame[i2]] == _STOPPED and paths.status[paths.frame[j2]] == _STOPPED:
                        continue  # two bodies standing still: nothing more happens
                    touch = self._first_touch(paths, i2, j2, tau_r)
                    if touch is not None:
                        self._queue(heap, paths, q2, i2, j2, tau_r, touch)
        return first

    def _first_touch(self, paths, i, j, lo):
        """The first touch (a step fraction) of rows i and j over [lo, 1], or None."""
        if lo >= 1.0:
            return None
        w = _core.window_rows(paths.rows[[i, j]], lo, 1.0)
        tau, states, solves = _core.first_touches(w, np.array([[0, 1]], dtype=np.int64), self.fit_tolerance,
                                                  self.tolerances._core, self.penetration, CREEP, states=True)
        self.stats.solver_rows += solves
        self.stats.count(states)
        return None if np.isnan(tau[0]) else lo + float(tau[0]) * (1.0 - lo)

    def _queue(self, heap, paths, q, i, j, lo, touch):
        """Judge the pair's contact (first touch ``touch`` in the window [lo, 1]) and queue
        it at the time to act (or at its touch, to be reported only)."""
        fa, fb = paths.frame[i], paths.frame[j]
        info = self._judge(paths, i, j, lo, touch)
        heapq.heappush(heap, (info["act_at"], id(info), q, i, j, (paths.version[fa], paths.version[fb]), info))

    def _judge(self, paths, i, j, lo, touch):
        """What the pair (rows i, j) needs: {"act_at": tau, "action": None | "stop" |
        "collide" | "push", "initial", "touch", "window", "contact"}."""
        fa, fb = paths.frame[i], paths.frame[j]
        w = _core.window_rows(paths.rows[[i, j]], lo, 1.0)
        s_touch = (touch - lo) / (1.0 - lo)
        initial = s_touch == 0.0
        c = self._contact(w, s_touch, 1.0)
        info = {"act_at": touch, "action": None, "initial": initial, "touch": touch, "window": (lo, 1.0),
                "contact": c}
        if c is None:  # the fit's allowance touched, the boxes did not: nothing happened
            return info
        push_a = paths.pushes(fa) and paths.free(fb)
        push_b = paths.pushes(fb) and paths.free(fa)
        if push_a or push_b:
            normal = _normal_at_end(w, s_touch, c)
            if not _overtaken(w if push_a else w[::-1], normal if push_a else -normal, self.penetration):
                return info
            action = "push"
        elif initial and (paths.stoppable(fa) or paths.stoppable(fb)) and _STOPPED not in (
                paths.status.get(fa), paths.status.get(fb)):
            action = "collide"  # touching when the window began, and pybullet's solve left it pressing
        elif paths.stoppable(fa) or paths.stoppable(fb):
            action = "stop"  # a strike, or pressing on a body that stands still from now on
        else:
            return info
        target = self.penetration
        if initial:  # pressing deeper than a creep (a box pivoting on a corner sinks that corner slowly)
            thin = min(w[0, PATH_ROW["half_extents"]].min(), w[1, PATH_ROW["half_extents"]].min())
            d0 = float(_core.path_depth(w, np.zeros(1))[0])
            target = max(d0, 0.0) + max(self.penetration, CREEP * thin)
        # A pair whose impact the plugin resolved earlier in this step and that presses in
        # again is the next strike of that impact (a spinning box's next corner): resolved
        # as one more collision when it presses past the target, whatever pybullet would do
        # with where it ends (after _LEAKS of them it is held).
        if action != "push" and (fa, fb) not in paths.collisions and not _goes_wrong(w, s_touch, c, target):
            return info
        s_act = _core.first_depth(w, s_touch, target)
        if np.isnan(s_act):
            if action != "push":  # never as deep as that: a graze
                return info
            s_act = s_touch
        info.update(action=action, act_at=lo + s_act * (1.0 - lo), pusher_first=push_a)
        return info

    def _act(self, paths, i, j, tau, info, user_moved, events):
        """Report the contact and act on it; returns the frames whose paths changed."""
        tables = paths.tables
        fa, fb = paths.frame[i], paths.frame[j]
        lo, hi = info["window"]
        c = info["contact"]
        if c is None:
            return []
        t_event = lo + c.t * (hi - lo)
        changed = []
        if info["action"] == "push":
            k, d = (fa, fb) if info["pusher_first"] else (fb, fa)
            row_k = paths.rows[i if info["pusher_first"] else j]
            if d not in user_moved:
                paths.carried_from[d] = k
                normal = _moved_with(row_k, tau, c.normal if info["pusher_first"] else -c.normal)
                paths.carried_by(d, row_k, tau)
                com1 = paths.com(d, 1.0)[:3, 3]
                v = self._push_velocity(tables, paths.state, paths.dt, d, paths.driver(k), com1, normal,
                                        paths.twist(d)[0])
                paths.velocity[d] = (v, paths.twist(d)[1])
                changed = [d]
        elif info["action"] == "stop":
            self._remember(paths, fa, fb, c.normal)
            for f in (fa, fb):
                if paths.stoppable(f):
                    paths.stop(f, tau)
                    changed.append(f)
        elif info["action"] == "collide":
            self._remember(paths, fa, fb, _core.path_separation(paths.rows[[i, j]], tau)[1])
            changed = self._collide(paths, i, j, tau)
            count = paths.collisions[(fa, fb)] = paths.collisions.get((fa, fb), 0) + 1
            if count > _LEAKS:  # still pressing in after that many: held where it is from now on
                for f in (fa, fb):
                    if paths.stoppable(f):
                        paths.stop(f, tau)
                        changed = sorted(set(changed) | {f})
        events.append(CCDEvent(*tables.keys[fa], *tables.keys[fb], t_event, t_event * paths.dt, c.point, c.normal,
                               c.feature, bool(changed), info["initial"]))
        return changed

    # ---------------------------------------------------- restitution guard
    def _remember(self, paths, fa, fb, normal):
        """Note an impact the plugin handles: the pair's approach along the normal and the
        share of it spin can honestly return, from the velocities it had before."""
        if not np.all(np.isfinite(normal)):
            return
        tables = paths.tables
        key = (tables.keys[fa], tables.keys[fb])
        if key in self.watch:
            self.watch[key].steps = _WATCH_STEPS
            return
        (va, wa), (vb, wb) = paths.twist(fa), paths.twist(fb)
        e = 1.0
        for f in (fa, fb):
            e *= raw.getDynamicsInfo(*tables.keys[f], physicsClientId=self.cid)[5]
        reach = [tables.radius[tables.frame_boxes[f]].max() for f in (fa, fb)]
        self.watch[key] = _Watch(np.asarray(normal, float), max(-float(np.dot(vb - va, normal)), 0.0), e,
                                 float(np.linalg.norm(wa)) * reach[0] + float(np.linalg.norm(wb)) * reach[1])

    def guard(self, tables, state):
        """After a step: the pairs whose impacts the plugin handled recently leave each
        other along the impact's normal no faster than restitution allows (plus what their
        spin before the impact can give); a faster parting, which pybullet's solve or the
        cascade of a spinning box's corners can make, is taken out of the free bodies'
        velocities, momentum kept."""
        for key in list(self.watch):
            w = self.watch[key]
            w.steps -= 1
            fa, fb = tables.index.get(key[0]), tables.index.get(key[1])
            if w.steps < 0 or fa is None or fb is None:
                del self.watch[key]
                continue
            va, vb = state.rows[fa, VELOCITY], state.rows[fb, VELOCITY]
            excess = float(np.dot(vb - va, w.normal)) - (w.e * w.approach + w.spin)
            if excess <= 0.0:
                continue
            m = [raw.getDynamicsInfo(*tables.keys[f], physicsClientId=self.cid)[0] if tables.kind[f] == FREE
                 else np.inf for f in (fa, fb)]
            if not (np.isfinite(m[0]) or np.isfinite(m[1])):
                continue
            share_a = 1.0 if not np.isfinite(m[1]) else 0.0 if not np.isfinite(m[0]) else m[1] / (m[0] + m[1])
            for f, v, dv in ((fa, va, share_a * excess), (fb, vb, -(1.0 - share_a) * excess)):
                if dv != 0.0:
                    v += dv * w.normal
                    raw.resetBaseVelocity(tables.keys[f][0], v.tolist(), state.rows[f, ANGULAR_VELOCITY].tolist(),
                                          physicsClientId=self.cid)
            self.stats.bounded += 1

    # ---------------------------------------------------------- collisions
    def _collide(self, paths, i, j, tau):
        """Resolve a pressing contact at tau as a rigid-body collision of the pair at the
        contact patch's points (see ``_impulses``). The free bodies move on from tau with
        their new velocities. Returns the frames whose paths changed."""
        tables = paths.tables
        fa, fb = paths.frame[i], paths.frame[j]
        pair = paths.rows[[i, j]]
        _, n = _core.path_separation(pair, tau)
        A, B = _core.row_poses(pair, np.array([tau, tau]))
        points = _patch_points(A, pair[0, PATH_ROW["half_extents"]], B, pair[1, PATH_ROW["half_extents"]], n)
        a, b = (self._body(paths, f, tau) for f in (fa, fb))
        e, mu = 1.0, 1.0
        for f in (fa, fb):
            info = raw.getDynamicsInfo(*tables.keys[f], physicsClientId=self.cid)
            e, mu = e * info[5], mu * info[1]  # pybullet's combined restitution and friction
        if not _impulses(a, b, points, n, e, min(mu, 10.0)):
            # Nothing approaches, yet the pair presses in: a body turning faster than Bullet
            # turns it (above pi/4 a step its turn is clamped), whose path then leaves the
            # pivot its velocity describes. Slowed to that rate, the two agree again.
            limit = 0.999 * _CLAMP / paths.dt
            slowed = False
            for body in (a, b):
                spin = float(np.linalg.norm(body["w"]))
                if body["inv_m"] > 0.0 and spin > limit:
                    body["w"] = body["w"] * (limit / spin)
                    slowed = True
            if not slowed:
                return []
        changed = []
        for body, f in ((a, fa), (b, fb)):
            if body["inv_m"] > 0.0:
                paths.restart(f, tau, body["v"], body["w"])
                changed.append(f)
        self.stats.held += 1
        return changed

    def _body(self, paths, f, tau):
        """Frame f at tau for a collision: centre of mass, inverse mass and world inverse
        inertia (0 for all but free bodies), velocities v and w."""
        com = paths.com(f, tau)
        if paths.free(f):
            info = raw.getDynamicsInfo(*paths.tables.keys[f], physicsClientId=self.cid)
            inv_m = 1.0 / info[0] if info[0] > 0 else 0.0
            diag = np.asarray(info[2], float)
            inv_d = np.divide(1.0, diag, out=np.zeros(3), where=diag > 0)
            inv_I = com[:3, :3] @ np.diag(inv_d) @ com[:3, :3].T
            inertia = com[:3, :3] @ np.diag(diag) @ com[:3, :3].T
            v, w = paths.twist(f)
        else:
            inv_m, inv_I, inertia = 0.0, np.zeros((3, 3)), np.zeros((3, 3))
            still = paths.status.get(f) == _STOPPED or (paths.tables.kind[f] == STATIC and f not in paths.kinematic)
            row = paths.state_row(f)
            v, w = (np.zeros(3), np.zeros(3)) if still else (row[VELOCITY].copy(), row[ANGULAR_VELOCITY].copy())
        return {"com": com[:3, 3], "inv_m": inv_m, "inv_I": inv_I, "I": inertia, "v": v, "w": w}

    # -------------------------------------------------------------- jumps
    def _jumps(self, jw, tables, state, dt, kinematic, user_moved, events):
        """Free bodies a kinematic jump (the user's teleport before the step) swept into,
        carried with it from the touch to where it stood when the step began: their path
        through the step (Bullet's, in a world where the kinematic body was already there)
        is replaced by a ride on it. Returns {frame: (kinematic frame, centre-of-mass pose
        (4, 4) at the step's start, velocity)}."""
        pushed = {}
        for i, j, tau in sorted(jw.hits, key=lambda h: h[2]):
            k, d = tables.box_frame[jw.boxes[[i, j]]].tolist()
            pair = jw.rows[[i, j]]
            c = self._contact(pair, tau, 1.0)
            if c is None:
                continue
            act = tables.kind[d] == FREE and d not in kinematic and d not in user_moved and d not in pushed
            events.append(CCDEvent(*tables.keys[k], *tables.keys[d], 0.0, 0.0, c.point, c.normal, c.feature,
                                   bool(act), False))
            if act:
                start = _core.frame_poses(state.rows, dt, np.array([d], dtype=np.int64), np.zeros(1))[0]
                X = _carry(pair[0], tau, _pose4(start))
                normal = _moved_with(pair[0], tau, c.normal)
                v = self._push_velocity(tables, state, dt, d, k, X[:3, 3], normal, state.rows[d, VELOCITY])
                pushed[d] = (k, X, v)
        return pushed

    @staticmethod
    def _frame_row(tables, state, dt, k):
        """Path row of kinematic frame k's own motion through the step (box = the frame)."""
        box = tables.frame_boxes[k][0]
        row = _core.path_rows(state.rows, dt, np.array([box], dtype=np.int64), tables.box_frame, tables.X_CS,
                              tables.half)[0]
        row[PATH_ROW["box_in_frame"]] = _IDENTITY
        return row

    # -------------------------------------------------------------- pushes
    def _push_velocity(self, tables, state, dt, d, k, point, normal, v):
        """Frame d's velocity after a collision, at ``point`` along ``normal`` (from the
        pusher), with an immovable body moving as kinematic frame k moved over the whole
        step (its jump and the step's own motion), its own velocity v before."""
        self.stats.pushes += 1
        return bounce(self.cid, tables, d, k, v, self._kinematic_velocity(state, dt, k, point), normal)

    @staticmethod
    def _kinematic_velocity(state, dt, k, point):
        """Velocity at world point ``point`` (after the step) of kinematic frame k's move from
        its pose before the step to its pose after, taken in dt."""
        e0, e1 = state.pose0.get(k, state.rows[k, POSE]), state.rows[k, POSE]
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
        c = _core.path_contact(pair, lo, hi, self.tolerances._core)
        self.stats.outcomes[Outcome.SEPARATED if c is None else c.outcome] += 1
        return c


# ------------------------------------------------------- shared with articulated.py
def place(cid, tables, state, f, pose, v, w):
    """Put free frame f's body at ``pose`` (centre of mass: position, quaternion) with
    velocities v, w, in pybullet and in the frame-state rows."""
    b = tables.keys[f][0]
    raw.resetBasePositionAndOrientation(b, pose[:3].tolist(), pose[3:].tolist(), physicsClientId=cid)
    raw.resetBaseVelocity(b, np.asarray(v).tolist(), np.asarray(w).tolist(), physicsClientId=cid)
    state.rows[f, POSE], state.rows[f, VELOCITY], state.rows[f, ANGULAR_VELOCITY] = pose, v, w


def bounce(cid, tables, d, k, v, v_k, normal):
    """Frame d's velocity (v before) after a collision along ``normal`` (from the pusher)
    with an immovable body moving at v_k there, frame k's: pybullet's combined
    restitution on the approach, nothing if they part already."""
    v = np.array(v, float)
    if np.all(np.isfinite(normal)):
        approach = float(np.dot(v - v_k, normal))
        if approach < 0.0:
            e = (raw.getDynamicsInfo(*tables.keys[d], physicsClientId=cid)[5] *
                 raw.getDynamicsInfo(*tables.keys[k], physicsClientId=cid)[5])
            v = v - (1.0 + e) * approach * normal
    return v


# ---------------------------------------------------------------- geometry
def _goes_wrong(w, s_touch, contact, target):
    """Whether pybullet would resolve the pair (rows w over their window, first touch at
    s_touch, ``contact`` with unit normal n from A towards B) wrongly from where it ends.

    Overlapping: pybullet pushes B out along the least overlap, away from A's centre. That
    is wrong if it points out of A's far side (against n, which turns with the body whose
    face it is), and fragile once B has gone in past half the pair's depth along n (the
    centres then near each other along n: the next overlap can flip it). Apart: wrong if
    they overlapped by ``target`` or more on the way (a contact pybullet never saw: passed
    through, or struck and left)."""
    if not np.all(np.isfinite(contact.normal)):
        return True
    depth, axis = _core.path_separation(w, 1.0)
    if depth <= 0.0:
        return not np.isnan(_core.first_depth(w, s_touch, target))
    n = _normal_at_end(w, s_touch, contact)
    (ca, Ra, ha), (cb, Rb, hb) = (_box_at_end(row) for row in w)
    reach = np.abs(Ra.T @ n) @ ha + np.abs(Rb.T @ n) @ hb
    return float(np.dot(axis, n)) < 0.0 or float(np.dot(cb - ca, n)) < 0.5 * reach


def _normal_at_end(w, s, contact):
    """The contact normal at s, turned to the end of the window with the body whose face
    it is (for an edge-edge contact, the one that turns less)."""
    kind = contact.feature.kind
    angles = [row[PATH_ROW["angle"]][0] for row in w]
    body = 0 if kind == "OV" else 1 if kind == "VO" else int(np.argmin(angles))
    return _moved_with(w[body], s, contact.normal)


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
    return _rotation(row[PATH_ROW["axis"]], (1.0 - s) * row[PATH_ROW["angle"]][0]) @ v


def _carry(row, tau, X):
    """Pose X (4, 4) at tau moved rigidly with the frame of path row ``row`` to its end."""
    frame = row.copy()
    frame[PATH_ROW["box_in_frame"]] = _IDENTITY
    F_tau, F_1 = _core.row_poses(np.stack([frame, frame]), np.array([tau, 1.0]))
    return F_1 @ np.linalg.solve(F_tau, X)


def _patch_points(A, ha, B, hb, n):
    """Candidate points of two touching boxes' contact: the corners of each that lie in
    (or within a thousandth of its size of) the other, their centre, and each box's
    support point towards the other along n (the centre of its face, edge or corner
    that leads)."""
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    pts = []
    for (X, h), (Y, g) in (((A, ha), (B, hb)), ((B, hb), (A, ha))):
        corners = (signs * h) @ X[:3, :3].T + X[:3, 3]
        local = (corners - Y[:3, 3]) @ Y[:3, :3]
        inside = np.all(np.abs(local) <= g + 1e-3 * g.min(), axis=1)
        pts.extend(corners[inside])
    out = [np.mean(pts, axis=0)] if pts else []
    for X, h, d in ((A, ha, n), (B, hb, -n)):
        along = X[:3, :3].T @ d
        lead = np.where(np.abs(along) > 1e-9, np.sign(along), 0.0)  # (cosines) a face or edge leads: its centre
        out.append(X[:3, 3] + X[:3, :3] @ (lead * h))
    return out + pts


def _impulses(a, b, points, n, e, mu, sweeps=12):
    """The collision of bodies a and b (dicts of ``Impacts._body``) touching at
    ``points`` with normal n (from a towards b), in the core (``_core.resolve_collision``:
    sequential impulses with Coulomb friction, perfectly inelastic, then restitution on
    the centres of mass, never raising the kinetic energy). Velocities are updated in
    place; returns whether anything approached."""
    rows = np.array([np.concatenate([body["com"], [body["inv_m"]], body["inv_I"].reshape(-1),
                                     body["I"].reshape(-1), body["v"], body["w"]]) for body in (a, b)])
    approached, out = _core.resolve_collision(rows, np.asarray(points, float).reshape(-1, 3), np.asarray(n, float),
                                              e, mu, sweeps)
    for body, vw in zip((a, b), out):
        body["v"], body["w"] = vw[:3].copy(), vw[3:].copy()
    return approached


def _advance(X, v, w, dt, fraction):
    """Pose X (4, 4) moved on for ``fraction`` of a step of dt with velocities v, w, as
    Bullet integrates (linear; about the fixed axis of w, its angle clamped as Bullet's)."""
    speed = float(np.linalg.norm(w))
    out = X.copy()
    out[:3, 3] = X[:3, 3] + fraction * dt * np.asarray(v)
    if speed > 0.0:
        angle = fraction * _core.bullet_step_angle(speed, dt)
        out[:3, :3] = _rotation(np.asarray(w) / speed, angle) @ X[:3, :3]
    return out


def _still_row(X, row):
    """A row of the same box standing at pose X (its box's pose) through the step."""
    out = row.copy()
    out[PATH_ROW["pose_after"]] = X.reshape(-1)
    out[PATH_ROW["displacement"]] = 0.0
    out[PATH_ROW["axis"]] = 0.0
    out[PATH_ROW["angle"]] = 0.0
    out[PATH_ROW["box_in_frame"]] = _IDENTITY
    return out


def _pose4(p):
    X = np.eye(4)
    q = p[3:] / np.linalg.norm(p[3:])
    x, y, z, w = q
    X[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    X[:3, 3] = p[:3]
    return X


def _pose7(X):
    """Position and quaternion (x, y, z, w) of a rigid pose."""
    R = X[:3, :3]
    t = np.trace(R)
    if t > 0:
        s = 2.0 * np.sqrt(t + 1.0)
        q = [(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, 0.25 * s]
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + R[i, i] - R[j, j] - R[k, k])
        q = [0.0] * 4
        q[i], q[j], q[k], q[3] = 0.25 * s, (R[j, i] + R[i, j]) / s, (R[k, i] + R[i, k]) / s, (R[k, j] - R[j, k]) / s
    return np.concatenate([X[:3, 3], np.array(q) / np.linalg.norm(q)])


def _box_at_end(row):
    """(centre, axes (3, 3) columns, half extents) of a path row's box after the step."""
    X = _core.row_poses(row[None], np.ones(1))[0]
    return X[:3, 3], X[:3, :3], row[PATH_ROW["half_extents"]]


def _rotation(axis, angle):
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)
