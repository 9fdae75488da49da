"""Drop-in tunneling prevention for pybullet worlds (the only module that imports pybullet).

``BoxCCD.step()`` replaces ``p.stepSimulation()``:

1. pybullet takes its step as usual.
2. The step is swept: every box collision shape that moved more than
   ``sweep_threshold`` of its own smallest extent gets its exact within-step
   path, rebuilt from the pose after the step and the post-solve velocities
   (Bullet moves the centre of mass linearly and turns it about a fixed axis:
   ``motion.StepPath``), fitted by quadratic motions (split into pieces and the
   box inflated by the fit's error bound, so the fit is conservative).
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
from dataclasses import dataclass, field, replace
from itertools import chain

import numpy as np
import pybullet as p

from . import _core
from .geometry import Box
from .motion import QuadraticMotion, StepPath, matrix_to_quat, quat_to_matrix
from .solver import DEFAULT_TOLERANCES, Contact, Feature, Tolerances, time_of_impact, time_of_impact_batch

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
    solver_rows: int = 0
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
        self.refresh()

    # ------------------------------------------------------------ discovery
    def _world_signature(self):
        n = p.getNumBodies(physicsClientId=self.cid)
        return n, (p.getBodyUniqueId(n - 1, physicsClientId=self.cid) if n else -1)

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
        """Rediscover every box in the world (called automatically when bodies are added or removed)."""
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
        self._frames = _Frames(np.array(body, int), np.array(link, int), np.array(static, bool),
                               np.array(rewind, bool), np.array(box_frame, int), half, X_CS, radius)
        self._keys = [(int(b), int(lk)) for b, lk in zip(body, link)]  # plain ints for the pybullet calls
        self._frame_index = {key: i for i, key in enumerate(self._keys)}
        self._dynamic = np.flatnonzero(~self._frames.static).tolist()
        self._frame_boxes = [[] for _ in body]  # frame -> its boxes
        for b, f in enumerate(box_frame):
            self._frame_boxes[f].append(b)
        self._pose_template = np.tile(np.eye(4), (len(body), 1, 1))
        self._pose_template[self._frames.static] = self._read_poses(np.flatnonzero(self._frames.static))
        # A box is swept when its fastest point moves more than this in a step.
        self._sweep_reach = self.sweep_threshold * 2.0 * half.min(axis=1)
        self.stats.tracked_boxes = len(half)
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
        """(F, 4, 4) centre-of-mass poses of the given frame indices."""
        cid, keys = self.cid, self._keys
        get_pose, get_link = p.getBasePositionAndOrientation, p.getLinkState
        st = [get_pose(keys[f][0], physicsClientId=cid) if keys[f][1] == -1 else
              get_link(keys[f][0], keys[f][1], physicsClientId=cid)[:2] for f in frames]
        X = np.zeros((len(frames), 4, 4))
        X[:, 3, 3] = 1.0
        if st:
            X[:, :3, 3] = [x[0] for x in st]
            to_matrix = p.getMatrixFromQuaternion  # C, row-major 3x3: cheaper than numpy for a few
            X[:, :3, :3] = np.reshape([to_matrix(x[1], physicsClientId=cid) for x in st], (-1, 3, 3))
        return X

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
        fr, st = self._frames, self.stats
        n_frames = len(fr.body)
        if not len(fr.half):
            return [], 1.0
        vel = np.zeros((n_frames, 6))
        vel[self._dynamic] = self._read_velocities(self._dynamic)
        v, w = vel[:, :3], vel[:, 3:]
        # Fast boxes: the farthest point moves more than the threshold (Bullet
        # turns a body by at most |w| dt in a step).
        bf = fr.box_frame
        speeds = np.sqrt(np.einsum("fki,fki->fk", vel.reshape(-1, 2, 3), vel.reshape(-1, 2, 3)))  # |v|, |w|
        reach = (speeds[bf, 0] + speeds[bf, 1] * fr.radius) * dt
        fast = reach > self._sweep_reach
        if not fast.any():
            st.seconds["state"] += time.perf_counter() - t0
            return [], 1.0
        # Poses: the fast frames, then only the partners pybullet's own broad phase
        # finds near their swept bounds (slow bodies can be anywhere within their
        # reach of the pose it knows, so the query is widened by the largest).
        X1 = self._pose_template.copy()  # identity, static poses filled in
        fast_boxes = np.flatnonzero(fast)
        fast_frames = set(bf[fast_boxes].tolist())
        X1[sorted(fast_frames)] = self._read_poses(sorted(fast_frames))
        path = StepPath(X1, v, w, dt)  # rows of frames not read yet are filled below
        lo, hi = self._swept_bounds(path, fast_boxes)
        slack = reach[~fast & ~fr.static[bf]].max(initial=0.0) + 1e-9
        near = set(fast_frames)
        for k in range(len(fast_boxes)):
            found = p.getOverlappingObjects((lo[k] - slack).tolist(), (hi[k] + slack).tolist(),
                                            physicsClientId=self.cid) or ()
            near.update(self._frame_index[key] for key in found if key in self._frame_index)
        # Static partners are read too: a mass-0 body can be moved by the user
        # (a kinematic obstacle), and pybullet's broad phase already sees it there.
        partners = sorted(near - fast_frames)
        if partners:
            path.X_W1[partners] = self._read_poses(partners)
        t1 = time.perf_counter()
        st.seconds["state"] += t1 - t0
        st.swept_boxes += len(fast_boxes)
        others = np.array([b for f in sorted(near - fast_frames) for b in self._frame_boxes[f]], dtype=int)
        lo_o, hi_o = self._swept_bounds(path, others)
        pairs = self._candidate_pairs(fast, np.concatenate([fast_boxes, others]),
                                      np.concatenate([lo, lo_o]), np.concatenate([hi, hi_o]))
        t2 = time.perf_counter()
        st.seconds["broad_phase"] += t2 - t1
        st.candidate_pairs += len(pairs)
        if not len(pairs):
            return [], 1.0
        hits = self._solve_pairs(path, pairs)
        t3 = time.perf_counter()
        st.seconds["solve"] += t3 - t2
        events, tau = self._resolve(path, hits, dt, near)
        st.seconds["rewind"] += time.perf_counter() - t3
        return events, tau

    def _path_boxes(self, path, boxes):
        """(n, 42) the boxes' exact paths over the step, as the core's step-path functions take them."""
        fr = self._frames
        f = fr.box_frame[boxes]
        return np.concatenate([path.X_W1[f].reshape(-1, 16), path.dv[f], path.axis[f], path.angle[f, None],
                               fr.X_CS[boxes].reshape(-1, 16), fr.half[boxes]], axis=1)

    def _swept_bounds(self, path, boxes):
        """(n, 3) lo and hi: bounds of the given boxes over the step (see _core.swept_bounds)."""
        b = _core.swept_bounds(self._path_boxes(path, boxes))
        return b[:, :3], b[:, 3:]

    def _candidate_pairs(self, fast, involved, lo, hi):
        """(P, 2) box index pairs among ``involved`` (with swept bounds ``lo``, ``hi``) whose
        bounds meet, at least one of them fast."""
        fr = self._frames
        fi = np.flatnonzero(fast[involved])
        overlap = np.all((lo[fi, None, :] <= hi[None, :, :]) & (lo[None, :, :] <= hi[fi, None, :]), axis=2)
        i, j = np.nonzero(overlap)
        a, b = involved[fi[i]], involved[j]
        keep = (a != b) & ~(fast[b] & (b < a))  # each fast-fast pair once
        a, b = a[keep], b[keep]
        fa, fb = fr.box_frame[a], fr.box_frame[b]
        body_a, body_b = fr.body[fa], fr.body[fb]
        keep = fa != fb  # boxes of one link never collide with each other
        same_body = body_a == body_b
        if same_body.any():
            allowed = np.array([int(x) in self.self_collision_bodies for x in body_a])
            keep &= ~same_body | allowed
        keep &= ~(fr.static[fa] & fr.static[fb])
        if self._filtered:
            keep &= np.array([_pair_key((int(body_a[k]), int(fr.link[fa[k]])), (int(body_b[k]), int(fr.link[fb[k]])))
                              not in self._filtered for k in range(len(a))], dtype=bool)
        return np.stack([a[keep], b[keep]], axis=1)

    def _solve_pairs(self, path, pairs):
        """First contact of each candidate pair on the fitted (conservative) motion.

        Returns a list of (box a, box b, tau_first) for the pairs that touch."""
        fr, st = self._frames, self.stats
        boxes = np.array(sorted(set(pairs.ravel().tolist())))
        frames = fr.box_frame[boxes]
        min_half = fr.half[boxes].min(axis=1)
        # Pieces per box: powers of two until the fit error is within tolerance.
        err1 = 2.0 * np.sqrt(3.0) / 216.0 * path.angle[frames] ** 3 * fr.radius[boxes]
        pieces = np.ones(len(boxes), int)
        while True:
            over = err1 / pieces**3 > self.fit_tolerance * min_half
            if not over.any() or pieces.max() >= 64:
                break
            pieces[over] *= 2
        slot = {int(b): k for k, b in enumerate(boxes)}
        pa = np.array([slot[int(x)] for x in pairs[:, 0]])
        pb = np.array([slot[int(x)] for x in pairs[:, 1]])
        n_pair = np.maximum(pieces[pa], pieces[pb])
        first = {}  # (box a, box b) -> earliest tau over the pieces
        for n in sorted(set(n_pair.tolist())):
            rows = np.flatnonzero(n_pair == n)
            sel = np.array(sorted(set(pa[rows].tolist()) | set(pb[rows].tolist())))
            sub = np.full(len(boxes), -1)
            sub[sel] = np.arange(len(sel))
            coeffs, err = path.take(frames[sel]).fit(fr.X_CS[boxes[sel]], int(n))
            # Inflate by the fit's reach: a point at distance r is off by err * r,
            # and a ball fits in the sheared box once scaled by 1 / (1 - err)
            # (err < 0.5: Bullet turns a body by less than pi in a step).
            grow = err * fr.radius[boxes[sel]] / (1.0 - err)
            half = fr.half[boxes[sel]] + grow[:, None]
            ia, ib = sub[pa[rows]], sub[pb[rows]]
            for k in range(int(n)):
                t = time_of_impact_batch(-half[ia], half[ia], coeffs[k, ia], -half[ib], half[ib], coeffs[k, ib],
                                         (0.0, 1.0), self.tolerances)
                st.solver_rows += len(rows)
                for r in np.flatnonzero(~np.isnan(t)):
                    key = (int(boxes[sel[ia[r]]]), int(boxes[sel[ib[r]]]))
                    first[key] = min(first.get(key, np.inf), (k + t[r]) / n)
        return [(a, b, tau) for (a, b), tau in first.items()]

    def _resolve(self, path, hits, dt, known):
        """Events and rewinds: each free body goes to its earliest rewind time.
        ``known``: the frames whose poses were read this step (the others are read
        here if exact-time mode stops them too)."""
        fr, st = self._frames, self.stats
        stop = {}
        found = []
        for a, b, tau in sorted(hits, key=lambda h: h[2]):
            tau_b = self._rewind_time(path, a, b, tau)
            if tau == 0.0 and tau_b is None:
                continue  # touching at the start and not deepening: pybullet's own contact
            found.append((a, b, tau, tau_b))
            if tau_b is None:
                continue
            for f in fr.box_frame[[a, b]]:
                if fr.rewindable[f] and tau_b < stop.get(int(f), np.inf):
                    stop[int(f)] = tau_b
        events = []
        v_new = {}
        for a, b, tau, tau_b in found:
            fa, fb = int(fr.box_frame[a]), int(fr.box_frame[b])
            c = self._contact(path, a, b, tau, 1.0 if tau_b is None else tau_b)
            rewound = tau_b is not None and tau_b in (stop.get(fa), stop.get(fb))
            if rewound and tau == 0.0 and tau_b < self.hold_fraction:
                self._release_held(path, fa, fb, c.normal, v_new)
            events.append(CCDEvent(int(fr.body[fa]), int(fr.link[fa]), int(fr.body[fb]), int(fr.link[fb]),
                                   c.t, c.t * dt, c.point, c.normal, c.feature, rewound, tau == 0.0))
        st.contacts += len(events)
        tau_world = min(stop.values(), default=1.0)
        if self.exact_time and stop:
            # The whole world goes to the earliest contact: every free body.
            stop = {int(f): tau_world for f in np.flatnonzero(fr.rewindable)}
            unread = sorted(set(stop) - set(known))
            if unread:
                path.X_W1[unread] = self._read_poses(unread)
        if stop:
            frames = np.array(sorted(stop))
            X = path.take(frames).at(np.array([stop[f] for f in frames]))
            quats = matrix_to_quat(X[:, :3, :3])
            for k, f in enumerate(frames):
                b = int(fr.body[f])
                p.resetBasePositionAndOrientation(b, X[k, :3, 3].tolist(), quats[k].tolist(), physicsClientId=self.cid)
                # The reset zeroes the velocity: give back the post-solve one. In
                # exact-time mode the rest of the step is simulated again, and it
                # will add its gravity again: take that part out here.
                v = v_new.get(f, path.v[f])
                if self.exact_time:
                    v = v - self._gravity * (1.0 - stop[f]) * dt
                p.resetBaseVelocity(b, v.tolist(), path.w[f].tolist(), physicsClientId=self.cid)
            st.rewinds += len(frames)
        return events, tau_world

    def _release_held(self, path, fa, fb, normal, v_new):
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
            info = p.getDynamicsInfo(int(fr.body[f]), int(fr.link[f]), physicsClientId=cid)
            m.append(info[0] if fr.rewindable[f] else np.inf)
            e *= info[5]
            v.append(v_new.get(f, path.v[f]))
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

    def _contact(self, path, a, b, lo, hi):
        """The first touch of a pair known to touch in [lo, hi] (step fractions): one solve
        on a quadratic refit of the exact path over that window, the boxes inflated by
        the refit's error bound so that the touch cannot be missed."""
        fr = self._frames
        if hi - lo < 1e-12:
            lo = max(0.0, hi - 1e-12)
        coeffs, err = path.take(fr.box_frame[[a, b]]).fit(fr.X_CS[[a, b]], 1, (lo, hi))
        grow = err * fr.radius[[a, b]] / (1.0 - err) + 1e-12 * fr.radius[[a, b]]
        half = fr.half[[a, b]] + grow[:, None]
        c = time_of_impact(Box(-half[0], half[0]), QuadraticMotion(coeffs[0, 0]), Box(-half[1], half[1]),
                           QuadraticMotion(coeffs[0, 1]), (0.0, 1.0), self.tolerances)
        if c is None:  # cannot happen for a true touch; report the window start
            return Contact(lo, np.full(3, np.nan), np.full(3, np.nan), Feature("", "", ""), lo == 0.0)
        return c._replace(t=lo + c.t * (hi - lo))

    def _rewind_time(self, path, a, b, tau_first):
        """The first tau >= tau_first on Bullet's exact path at which the sharp boxes
        overlap by ``penetration`` (None if they never do in this step: a graze)."""
        boxes = self._path_boxes(path, [a, b])
        target = self.penetration
        if tau_first == 0.0:
            # Touching when the step began: pybullet resolved that contact, but a
            # spinning body can still curve into its partner. Let the overlap grow
            # to a quarter of the thinner box before stepping in, so that pybullet's
            # penetration recovery acts on it; past that, hold it where it is.
            d0 = float(_core.path_depth(boxes, np.zeros(1))[0])
            target = max(d0 + self.penetration, 0.5 * self._frames.half[[a, b]].min())
        tau = _core.first_depth(boxes, tau_first, target)
        return None if np.isnan(tau) else float(tau)


def _shifted(e: CCDEvent, elapsed: float, dt: float) -> CCDEvent:
    """An event of a partial step (exact-time mode), timed from the start of the whole step."""
    return e if not elapsed else replace(e, time=e.time + elapsed, tau=(e.time + elapsed) / dt)


def _pair_key(x, y):
    return (x, y) if x <= y else (y, x)
