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

import numpy as np

from .. import _core
from ._hooks import raw
from .events import CCDEvent
from .layout import ANGULAR_VELOCITY, PATH_ROW, POSE, VELOCITY
from .world import FREE

__all__ = ["Impacts"]

_HOLD_FRACTION = 0.01  # a stop this close to the start of a touching pair's window: pybullet left it approaching
_MOVING, _STOPPED, _CARRIED = 0, 1, 2
_IDENTITY = np.eye(4).reshape(-1)


class _Paths:
    """The frames of a sweep on their effective paths: Bullet's, or stopped at a time, or
    carried from a time by another frame's motion. Rows are the sweep's path rows,
    rewritten as paths change; all are over the whole step (tau in [0, 1])."""

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
        self.stop_time = {}  # stopped frame -> tau
        self.carry = {}  # carried frame -> (carrier's frame row (42,), rel (4, 4): CoM in carrier frame)
        self.carried_from = {}  # carried frame -> the frame that pushed it
        self.kinematic = kinematic

    def driver(self, f):
        """The kinematic frame that moves f (f itself, or its carrier's driver)."""
        while f in self.carried_from:
            f = self.carried_from[f]
        return f

    def pushes(self, f) -> bool:
        """f moves on regardless: a kinematic frame, or one carried by it."""
        return f in self.kinematic or self.status.get(f) == _CARRIED

    def stoppable(self, f) -> bool:
        return self.tables.kind[f] == FREE and f not in self.kinematic and self.status.get(f) == _MOVING

    def com(self, f, tau) -> np.ndarray:
        """(4, 4) centre-of-mass pose of frame f at tau on its effective path."""
        if self.status.get(f) == _CARRIED:
            carrier, rel = self.carry[f]
            return _core.row_poses(carrier[None], np.array([tau]))[0] @ rel
        t = self.stop_time.get(f, tau)
        p = _core.frame_poses(self.state.rows, self.dt, np.array([f], dtype=np.int64), np.array([t]))[0]
        return _pose4(p)

    def stop(self, f, tau):
        """Frame f stands still from tau on."""
        for r in self.rows_of[f]:
            X = _core.row_poses(self.rows[[r]], np.array([tau]))[0]
            self.rows[r] = _still_row(X, self.rows[r])
        self.stop_time[f] = tau
        self._changed(f, _STOPPED, tau)

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

    def resolve(self, sw, jw, tables, state, dt, user_moved, gravity):
        """Events of the step's sweep ``sw`` and of the kinematic jumps' sweep ``jw`` (either
        may be None), with the rewinds and pushes applied. Returns (events, tau_world):
        tau_world is the earliest rewind (1 if none), where the exact-time mode stops the
        world. ``user_moved``: frames the user teleported since the last step (never
        pushed: their pose is the user's)."""
        kinematic = set(state.kinematic)
        events, v_new = [], {}
        pushed = self._jumps(jw, tables, state, dt, kinematic, user_moved, events) if jw is not None else {}
        paths = None
        if sw is not None and sw.hits:
            paths = _Paths(sw, tables, state, dt, kinematic)
        for d, (k, start) in pushed.items():  # then it rides its kinematic body through the step
            row_k = self._frame_row(tables, state, dt, k)
            if paths is not None and d in paths.rows_of:
                paths.carried_by(d, row_k, 0.0, com=start)
                paths.carried_from[d] = k
            else:
                self._place(tables, state, d, _pose7(_carry(row_k, 0.0, start)), state.rows[d, VELOCITY],
                            state.rows[d, ANGULAR_VELOCITY])
        if paths is not None:
            self._time_order(paths, sw, user_moved, events, v_new)
        self.stats.contacts += len(events)
        stop = dict(paths.stop_time) if paths else {}
        tau_world = min(stop.values(), default=1.0)
        if self.exact_time and stop:
            # The whole world goes to the earliest contact: every free body not carried.
            carried = set(paths.carry)
            stop = {f: tau_world for f in np.flatnonzero(tables.kind == FREE).tolist() if f not in carried
                    and f not in pushed}
            state.read_poses(state.stale(sorted(stop)))
        self._rewind(tables, state, dt, stop, v_new, gravity)
        for d in paths.carry if paths is not None else ():
            self._place(tables, state, d, _pose7(paths.com(d, 1.0)), state.rows[d, VELOCITY],
                        state.rows[d, ANGULAR_VELOCITY])
        return events, tau_world

    # -------------------------------------------------------- time order
    def _time_order(self, paths, sw, user_moved, events, v_new):
        """Take the contacts in time order, acting where pybullet would go wrong, and sweep
        again the pairs of every body whose path changed."""
        pairs_of = {}
        for q, (i, j) in enumerate(sw.pairs.tolist()):
            for r in (i, j):
                pairs_of.setdefault(paths.frame[r], []).append(q)
        heap = []
        for i, j, tau in sw.hits:
            q = sw.pair_index[(i, j)]
            self._queue(heap, paths, q, i, j, 0.0, tau)
        while heap:
            tau_r, _, q, i, j, versions, info = heapq.heappop(heap)
            fa, fb = paths.frame[i], paths.frame[j]
            if versions != (paths.version[fa], paths.version[fb]):
                since = max(paths.since[fa], paths.since[fb])
                touch = self._first_touch(paths, i, j, since)
                if touch is not None:
                    self._queue(heap, paths, q, i, j, since, touch)
                continue
            changed = self._act(paths, i, j, tau_r, info, user_moved, events, v_new)
            for f in changed:
                for q2 in pairs_of.get(f, ()):
                    i2, j2 = sw.pairs[q2]
                    touch = self._first_touch(paths, i2, j2, tau_r)
                    if touch is not None:
                        self._queue(heap, paths, q2, i2, j2, tau_r, touch)

    def _first_touch(self, paths, i, j, lo):
        """The first touch (a step fraction) of rows i and j over [lo, 1], or None."""
        if lo >= 1.0:
            return None
        w = _core.window_rows(paths.rows[[i, j]], lo, 1.0)
        tau, solves = _core.first_touches(w, np.array([[0, 1]], dtype=np.int64), self.fit_tolerance,
                                          self.tolerances._core)
        self.stats.solver_rows += solves
        return None if np.isnan(tau[0]) else lo + float(tau[0]) * (1.0 - lo)

    def _queue(self, heap, paths, q, i, j, lo, touch):
        """Judge the pair's contact (first touch ``touch`` in the window [lo, 1]) and queue
        it at the time to act (or at its touch, to be reported only)."""
        fa, fb = paths.frame[i], paths.frame[j]
        info = self._judge(paths, i, j, lo, touch)
        heapq.heappush(heap, (info["act_at"], id(info), q, i, j, (paths.version[fa], paths.version[fb]), info))

    def _judge(self, paths, i, j, lo, touch):
        """What the pair (rows i, j) needs: {"act_at": tau, "action": None | "stop" |
        "push", "initial", "touch", "window"}."""
        fa, fb = paths.frame[i], paths.frame[j]
        w = _core.window_rows(paths.rows[[i, j]], lo, 1.0)
        s_touch = (touch - lo) / (1.0 - lo)
        initial = s_touch == 0.0
        c = self._contact(w, s_touch, 1.0)
        info = {"act_at": touch, "action": None, "initial": initial, "touch": touch, "window": (lo, 1.0),
                "contact": c}
        if c is None:  # the fit's allowance touched, the boxes did not: nothing happened
            return info
        push_a = paths.pushes(fa) and paths.stoppable(fb)
        push_b = paths.pushes(fb) and paths.stoppable(fa)
        if push_a or push_b:
            normal = _normal_at_end(w, s_touch, c)
            if not _overtaken(w if push_a else w[::-1], normal if push_a else -normal, self.penetration):
                return info
            action = "push"
        elif paths.stoppable(fa) or paths.stoppable(fb):
            action = "stop"
        else:
            return info
        d0 = float(_core.path_depth(w, np.zeros(1))[0]) if initial else 0.0
        target = (max(d0, 0.0) + self.penetration) if initial else self.penetration
        if action == "stop" and not _goes_wrong(w, s_touch, c, target):
            return info
        s_act = _core.first_depth(w, s_touch, target)
        if np.isnan(s_act):
            if action == "stop":  # never as deep as that: a graze
                return info
            s_act = s_touch
        info.update(action=action, act_at=lo + s_act * (1.0 - lo), pusher_first=push_a)
        return info

    def _act(self, paths, i, j, tau, info, user_moved, events, v_new):
        """Report the contact and act on it; returns the frames whose paths changed."""
        tables, state = paths.tables, paths.state
        fa, fb = paths.frame[i], paths.frame[j]
        lo, hi = info["window"]
        c = info["contact"]
        if c is None:
            return []
        t_event = lo + c.t * (hi - lo)
        changed, acted = [], False
        if info["action"] == "push":
            k, d = (fa, fb) if info["pusher_first"] else (fb, fa)
            row_k = paths.rows[i if info["pusher_first"] else j]
            if d not in user_moved:
                paths.carried_from[d] = k
                normal = _moved_with(row_k, tau, c.normal if info["pusher_first"] else -c.normal)
                paths.carried_by(d, row_k, tau)
                driver = paths.driver(k)
                self._push_velocity(tables, state, paths.dt, d, driver, paths.com(d, 1.0)[:3, 3], normal)
                changed, acted = [d], True
        elif info["action"] == "stop":
            for f in (fa, fb):
                if paths.stoppable(f):
                    paths.stop(f, tau)
                    changed.append(f)
            acted = bool(changed)
            if acted and info["initial"] and tau - info["touch"] < _HOLD_FRACTION:
                self._release_held(tables, state, fa, fb, c.normal, v_new)
        events.append(CCDEvent(*tables.keys[fa], *tables.keys[fb], t_event, t_event * paths.dt, c.point, c.normal,
                               c.feature, acted, info["initial"]))
        return changed

    # -------------------------------------------------------------- jumps
    def _jumps(self, jw, tables, state, dt, kinematic, user_moved, events):
        """Free bodies a kinematic jump (the user's teleport before the step) swept into,
        carried with it from the touch to where it stood when the step began: their path
        through the step (Bullet's, in a world where the kinematic body was already there)
        is replaced by a ride on it. Returns {frame: (kinematic frame, centre-of-mass pose
        (4, 4) at the step's start)}."""
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
                pushed[d] = (k, X)
                normal = _moved_with(pair[0], tau, c.normal)
                self._push_velocity(tables, state, dt, d, k, X[:3, 3], normal)
        return pushed

    @staticmethod
    def _frame_row(tables, state, dt, k):
        """Path row of kinematic frame k's own motion through the step (box = the frame)."""
        box = tables.frame_boxes[k][0]
        row = _core.path_rows(state.rows, dt, np.array([box], dtype=np.int64), tables.box_frame, tables.X_CS,
                              tables.half)[0]
        row[PATH_ROW["box_in_frame"]] = _IDENTITY
        return row

    # ------------------------------------------------------------- rewinds
    def _rewind(self, tables, state, dt, stop, v_new, gravity):
        if not stop:
            return
        frames = sorted(stop)
        poses = _core.frame_poses(state.rows, dt, np.array(frames, dtype=np.int64), np.array([stop[f] for f in frames]))
        for f, pose in zip(frames, poses):
            # The reset zeroes the velocity: give back the post-solve one. In exact-time
            # mode the rest of the step is simulated again, and it will add its gravity
            # again: take that part out here.
            v = v_new.get(f, state.rows[f, VELOCITY])
            if self.exact_time:
                v = v - gravity * (1.0 - stop[f]) * dt
            self._place(tables, state, f, pose, v, state.rows[f, ANGULAR_VELOCITY])
        self.stats.rewinds += len(frames)

    def _release_held(self, tables, state, fa, fb, normal, v_new):
        """A contact pybullet left approaching: resolved as a 1-D collision of the two
        centres of mass along the normal, with pybullet's combined restitution (momentum
        is conserved; spins are left to pybullet)."""
        if not np.all(np.isfinite(normal)):
            return
        m, e, v = [], 1.0, []
        for f in (fa, fb):
            info = raw.getDynamicsInfo(*tables.keys[f], physicsClientId=self.cid)
            m.append(info[0] if tables.kind[f] == FREE else np.inf)
            e *= info[5]
            v.append(v_new.get(f, state.rows[f, VELOCITY]))
        approach = float(np.dot(v[1] - v[0], normal))  # < 0: B moves towards A
        if approach >= 0.0 or not (np.isfinite(m[0]) or np.isfinite(m[1])):
            return
        w_a = 1.0 if not np.isfinite(m[1]) else (0.0 if not np.isfinite(m[0]) else m[1] / (m[0] + m[1]))
        dv = (1.0 + e) * approach * normal
        if tables.kind[fa] == FREE:
            v_new[fa] = v[0] + w_a * dv
        if tables.kind[fb] == FREE:
            v_new[fb] = v[1] - (1.0 - w_a) * dv
        self.stats.held += 1

    # -------------------------------------------------------------- pushes
    def _push_velocity(self, tables, state, dt, d, k, point, normal):
        """Give frame d (at ``point`` after the step) the normal velocity of a collision with
        an immovable body moving as kinematic frame k moved over the whole step (its jump
        and the step's own motion)."""
        v_k = self._kinematic_velocity(tables, state, dt, k, point)
        v = state.rows[d, VELOCITY].copy()
        if np.all(np.isfinite(normal)):
            approach = float(np.dot(v - v_k, normal))
            if approach < 0.0:
                e = (raw.getDynamicsInfo(*tables.keys[d], physicsClientId=self.cid)[5] *
                     raw.getDynamicsInfo(*tables.keys[k], physicsClientId=self.cid)[5])
                v = v - (1.0 + e) * approach * normal
        state.rows[d, VELOCITY] = v
        self.stats.pushes += 1

    @staticmethod
    def _kinematic_velocity(tables, state, dt, k, point):
        """Velocity at world point ``point`` (after the step) of kinematic frame k's move from
        its pose before the step to its pose after, taken in dt."""
        e0, e1 = state.pose0.get(k, state.rows[k, POSE]), state.rows[k, POSE]
        one = np.zeros(1, dtype=np.int64)
        move = _core.path_rows_between(e0[None], e1[None], one, one, np.eye(4)[None], np.zeros((1, 3)))[0]
        omega = move[PATH_ROW["axis"]] * move[PATH_ROW["angle"]][0] / dt
        return move[PATH_ROW["displacement"]] / dt + np.cross(omega, point - e1[:3])

    def _place(self, tables, state, f, pose, v, w):
        b = tables.keys[f][0]
        raw.resetBasePositionAndOrientation(b, pose[:3].tolist(), pose[3:].tolist(), physicsClientId=self.cid)
        raw.resetBaseVelocity(b, np.asarray(v).tolist(), np.asarray(w).tolist(), physicsClientId=self.cid)
        state.rows[f, POSE], state.rows[f, VELOCITY] = pose, v

    def _contact(self, pair, lo, hi):
        """The first touch of a pair (path rows) in [lo, hi] (step fractions): one solve on
        a quadratic refit of the exact path over that window, the boxes inflated by the
        refit's error bound so that a touch cannot be missed; None if they stay apart
        (the first touch found on the step's fit was within that fit's allowance only)."""
        return _core.path_contact(pair, lo, hi, self.tolerances._core)


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
