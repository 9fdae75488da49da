"""Drop-in tunneling prevention for pybullet worlds (the only module that imports pybullet).

``BoxCCD.step()`` replaces ``p.stepSimulation()``:

1. pybullet takes its step as usual.
2. The step is swept: every box collision shape that moved more than
   ``sweep_threshold`` of its own smallest extent gets its exact within-step
   path, rebuilt from the pose after the step and the post-solve velocities
   (Bullet moves the centre of mass linearly and turns it about a fixed axis:
   ``_core/step_path.hpp``), fitted by quadratic motions (split into pieces and
   the box inflated by the fit's error bound, so the fit is conservative). The
   per-step numerics run in the core; this module reads and writes pybullet.
3. Broad phase: the fast boxes' swept bounds go to pybullet's own broad phase
   (widened by the largest reach of any slow body); the boxes it returns are
   paired with them by swept bounds, and the pairs go to the batch solver.
4. Rewind: for each pair that touched, the first pose on Bullet's own path at
   which the sharp boxes overlap by ``penetration`` (2e-7 m by default: Bullet's
   box-box detector makes a contact only from the touching pose on, and a vertex
   at exactly zero gap can be missed) is found, and the free bodies of the pair
   are put there with their post-solve velocities. The next step's contact solver
   handles the impact, so nothing ends on the far side.

Why sweep after the step rather than predict before it: the path depends on the
post-solve velocity, which is known only after pybullet solved the step's
contacts; afterwards the path is exact, not predicted.

Frames: ``getCollisionShapeData`` gives a box's full extents and its frame
relative to the link's centre-of-mass frame; ``getBasePositionAndOrientation``
and ``getLinkState(...)[0:2]`` give centre-of-mass frames. Maximal-coordinate
bodies do not answer ``getCollisionShapeData``: register their boxes with
``BoxCCD.register_box``. pybullet cannot report collision filters back, so
filters set directly on pybullet are invisible here: set them through
``BoxCCD.set_collision_filter_pair`` (which also calls pybullet).
"""

from __future__ import annotations

import time
import uuid
from dataclasses import dataclass, field, replace
from itertools import chain

import numpy as np
import pybullet as p

from . import _core
from .geometry import Box
from .motion import quat_to_matrix
from .solver import DEFAULT_TOLERANCES, Contact, Feature, Outcome, Tolerances

__all__ = ["BoxCCD", "CCDEvent", "CCDStats"]


@dataclass(frozen=True)
class CCDEvent:
    """A contact found by sweeping a step.

    ``tau`` is the contact's fraction of the step (0 = start, 1 = end) and ``time``
    the same in seconds after the step started; ``point`` and ``normal`` (unit,
    from box A towards box B) are world coordinates at the first touch;
    ``feature`` names the BMS plane; ``rewound`` says whether the free bodies of
    the pair were put back at the contact (False for a graze shallower than the
    rewind depth, or when neither body can be rewound); ``initial`` marks a pair
    that already touched when the step began and pressed deeper during it (its
    rewind allows an overlap of up to a quarter of the thinner box).
    """

    body_a: int
    link_a: int
    body_b: int
    link_b: int
    tau: float
    time: float
    point: np.ndarray
    normal: np.ndarray
    feature: Feature
    rewound: bool
    initial: bool


@dataclass
class CCDStats:
    """Counters since construction (``steps``, ``tracked_boxes`` is the current count)."""

    steps: int = 0
    tracked_boxes: int = 0
    swept_boxes: int = 0
    candidate_pairs: int = 0
    solver_rows: int = 0  # solver calls: a pair whose step is split into n pieces counts up to n
    contacts: int = 0
    rewinds: int = 0
    held: int = 0  # contacts pybullet left unresolved, released by BoxCCD._release_held
    seconds: dict = field(default_factory=lambda: dict.fromkeys(
        ("step", "state", "broad_phase", "solve", "rewind"), 0.0))


@dataclass
class _Frames:
    """Rigid frames (body, link) that carry boxes, and their boxes (parallel arrays)."""

    body: np.ndarray  # (F,) int
    link: np.ndarray  # (F,) int
    static: np.ndarray  # (F,) bool: never moves (mass-0 body without joints)
    rewindable: np.ndarray  # (F,) bool: the base of a free single rigid body
    box_frame: np.ndarray  # (B,) int: index into the frames
    half: np.ndarray  # (B, 3) half extents
    X_CS: np.ndarray  # (B, 4, 4): box frame in its frame's centre-of-mass frame
    radius: np.ndarray  # (B,) farthest box point from the centre of mass


class BoxCCD:
    """Continuous collision detection for every box in a pybullet world.

    Parameters
    ----------
    physics_client_id : int
    sweep_threshold : float
        A box is swept when its fastest point moves more than this fraction of the
        box's smallest full extent in a step (a slower box overlaps anything it
        meets in some step, so pybullet's discrete contacts catch it). Default 0.25.
    fit_tolerance : float
        Largest allowed error of the quadratic rotation fit, as a fraction of the
        box's smallest half extent; a step is split into 2, 4, ... pieces until it
        holds, and the box is inflated by what remains. Default 0.05.
    penetration : float
        Depth (m) of the rewound overlap of the sharp boxes. Default 2e-7.
    self_collision_bodies : iterable of int
        Bodies whose links collide with each other (pybullet cannot report it).
    exact_time : bool
        Instead of rewinding only the bodies that touched, stop every free body at the
        step's earliest contact and simulate the rest of the step from there (up to
        ``max_partial_steps`` times a step). Articulated bodies are not rewound.
    tolerances : Tolerances
        Solver tolerances.
    """

    def __init__(self, physics_client_id: int = 0, *, sweep_threshold: float = 0.25,
                 fit_tolerance: float = 0.05, penetration: float = 2e-7, self_collision_bodies=(),
                 exact_time: bool = False, max_partial_steps: int = 8,
                 tolerances: Tolerances = DEFAULT_TOLERANCES):
        self.cid = physics_client_id
        self.sweep_threshold = float(sweep_threshold)
        self.fit_tolerance = float(fit_tolerance)
        self.penetration = float(penetration)
        self.hold_fraction = 0.01
        self.exact_time = bool(exact_time)
        self._gravity = np.zeros(3)  # read from pybullet at every step
        self.max_partial_steps = int(max_partial_steps)
        self.self_collision_bodies = set(int(b) for b in self_collision_bodies)
        self.tolerances = tolerances
        self.stats = CCDStats()
        self._filtered: set = set()
        self._registered: dict = {}  # (body, link) -> list of (half, X_CS)
        self._non_box: list = []
        self._unreadable: list = []
        self._world_key = None
        # A mark this instance leaves in the world (pybullet user data on the first
        # body): p.resetSimulation() removes it, so a rebuilt world is rediscovered
        # even when it has the same bodies' count and ids.
        self._mark = f"bullet_boxccd.{uuid.uuid4().hex}"
        self._mark_id = -1
        self.refresh()

    # ------------------------------------------------------------ discovery
    def _world_signature(self):
        """Changes when bodies are added or removed, or the world is reset."""
        cid = self.cid
        n = p.getNumBodies(physicsClientId=cid)
        if not n:
            return (0,)
        marked = self._mark_id >= 0 and p.getUserData(self._mark_id, physicsClientId=cid) == self._mark.encode()
        return n, p.getBodyUniqueId(n - 1, physicsClientId=cid), marked

    def register_box(self, body: int, link: int, half_extents, position=(0.0, 0.0, 0.0),
                     orientation=(0.0, 0.0, 0.0, 1.0)) -> None:
        """Declare a box on a frame whose shapes pybullet cannot report (maximal-coordinate
        bodies). ``position``/``orientation`` place the box in the link's
        centre-of-mass frame, as ``getCollisionShapeData`` would."""
        X = np.eye(4)
        X[:3, :3] = quat_to_matrix(orientation)
        X[:3, 3] = position
        Box.centered(half_extents)  # validates
        self._registered.setdefault((int(body), int(link)), []).append((np.asarray(half_extents, float), X))
        self.refresh()

    def set_collision_filter_pair(self, body_a: int, body_b: int, link_a: int, link_b: int, enable: bool) -> None:
        """``p.setCollisionFilterPair`` that the plugin also honours."""
        p.setCollisionFilterPair(body_a, body_b, link_a, link_b, int(enable), physicsClientId=self.cid)
        key = _pair_key((body_a, link_a), (body_b, link_b))
        if enable:
            self._filtered.discard(key)
        else:
            self._filtered.add(key)

    def refresh(self) -> None:
        """Rediscover every box in the world (called automatically when bodies are added or
        removed, and after ``p.resetSimulation()``)."""
        cid = self.cid
        body, link, static, rewind, box_frame, half, X_CS = [], [], [], [], [], [], []
        self._non_box, self._unreadable = [], []
        for i in range(p.getNumBodies(physicsClientId=cid)):
            b = p.getBodyUniqueId(i, physicsClientId=cid)
            n_joints = p.getNumJoints(b, physicsClientId=cid)
            for lk in range(-1, n_joints):
                shapes = self._shapes(b, lk)
                if not shapes:
                    continue
                base_mass = p.getDynamicsInfo(b, -1, physicsClientId=cid)[0]
                body.append(b)
                link.append(lk)
                static.append(n_joints == 0 and base_mass == 0.0)
                rewind.append(n_joints == 0 and base_mass > 0.0)
                for h, X in shapes:
                    box_frame.append(len(body) - 1)
                    half.append(h)
                    X_CS.append(X)
        half = np.array(half, dtype=float).reshape(-1, 3)
        X_CS = np.array(X_CS, dtype=float).reshape(-1, 4, 4)
        radius = np.linalg.norm(X_CS[:, :3, 3], axis=1) + np.linalg.norm(half, axis=1)
        self._frames = _Frames(np.array(body, np.int64), np.array(link, np.int64), np.array(static, bool),
                               np.array(rewind, bool), np.array(box_frame, np.int64), half, X_CS, radius)
        self._keys = [(int(b), int(lk)) for b, lk in zip(body, link)]  # plain ints for the pybullet calls
        self._frame_index = {key: i for i, key in enumerate(self._keys)}
        self._dynamic = np.flatnonzero(~self._frames.static).tolist()
        self._frame_boxes = [[] for _ in body]  # frame -> its boxes
        for b, f in enumerate(box_frame):
            self._frame_boxes[f].append(b)
        # Per frame: position, quaternion, v, w (the core's frame state); poses
        # are read when needed, velocities of the dynamic frames at every step.
        self._state = np.zeros((len(body), 13))
        self._state[:, 6] = 1.0
        static_frames = np.flatnonzero(self._frames.static).tolist()
        self._state[static_frames, :7] = self._read_poses(static_frames)
        self._frame_flags = (self._frames.static.astype(np.uint8) |
                             np.isin(self._frames.body, list(self.self_collision_bodies)).astype(np.uint8) << 1)
        # A box is swept when its fastest point moves more than this in a step.
        self._sweep_reach = self.sweep_threshold * 2.0 * half.min(axis=1)
        self.stats.tracked_boxes = len(half)
        if p.getNumBodies(physicsClientId=cid):
            first = p.getBodyUniqueId(0, physicsClientId=cid)
            self._mark_id = p.addUserData(first, self._mark, self._mark, physicsClientId=cid)
        self._world_key = self._world_signature()

    def _shapes(self, b, lk):
        if (b, lk) in self._registered:
            return self._registered[(b, lk)]
        try:
            data = p.getCollisionShapeData(b, lk, physicsClientId=self.cid)
        except p.error:
            if p.getDynamicsInfo(b, lk, physicsClientId=self.cid)[10] == 1:  # maximal coordinates
                self._unreadable.append((b, lk))
            return []
        out = []
        for d in data:
            if d[2] != p.GEOM_BOX:
                self._non_box.append((b, lk, d[2]))
                continue
            X = np.eye(4)
            X[:3, :3] = quat_to_matrix(d[6])
            X[:3, 3] = d[5]
            out.append((0.5 * np.asarray(d[3], float), X))
        return out

    def summary(self) -> str:
        """What is tracked, what is left to pybullet, and what needs registering."""
        names = {p.GEOM_SPHERE: "sphere", p.GEOM_CAPSULE: "capsule", p.GEOM_CYLINDER: "cylinder",
                 p.GEOM_MESH: "mesh", p.GEOM_PLANE: "plane"}
        fr = self._frames
        lines = [f"BoxCCD: {len(fr.half)} boxes on {len(fr.body)} links of "
                 f"{len(set(fr.body.tolist()))} bodies ({int(fr.static.sum())} static links)"]
        for b, lk, g in self._non_box:
            lines.append(f"  left to pybullet: body {b} link {lk}: {names.get(g, g)}")
        for b, lk in self._unreadable:
            lines.append(f"  maximal-coordinate body {b} link {lk}: shapes unreadable, use register_box()")
        return "\n".join(lines)

    # ------------------------------------------------------------ per step
    def _read_velocities(self, frames):
        """(F, 6) v and w (world, centre of mass) of the given frame indices."""
        cid, keys = self.cid, self._keys
        get_v, get_link = p.getBaseVelocity, p.getLinkState
        vel = [get_v(keys[f][0], physicsClientId=cid) if keys[f][1] == -1 else
               get_link(keys[f][0], keys[f][1], computeLinkVelocity=1, physicsClientId=cid)[6:8] for f in frames]
        flat = chain.from_iterable(chain.from_iterable(vel))  # faster than converting nested tuples
        return np.fromiter(flat, dtype=float, count=6 * len(frames)).reshape(len(frames), 6)

    def _read_poses(self, frames):
        """(F, 7) centre-of-mass positions and quaternions (x, y, z, w) of the given frame indices."""
        cid, keys = self.cid, self._keys
        get_pose, get_link = p.getBasePositionAndOrientation, p.getLinkState
        st = [get_pose(keys[f][0], physicsClientId=cid) if keys[f][1] == -1 else
              get_link(keys[f][0], keys[f][1], physicsClientId=cid)[:2] for f in frames]
        flat = chain.from_iterable(chain.from_iterable(st))
        return np.fromiter(flat, dtype=float, count=7 * len(frames)).reshape(len(frames), 7)

    def step(self) -> list:
        """``p.stepSimulation()`` followed by the sweep and rewind; returns this step's contacts."""
        t_start = time.perf_counter()
        if self._world_signature() != self._world_key:
            self.refresh()
        params = p.getPhysicsEngineParameters(physicsClientId=self.cid)
        if params.get("numSubSteps", 0) > 1:
            raise ValueError("BoxCCD sweeps whole steps: set numSubSteps to 0 or 1 (it replaces substepping)")
        dt = params["fixedTimeStep"]
        self._gravity = np.array([params.get(f"gravityAcceleration{c}", 0.0) for c in "XYZ"])
        events, elapsed = [], 0.0
        try:
            for _ in range(1 + (self.max_partial_steps if self.exact_time else 0)):
                p.stepSimulation(physicsClientId=self.cid)
                t_sim = time.perf_counter()
                self.stats.seconds["step"] += t_sim - t_start
                found, tau = self._sweep(dt - elapsed, t_sim)
                events += [_shifted(e, elapsed, dt) for e in found]
                if not self.exact_time or tau >= 1.0:
                    break
                # Exact-time mode: the world stopped at tau of this (partial) step;
                # simulate the rest of the step from there.
                elapsed += tau * (dt - elapsed)
                if dt - elapsed <= 1e-9 * dt:
                    break
                p.setPhysicsEngineParameter(fixedTimeStep=dt - elapsed, physicsClientId=self.cid)
                t_start = time.perf_counter()
        finally:
            if elapsed:
                p.setPhysicsEngineParameter(fixedTimeStep=dt, physicsClientId=self.cid)
        self.stats.steps += 1
        return events

    def _sweep(self, dt, t0):
        fr, st, S = self._frames, self.stats, self._state
        if not len(fr.half):
            return [], 1.0
        S[self._dynamic, 7:] = self._read_velocities(self._dynamic)
        # Fast boxes: the farthest point moves more than the threshold.
        fast, slack = _core.fast_boxes(S, dt, fr.box_frame, fr.radius, self._sweep_reach)
        if not len(fast):
            st.seconds["state"] += time.perf_counter() - t0
            return [], 1.0
        # Poses: the fast frames, then only the partners pybullet's own broad phase
        # finds near their swept bounds (slow bodies can be anywhere within their
        # reach of the pose it knows, so the query is widened by the largest).
        fast_frames = sorted(set(fr.box_frame[fast].tolist()))
        S[fast_frames, :7] = self._read_poses(fast_frames)
        rows = _core.path_rows(S, dt, fast, fr.box_frame, fr.X_CS, fr.half)
        bounds = _core.swept_bounds(rows)
        near = set(fast_frames)
        for b in (bounds + _WIDEN * (slack + 1e-9)).tolist():
            found = p.getOverlappingObjects(b[:3], b[3:], physicsClientId=self.cid) or ()
            near.update(self._frame_index[key] for key in found if key in self._frame_index)
        # Static partners are read too: a mass-0 body can be moved by the user
        # (a kinematic obstacle), and pybullet's broad phase already sees it there.
        partners = sorted(near.difference(fast_frames))
        if partners:
            S[partners, :7] = self._read_poses(partners)
        t1 = time.perf_counter()
        st.seconds["state"] += t1 - t0
        st.swept_boxes += len(fast)
        boxes = np.array(fast.tolist() + [b for f in partners for b in self._frame_boxes[f]], dtype=np.int64)
        if len(boxes) > len(fast):
            more = _core.path_rows(S, dt, boxes[len(fast):], fr.box_frame, fr.X_CS, fr.half)
            rows, bounds = np.concatenate([rows, more]), np.concatenate([bounds, _core.swept_bounds(more)])
        pairs = _core.candidate_pairs(bounds, len(fast), fr.box_frame[boxes], fr.body, self._frame_flags)
        if self._filtered and len(pairs):
            pairs = pairs[[self._pair_allowed(*boxes[pr].tolist()) for pr in pairs]]
        t2 = time.perf_counter()
        st.seconds["broad_phase"] += t2 - t1
        st.candidate_pairs += len(pairs)
        if not len(pairs):
            return [], 1.0
        # First contact of each pair on the fitted (conservative) motions.
        tau, solves = _core.first_touches(rows, pairs, self.fit_tolerance, self.tolerances._core)
        st.solver_rows += solves
        hit = np.flatnonzero(~np.isnan(tau))
        hits = [(i, j, t) for (i, j), t in zip(pairs[hit].tolist(), tau[hit].tolist())]
        t3 = time.perf_counter()
        st.seconds["solve"] += t3 - t2
        events, tau_world = self._resolve(rows, boxes, hits, dt, near)
        st.seconds["rewind"] += time.perf_counter() - t3
        return events, tau_world

    def _pair_allowed(self, a, b):
        """Not disabled by set_collision_filter_pair (boxes a, b)."""
        fa, fb = self._frames.box_frame[[a, b]]
        return _pair_key(self._keys[fa], self._keys[fb]) not in self._filtered

    def _resolve(self, rows, boxes, hits, dt, known):
        """Events and rewinds: each free body goes to its earliest rewind time.
        ``rows`` are the path rows of ``boxes``; ``hits`` (row a, row b, first
        touch); ``known``: the frames whose poses were read this step (the others
        are read here if exact-time mode stops them too)."""
        fr, st, S = self._frames, self.stats, self._state
        stop = {}
        found = []
        for i, j, tau in sorted(hits, key=lambda h: h[2]):
            pair = rows[[i, j]]
            tau_b = self._rewind_time(pair, boxes[[i, j]], tau)
            if tau == 0.0 and tau_b is None:
                continue  # touching at the start and not deepening: pybullet's own contact
            fa, fb = fr.box_frame[boxes[[i, j]]].tolist()
            found.append((pair, fa, fb, tau, tau_b))
            if tau_b is None:
                continue
            for f in (fa, fb):
                if fr.rewindable[f] and tau_b < stop.get(f, np.inf):
                    stop[f] = tau_b
        events = []
        v_new = {}
        for pair, fa, fb, tau, tau_b in found:
            c = self._contact(pair, tau, 1.0 if tau_b is None else tau_b)
            rewound = tau_b is not None and tau_b in (stop.get(fa), stop.get(fb))
            if rewound and tau == 0.0 and tau_b < self.hold_fraction:
                self._release_held(fa, fb, c.normal, v_new)
            events.append(CCDEvent(*self._keys[fa], *self._keys[fb], c.t, c.t * dt, c.point, c.normal, c.feature,
                                   rewound, tau == 0.0))
        st.contacts += len(events)
        tau_world = min(stop.values(), default=1.0)
        if self.exact_time and stop:
            # The whole world goes to the earliest contact: every free body.
            stop = {int(f): tau_world for f in np.flatnonzero(fr.rewindable)}
            unread = sorted(set(stop) - set(known))
            if unread:
                S[unread, :7] = self._read_poses(unread)
        if stop:
            frames = sorted(stop)
            poses = _core.frame_poses(S, dt, np.array(frames, dtype=np.int64), np.array([stop[f] for f in frames]))
            for f, pose in zip(frames, poses.tolist()):
                b = self._keys[f][0]
                p.resetBasePositionAndOrientation(b, pose[:3], pose[3:], physicsClientId=self.cid)
                # The reset zeroes the velocity: give back the post-solve one. In
                # exact-time mode the rest of the step is simulated again, and it
                # will add its gravity again: take that part out here.
                v = v_new.get(f, S[f, 7:10])
                if self.exact_time:
                    v = v - self._gravity * (1.0 - stop[f]) * dt
                p.resetBaseVelocity(b, v.tolist(), S[f, 10:13].tolist(), physicsClientId=self.cid)
            st.rewinds += len(frames)
        return events, tau_world

    def _release_held(self, fa, fb, normal, v_new):
        """A contact pybullet left unresolved: the pair touched when the step began and
        still presses in almost at once (a fast-spinning body pivoting on a vertex,
        whose contact point pybullet saw separating). Held in place it would stay
        stuck, so the approach along the contact normal is resolved here as a 1-D
        collision of the two centres of mass with pybullet's combined restitution
        (momentum is conserved; spins are left to pybullet)."""
        fr, cid = self._frames, self.cid
        if not np.all(np.isfinite(normal)):
            return
        m, e, v = [], 1.0, []
        for f in (fa, fb):
            info = p.getDynamicsInfo(*self._keys[f], physicsClientId=cid)
            m.append(info[0] if fr.rewindable[f] else np.inf)
            e *= info[5]
            v.append(v_new.get(f, self._state[f, 7:10]))
        approach = float(np.dot(v[1] - v[0], normal))  # < 0: B moves towards A
        if approach >= 0.0 or not (np.isfinite(m[0]) or np.isfinite(m[1])):
            return
        w_a = 1.0 if not np.isfinite(m[1]) else (0.0 if not np.isfinite(m[0]) else m[1] / (m[0] + m[1]))
        dv = (1.0 + e) * approach * normal
        if fr.rewindable[fa]:
            v_new[fa] = v[0] + w_a * dv
        if fr.rewindable[fb]:
            v_new[fb] = v[1] - (1.0 - w_a) * dv
        self.stats.held += 1

    def _contact(self, pair, lo, hi):
        """The first touch of a pair (path rows) known to touch in [lo, hi] (step
        fractions): one solve on a quadratic refit of the exact path over that
        window, the boxes inflated by the refit's error bound so that the touch
        cannot be missed."""
        r = _core.path_contact(pair, lo, hi, self.tolerances._core)
        if r is None:  # cannot happen for a true touch; report the window start
            return Contact(lo, np.full(3, np.nan), np.full(3, np.nan), Feature("", "", ""), lo == 0.0,
                           Outcome.SEPARATED)
        return r

    def _rewind_time(self, pair, boxes, tau_first):
        """The first tau >= tau_first on Bullet's exact path at which the sharp boxes
        (path rows ``pair`` of ``boxes``) overlap by ``penetration`` (None if they
        never do in this step: a graze)."""
        target = self.penetration
        if tau_first == 0.0:
            # Touching when the step began: pybullet resolved that contact, but a
            # spinning body can still curve into its partner. Let the overlap grow
            # to a quarter of the thinner box before stepping in, so that pybullet's
            # penetration recovery acts on it; past that, hold it where it is.
            d0 = float(_core.path_depth(pair, np.zeros(1))[0])
            target = max(d0 + self.penetration, 0.5 * self._frames.half[boxes].min())
        tau = _core.first_depth(pair, tau_first, target)
        return None if np.isnan(tau) else float(tau)


_WIDEN = np.array([-1.0, -1.0, -1.0, 1.0, 1.0, 1.0])  # lo, hi bounds widened by a scalar


def _shifted(e: CCDEvent, elapsed: float, dt: float) -> CCDEvent:
    """An event of a partial step (exact-time mode), timed from the start of the whole step."""
    return e if not elapsed else replace(e, time=e.time + elapsed, tau=(e.time + elapsed) / dt)


def _pair_key(x, y):
    return (x, y) if x <= y else (y, x)
