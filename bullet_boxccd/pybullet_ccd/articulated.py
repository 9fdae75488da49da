"""Articulated bodies: every link box swept on its exact within-step path, and the
whole body rewound in joint space.

After pybullet's step each articulated body is read once (base pose and velocity,
every joint's position and velocity: three calls), and the core's ``ChainMotion``
rebuilds every link's path through the step by Bullet's own integration rules
(``chain.py``; docs/design.md, "Link paths"). The body's frames get their pose after
the step and the chord of their step as a velocity, so that the rigid sweep
(``sweep``) sees them as partners of fast free boxes; their own fast boxes are swept
here, on the exact paths (``LinkBoxPath``, conservatively fitted: a touch is never
missed nor reported late), against every box near their swept bounds.

A pair that pybullet would resolve wrongly from where the step left it (the link
went through, or ended deeper than half the pair's reach along the contact normal)
takes the world back to the first time the pair overlaps by ``penetration`` on the
exact path (``contacts`` orders it with the free bodies' contacts): every body there,
an articulated one by its base pose and every joint position at that time, with its
velocities in proportion between those before and after the step
(``resetJointStateMultiDof`` takes both; motor targets and constraints are left as the
user set them). With no partial step left, each such body stops on its own at its
earliest such contact.

Self-collision: a body's links are paired when pybullet collides them, that is when
the body was loaded with URDF_USE_SELF_COLLISION (or named in
``self_collision_bodies``), minus a link's parent (by default), or all its ancestors
(URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS), as Bullet's
btMultiBodyLinkCollider::checkCollideWithOverride decides.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pybullet

from .. import _core
from ..motion import pose7, pose_matrix
from ..solver import Outcome
from ._hooks import MAX_VELOCITY, raw
from .chain import read_chain
from .contacts import bounce, place
from .events import CCDEvent, not_finite_message
from .layout import ANGULAR_VELOCITY, POSE, TWIST, VELOCITY
from .others import joint_layout, put_body
from .sweep import CREEP, meet, overlap_query, unswept_near
from .world import FREE, LINK

__all__ = ["Articulated"]


@dataclass
class _Body:
    body: int
    chain: object  # BodyChain
    frames: list  # its tracked frames (base first if tracked)
    links: dict  # frame -> link index (-1: base)
    boxes: list  # [(frame, box index)]
    ancestors: dict  # link -> set of links a self-collision pair with it is not made with
    motion: object = None  # ChainMotion of the current step
    base_state: np.ndarray = None
    qdot: np.ndarray = None
    paths: dict = field(default_factory=dict)  # box -> BoxPath of the current step
    link_of_frame: np.ndarray = None  # (len(frames),) int64: each frame's link
    frame_index: np.ndarray = None  # (len(frames),) int64: ``frames``
    layout: tuple = None  # its joints that are not fixed, and their spans in q and qdot (joint_layout)
    start: tuple = None  # (base velocity (6,), qdot) when the step began, if known
    box_links: np.ndarray = None  # (len(boxes),) each box's link (-1: base), its pose on the link's frame
    box_X: np.ndarray = None  # (len(boxes), 4, 4), half extents (len(boxes), 3) and sweep reach (len(boxes),)
    box_half: np.ndarray = None
    box_reach: np.ndarray = None
    # (radius, reach, thin): the base's farthest box point, its boxes' smallest sweep reach and half extent
    base_idle: tuple = None
    link_idle: tuple = None  # ([link], [radius], [reach], [thin]): the same for each link with boxes
    fast: bool = False  # whether a fast box of it was judged against a partner in the last step


def _struck_free(hit, path, other, half, other_half, depth_tolerance, impact_depth):
    """A link's contact with a free body, met inside the step and left to pybullet by
    ``Articulated._judge``, that ends it deeper than ``depth_tolerance`` is an impact
    pybullet resolves wrongly, as a free pair's: the struck body stood still in the overlap
    that its motion from the touch on would have avoided. It is acted on from the time the
    pair overlaps by the impact depth (``impact_depth(half, other_half)``)."""
    touch, act, contact, initial, pressing = hit
    if act is not None or initial or not _core.paths_depth(path, other, 1.0) > depth_tolerance:
        return hit
    at = _core.paths_first_depth(path, other, touch, impact_depth(half, other_half))
    return hit if math.isnan(at) else (touch, at, contact, initial, pressing)


class Articulated:
    """The articulated bodies of a world (see the module docstring)."""

    def __init__(self, cid, tables, self_collision, sweep_reach, warn, max_velocity):
        """``self_collision``: {body: URDF_USE_SELF_COLLISION* bits} of the bodies whose links
        collide with each other; ``sweep_reach``: (boxes,) a box moving farther in a step is swept;
        ``max_velocity``: {body: maxJointVelocity the user set} (the journal's)."""
        self.cid, self.tables, self.sweep_reach = cid, tables, sweep_reach
        self._warn, self._max_velocity = warn, max_velocity
        self.clamp_seen = []  # bodies read at the joint velocity clamp in the current step (name_clamped)
        self._link_ok = {}  # (box, box) of articulated bodies -> whether pybullet collides them
        self.bodies = {}
        for b, frames in tables.frames_of.items():
            if not any(tables.kind[f] == LINK for f in frames):
                continue
            try:
                chain = read_chain(cid, b)
            except ValueError as e:
                warn(("chain", b), f"{e}; its links are swept on straight-line estimates and not rewound")
                continue
            links = {f: tables.keys[f][1] for f in frames}
            bits = self_collision.get(b)
            self.bodies[b] = _Body(b, chain, frames, links, [(f, i) for f in frames for i in tables.frame_boxes[f]],
                                   _excluded(chain.parent, bits) if bits is not None else None)
        for rec in self.bodies.values():
            rec.link_of_frame = np.array([rec.links[f] for f in rec.frames], dtype=np.int64)
            rec.frame_index = np.array(rec.frames, dtype=np.int64)
            ids = np.array([i for _, i in rec.boxes], dtype=np.int64)
            rec.box_links = np.array([rec.links[f] for f, _ in rec.boxes], dtype=np.int64)
            rec.box_X, rec.box_half, rec.box_reach = tables.X_CS[ids], tables.half[ids], sweep_reach[ids]
            per_link = {}
            for k, link in enumerate(rec.box_links.tolist()):
                r, reach, thin = per_link.get(link, (0.0, math.inf, math.inf))
                per_link[link] = (max(r, float(tables.radius[ids[k]])), min(reach, float(rec.box_reach[k])),
                                  min(thin, float(rec.box_half[k].min())))
            rec.base_idle = per_link.pop(-1, None)
            rec.link_idle = (list(per_link), *zip(*per_link.values())) if per_link else None
            rec.layout = joint_layout(rec.chain)
        # The bodies a box of which can meet another tracked box (one on another body, or its own: self-collision),
        # or come near a shape of another body left to pybullet (to be named).
        self.watched = [rec for rec in self.bodies.values()
                        if len(tables.half) > len(rec.boxes) or (rec.ancestors is not None and len(rec.boxes) > 1)
                        or any(key[0] != rec.body for key in tables.unswept)]
        self.frames = {f for rec in self.bodies.values() for f in rec.frames}
        self._rigid = len(tables.keys) > len(self.frames)  # whether any box is not on an articulated body
        self.boxes = np.array(sorted(i for rec in self.bodies.values() for _, i in rec.boxes), dtype=np.int64)

    # ------------------------------------------------------------ reading
    def idle(self, dt, state, unswept=()) -> bool:
        """Whether no box of a body that can meet another box moved farther than its sweep
        reach in the step of dt just taken near anything it can meet, from one read per
        body: every box link's velocities after the step (getLinkStates; the base's by
        getBaseVelocity), a point of a link moving by at most m = (|v| + |w| r) dt, r its
        farthest box point from the link's centre of mass (as ``find`` decides it, on the
        chord). A body with such a box is still idle when pybullet's broad phase finds
        nothing it can meet within twice those moves of its fast links' bounds (getAABB;
        and the farthest anything else moved): a robot swinging in free space. A body with a
        box judged against a partner in the last step is taken to move still (it is read
        whole at once). Nor is it idle near a shape in ``unswept`` (left to pybullet, not named
        yet) of another body, with a link that moves more than its boxes' smallest half extent
        (less cannot cross a shape of no thickness: ``find`` would not name it)."""
        cid, fast, widen = self.cid, [], 0.0
        for rec in self.watched:
            if rec.fast:
                return False
            lo, hi = [math.inf] * 3, [-math.inf] * 3
            near = [math.inf] * 3, [-math.inf] * 3  # the bounds of links that can cross a shape
            moving = [(-1, raw.getBaseVelocity(rec.body, physicsClientId=cid), *rec.base_idle)] \
                if rec.base_idle is not None else []
            if rec.link_idle:
                states = raw.getLinkStates(rec.body, rec.link_idle[0], computeLinkVelocity=1, physicsClientId=cid)
                moving += [(link, s[6:8], *rest)
                           for link, s, *rest in zip(rec.link_idle[0], states, *rec.link_idle[1:])]
            for link, (v, w), r, reach, thin in moving:
                m = _moves(v, w, r, dt)
                widen = max(widen, 2.0 * m)
                if m > reach:
                    aabb = raw.getAABB(rec.body, link, physicsClientId=cid)
                    _grow(lo, hi, aabb, 2.0 * m)
                    if m > thin:
                        _grow(*near, aabb, 2.0 * m)
            if lo[0] <= hi[0]:
                fast.append((rec, lo + hi, near[0] + near[1] if near[0][0] <= near[1][0] else None))
        if fast:
            widen = max(widen, state.sweeper.slack(dt))
            t = self.tables
            for rec, box, crossing in fast:
                for key in overlap_query(cid, box, widen):
                    g = t.index.get(key)
                    if g is not None and (int(t.body[g]) != rec.body or rec.ancestors is not None):
                        return False
                if crossing is not None and unswept and any(
                        key in unswept and key[0] != rec.body for key in overlap_query(cid, crossing, widen)):
                    return False
        for rec in self.bodies.values():
            rec.base_state = None  # not read this step: the next step's start is not known
        return True

    def read(self, dt, state, known=True):
        """Read every articulated body after the step, and put its frames' poses after the
        step and their chords (as velocities) in ``state.rows``."""
        cid, self._dt = self.cid, dt
        for rec in self.bodies.values():
            pos, orn = raw.getBasePositionAndOrientation(rec.body, physicsClientId=cid)
            v, w = raw.getBaseVelocity(rec.body, physicsClientId=cid)
            moving = rec.layout[0]
            js = raw.getJointStatesMultiDof(rec.body, moving, physicsClientId=cid) if moving else ()
            rec.start = (rec.base_state[7:13], rec.qdot) if known and rec.base_state is not None else None
            # A fixed joint has no coordinates: the moving joints' are the flat q and qdot.
            base, q = [*pos, *orn, *v, *w], [x for s in js for x in s[0]]
            qdot = [x for s in js for x in s[1]]
            rec.base_state = np.array(base, dtype=np.float64)
            rec.qdot = np.array(qdot, dtype=np.float64)
            if not all(map(math.isfinite, base + q + qdot)):
                # (a NaN or infinite velocity the user set, or a step of a time not finite)
                self._warn(("not finite", rec.body), not_finite_message(rec.body))
                rec.motion = rec.base_state = None
                continue
            if MAX_VELOCITY in map(abs, qdot + base[7:]) \
                    and self._max_velocity.get(rec.body, MAX_VELOCITY) == MAX_VELOCITY:
                self.clamp_seen.append(rec)
            rec.motion = _core.ChainMotion(rec.chain.core, rec.base_state, np.array(q, dtype=np.float64), rec.qdot, dt)
            rec.paths = {}
            state.rows[rec.frame_index] = rec.motion.frame_rows(rec.link_of_frame)
            state.fresh.update(rec.frames)

    def jumped_into(self, rec, joints, dt, pose_of):
        """Where the user set joints of ``rec`` between steps (``joints``: {joint: its position
        before}, one-degree joints only), the first (link, free body, how far the link's box
        moved) of a link box that the set moved, straight along its joints, farther than its
        sweep reach and through a free body's box standing where it stands; None if none.
        ``pose_of(frame)``: a free frame's (position, orientation) now."""
        cid, t = self.cid, self.tables
        moving, q_spans, _ = rec.layout
        pos, orn = raw.getBasePositionAndOrientation(rec.body, physicsClientId=cid)
        q1 = [x for s in raw.getJointStatesMultiDof(rec.body, moving, physicsClientId=cid) for x in s[0]] \
            if moving else []
        q0 = list(q1)
        for joint, (a, b) in zip(moving, q_spans):
            before = joints.get(joint)
            if before is not None:
                if b - a != 1 or len(before) != 1:
                    return None  # (a spherical joint's set is no straight move of q)
                q0[a] = before[0]
        if q0 == q1 or not all(map(math.isfinite, q0 + q1 + [*pos, *orn])):
            return None
        q, qdot = np.array(q1, dtype=np.float64), (np.array(q1) - np.array(q0)) / dt
        motion = _core.ChainMotion(rec.chain.core, np.array([*pos, *orn] + [0.0] * 6), q, qdot, dt)
        for k, move, bounds in motion.fast_boxes(rec.box_links, rec.box_X, rec.box_half, rec.box_reach):
            f, i = rec.boxes[k]
            near = [g for g in (t.index.get(key) for key in overlap_query(cid, bounds, 0.0))
                    if g is not None and t.kind[g] == FREE and int(t.body[g]) != rec.body and t.filters.allowed(f, g)]
            if not near:
                continue
            path = _core.LinkBoxPath(motion, rec.links[f], t.X_CS[i], t.half[i])
            still = np.zeros((len(t.keys), 13))
            for g in near:
                p, o = pose_of(g)
                still[g, POSE] = [*p, *o]
            boxes = np.array([j for g in near for j in t.frame_boxes[g]], dtype=np.int64)
            rows = _core.path_rows(still, dt, boxes, t.box_frame, t.X_CS, t.half)
            for j, row in zip(boxes.tolist(), rows):
                if not math.isnan(_core.paths_first_depth(path, _core.RowBoxPath(row), 0.0, 0.0)):
                    return rec.links[f], int(t.body[t.box_frame[j]]), move
        return None

    def name_clamped(self, name_base):
        """Name the joints of the bodies in ``clamp_seen`` (read at pybullet's default joint
        velocity clamp in a piece of the step) that the step leaves at it, and tell
        ``name_base`` those whose base it leaves at the velocity clamp: a pybullet step the
        world went back from is not the world the user gets."""
        for rec in self.clamp_seen:
            if rec.qdot is not None and np.any(np.abs(rec.qdot) >= MAX_VELOCITY):
                self._at_clamp(rec)
            if rec.base_state is not None and np.any(np.abs(rec.base_state[7:13]) >= MAX_VELOCITY):
                name_base(rec.body)
        self.clamp_seen = []

    def _at_clamp(self, rec):
        """Name the joints of a body moving at pybullet's default velocity clamp."""
        moving, _, spans = rec.layout
        joints = [j for j, (a, b) in zip(moving, spans) if np.any(np.abs(rec.qdot[a:b]) >= MAX_VELOCITY)]
        self._warn(("joint clamp", rec.body), f"body {rec.body} joint{'s' if len(joints) > 1 else ''} "
                                              f"{', '.join(map(str, joints))} move{'' if len(joints) > 1 else 's'} at "
                                              f"{MAX_VELOCITY:g} (rad/s, m/s), pybullet's default joint velocity "
                                              "clamp: if given more, pybullet cut it to that "
                                              f"(p.changeDynamics({rec.body}, -1, maxJointVelocity=...) lifts it)")

    def _path(self, rec, box, dt):
        path = rec.paths.get(box)
        if path is None:
            t = self.tables
            f = int(t.box_frame[box])
            link = rec.links[f]
            if link == -1:
                row = _core.path_rows(rec.base_state[None], dt, np.array([box], dtype=np.int64),
                                      np.zeros(len(t.box_frame), dtype=np.int64), t.X_CS, t.half)[0]
                path = _core.RowBoxPath(row)
            else:
                path = _core.LinkBoxPath(rec.motion, link, t.X_CS[box], t.half[box])
            rec.paths[box] = path
        return path

    # ------------------------------------------------------------ sweeping
    def find(self, dt, state, fit_tolerance, tolerances, penetration, stats, near_unswept=None, impact=None):
        """Sweep the fast link boxes. Returns their contacts in time order: [(touch, act at
        (None: pybullet's to resolve), (point, normal, feature), initial, pressing, body
        record, frame, partner frame, (path, partner path))]. ``near_unswept`` is told the
        shapes left to pybullet (``tables.unswept``) within the reach of a fast link box that
        moves more than its smallest half extent (less cannot cross a shape of no thickness).
        ``impact``: (depth_tolerance, the impact depth of two boxes' half extents) for
        ``_struck_free``."""
        t = self.tables
        fast, through = [], []  # through: (frame, bounds) of those moving more than their smallest half extent
        moved = {}  # body -> its boxes' (k, move, bounds) where fast_boxes was asked
        for rec in self.watched:
            rec.fast = False  # until a fast box of it is judged against a partner
            if rec.motion is None:  # its state is not finite: pybullet's alone
                continue
            moves = moved[rec.body] = rec.motion.fast_boxes(rec.box_links, rec.box_X, rec.box_half, rec.box_reach)
            fast += [(rec, *rec.boxes[k], bounds) for k, _, bounds in moves]
            through += [(rec.boxes[k][0], bounds) for k, move, bounds in moves if move > rec.box_half[k].min()]
        if not fast:
            return []
        stats.swept_boxes += len(fast)
        if near_unswept is not None and through:
            near = unswept_near(self.cid, t, [f for f, _ in through], np.array([b for _, b in through]), 0.0)
            if near:
                near_unswept(near)
        rigid = self._rigid_near(fast, state, dt)
        linked = self._linked_pairs(fast, moved)
        found, reach, allowed = [], self.sweep_reach, t.filters.allowed
        seen = set()
        for k, (rec, f, i, box) in enumerate(fast):
            pairs = [(g, j, other) for g, j, other, bounds in rigid if meet(box, bounds) and allowed(f, g)]
            pairs += [(g, j, None) for g, j in linked.get(k, ())]
            path = None
            for g, j, other in pairs:
                key = (i, j) if i < j else (j, i)
                if key in seen:
                    continue
                seen.add(key)
                path = path or self._path(rec, i, dt)
                other = other or self._path(self.bodies[int(t.body[g])], j, dt)
                if _core.paths_relative_move(path, other) <= min(reach[i], reach[j]):
                    continue  # slow against each other (a link and its neighbour, a foot and the ground it rests on)
                rec.fast = True
                hit = self._judge(path, other, fit_tolerance, tolerances, penetration, stats)
                if hit is not None and impact is not None and t.kind[g] == FREE:
                    hit = _struck_free(hit, path, other, t.half[i], t.half[j], *impact)
                if hit is not None:
                    found.append((*hit, rec, f, g, (path, other)))
        found.sort(key=lambda x: x[0])
        return found

    def events(self, found, upto=1.0, acted_at=None):
        """The CCDEvents of ``find``'s contacts that touched by ``upto``; ``acted_at``: the
        time the world was taken back to (a contact acting then is marked rewound)."""
        t, dt = self.tables, self._dt
        return [CCDEvent(*t.keys[f], *t.keys[g], touch, touch * dt, c[0], c[1], c[2],
                         act is not None and (acted_at is None or act == acted_at), initial)
                for touch, act, c, initial, _, _, f, g, _ in found if touch <= upto]

    @staticmethod
    def act_at(found):
        """(the earliest time one of ``find``'s contacts needs the world back at (1 if
        none), the frames of that contact)."""
        acting = [x for x in found if x[1] is not None]
        if not acting:
            return 1.0, set()
        first = min(acting, key=lambda x: x[1])
        return first[1], {first[6], first[7]}

    def stop_each(self, found, state, dt, stats):
        """Stop each body whose pair needs it at its own time (with its velocities there), or
        push the free box a link presses into. Returns ({body: tau it was stopped at}, {free
        frames pushed})."""
        t = self.tables
        stops, pushes = {}, []
        for _, act, _, _, pressing, rec, f, g, pair in found:
            if act is None:
                continue
            partner = self.bodies.get(int(t.body[g]))
            if pressing and t.kind[g] == FREE and partner is None:
                pushes.append((act, rec, f, g, pair))
                continue
            stops[rec.body] = min(stops.get(rec.body, act), act)
            if partner is not None and partner is not rec:
                stops[partner.body] = min(stops.get(partner.body, act), act)
        for b, tau in stops.items():
            self.stop(self.bodies[b], tau, state)
        stats.rewinds += len(stops)
        pushed = set()
        for tau, rec, f, g, pair in pushes:
            if rec.body not in stops and g not in pushed:
                self._push(rec, f, g, tau, pair, state, dt)
                pushed.add(g)
        stats.pushes += len(pushed)
        return stops, pushed

    def _linked_pairs(self, fast, moved):
        """{k: [(frame, box)]}: for the k-th fast box, the articulated bodies' boxes whose swept
        bounds meet its own (pybullet's filters and a body's own boxes, unless it collides
        with itself, ruled out in the core): every box of a body with self-collision and a
        fast box, and, when there are several articulated bodies, all of theirs. ``moved``:
        {body: fast_boxes' answer} for the bodies whose fast boxes are in ``fast``."""
        bodies = {rec.body for rec, *_ in fast if rec.ancestors is not None}
        if len(self.bodies) > 1:
            bodies = set(self.bodies)
        if not bodies:
            return {}
        boxes, bounds = [i for _, _, i, _ in fast], [b for *_, b in fast]
        for b in bodies:
            rec = self.bodies[b]
            if rec.motion is None:
                continue
            # Its boxes not among the fast ones (those are in already, with the same bounds).
            reach = np.full(len(rec.boxes), -np.inf)
            reach[[k for k, _, _ in moved.get(b, ())]] = np.inf
            for k, _, box in rec.motion.fast_boxes(rec.box_links, rec.box_X, rec.box_half, reach):
                boxes.append(rec.boxes[k][1])
                bounds.append(box)
        t = self.tables
        frame = t.box_frame[boxes]
        f = t.filters
        pairs = _core.candidate_pairs(np.array(bounds, dtype=np.float64), len(fast), frame, t.body, t.self_collides,
                                      f.group, f.mask, f.mode)
        out, ok, frames = {}, self._link_ok, frame.tolist()
        for k, m in pairs.tolist():
            i, j = boxes[k], boxes[m]
            key = (i, j) if i < j else (j, i)
            allowed = ok.get(key)
            if allowed is None:
                allowed = ok[key] = self._collide(fast[k][0], fast[k][1], frames[m])
            if allowed:
                out.setdefault(k, []).append((frames[m], j))
        return out

    def _rigid_near(self, fast, state, dt):
        """[(frame, box, path, swept bounds)] of the boxes not of articulated bodies that
        pybullet's broad phase finds near the fast boxes (one query on their common bounds,
        widened by the farthest such a box moves in the step)."""
        if not self._rigid:
            return []
        t = self.tables
        bounds = [b for *_, b in fast]
        box = [min(b[d] for b in bounds) for d in range(3)] + [max(b[d] for b in bounds) for d in range(3, 6)]
        near = overlap_query(self.cid, box, state.sweeper.slack(dt))
        frames = [g for g in (t.index.get(key) for key in near) if g is not None and g not in self.frames]
        if not frames:
            return []
        state.read_poses(state.stale(frames))
        boxes = np.array([j for g in frames for j in t.frame_boxes[g]], dtype=np.int64)
        rows = _core.path_rows(state.rows, dt, boxes, t.box_frame, t.X_CS, t.half)
        out = []
        for j, row in zip(boxes.tolist(), rows):
            path = _core.RowBoxPath(row)
            out.append((int(t.box_frame[j]), j, path, path.bounds(1).tolist()))
        return out

    def _collide(self, rec, f, g):
        """Whether pybullet collides frame f (of rec) with frame g."""
        t = self.tables
        if int(t.body[g]) == rec.body:
            if rec.ancestors is None:
                return False
            la, lb = rec.links[f], rec.links[g]
            if lb in rec.ancestors.get(la, ()) or la in rec.ancestors.get(lb, ()):
                return False
        return bool(t.filters.allowed(f, g))

    @staticmethod
    def _judge(a, b, fit_tolerance, tolerances, penetration, stats):
        """(touch, act at or None, (point, normal, feature), initial, pressing: touching or
        all but when the step began) of a pair of paths, or None if they stay apart.

        A pair touching, or all but, when the step began was in pybullet's contact solve
        (its contacts reach a little beyond the touch): acted on, from the time it presses
        in by more than a creep, only if it ends where pybullet resolves it wrongly; a pair
        that met inside the step, from its touch. A link's contact that ends merely deep is
        pybullet's: its motors and joints press links into what they touch, and pybullet's
        solver resolves that as it always does (``_core.judge_link_contact``)."""
        touch, act, c, point, normal, initial, pressing, solves = _core.judge_link_contact(
            a, b, fit_tolerance, penetration, CREEP, tolerances._core)
        stats.solver_rows += solves
        stats.candidate_pairs += 1
        stats.outcomes[Outcome.SEPARATED if c is None else c.outcome] += 1
        if math.isnan(touch):
            return None
        # No BMS plane found (a touch at the start, or on a piece too fast to fit): no feature to name.
        contact = (c.point, c.normal, c.feature) if c.feature is not None else (point, normal, None)
        return touch, None if math.isnan(act) else act, contact, initial, pressing

    # ------------------------------------------------------------ pushing
    def _push(self, rec, f, g, tau, pair, state, dt):
        """Free frame g, pressed into by the link of frame f from tau on, carried with that
        link's frame from tau to the end of the step, and given the velocity of a collision
        with an immovable body moving as the link does there (pybullet's combined
        restitution; spin left as it is)."""
        link = rec.links[f]
        frame = (lambda s: rec.motion.base_pose(s)) if link == -1 else (lambda s: rec.motion.link_pose(link, s))
        F_t, F_1 = (pose_matrix(p[:3], p[3:]) for p in (frame(tau), frame(1.0)))
        p = _core.frame_poses(state.rows, dt, np.array([g], dtype=np.int64), np.array([tau]))[0]
        X = pose_matrix(p[:3], p[3:])
        turn = F_1 @ np.linalg.inv(F_t)
        X1 = turn @ X
        _, n = _core.paths_separation(pair[0], pair[1], tau)
        n = turn[:3, :3] @ n
        v_link = state.rows[f, VELOCITY] + np.cross(state.rows[f, ANGULAR_VELOCITY], X1[:3, 3] - F_1[:3, 3])
        v = bounce(self.cid, self.tables, g, f, state.rows[g, VELOCITY], v_link, n)
        place(self.cid, self.tables, state, g, pose7(X1), v, state.rows[g, ANGULAR_VELOCITY].copy())

    # ------------------------------------------------------------ stopping
    def stop(self, rec, tau, state, whole=False):
        """Put the body where its path has it at tau (base pose, joint positions), with the
        velocities it had there: between its velocities before and after the step, in
        proportion (after the step if those before are not known, or if ``whole``); its
        frames stand still from there."""
        cid, m = self.cid, rec.motion
        base = m.base_pose(tau)
        twist, qdot = rec.base_state[7:13].copy(), rec.qdot
        if not whole and rec.start is not None and len(rec.start[1]) == len(qdot):
            twist = rec.start[0] + tau * (twist - rec.start[0])
            qdot = rec.start[1] + tau * (qdot - rec.start[1])
        rec.base_state[7:13], rec.qdot = twist, qdot  # the next (partial) step starts from these
        put_body(cid, rec.body, base, twist, rec.layout, m.joint_positions(tau), qdot)
        ends = m.link_poses(tau)
        for f in rec.frames:
            link = rec.links[f]
            state.rows[f, POSE] = base if link == -1 else ends[link]
            state.rows[f, TWIST] = 0.0
        rec.motion = None  # its paths are no longer this step's

    def stop_all(self, tau, state, struck=frozenset()):
        """The world taken back to tau: every articulated body where its path has it then,
        with its velocities there in proportion; a body with a frame in ``struck`` (of the
        contact the world was taken back to as the partial step began) keeps its velocities
        after the step, as its free partner does: the impact's impulse acted whole at that
        start, and scaled on one side only it would take momentum out of the pair."""
        for rec in self.bodies.values():
            if rec.motion is not None:
                self.stop(rec, tau, state, not struck.isdisjoint(rec.frames))


def _grow(lo, hi, aabb, by):
    """Grow bounds lo, hi (lists of 3) to hold pybullet's bounds ``aabb`` widened by ``by``."""
    for d in range(3):
        lo[d] = min(lo[d], aabb[0][d] - by)
        hi[d] = max(hi[d], aabb[1][d] + by)


def _moves(v, w, r, dt):
    """How far a point at most r from a frame's origin moves in dt at velocities v, w."""
    speed, spin = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    return (speed + spin * r) * dt


def _excluded(parent, bits):
    """link -> the links pybullet does not pair it with in self-collision."""
    out = {}
    all_parents = bool(bits & pybullet.URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS)
    include_parent = bool(bits & pybullet.URDF_USE_SELF_COLLISION_INCLUDE_PARENT)
    for link in range(len(parent)):
        if all_parents:
            up, p = set(), int(parent[link])
            while True:
                up.add(p)
                if p == -1:
                    break
                p = int(parent[p])
            out[link] = up
        elif not include_parent:
            out[link] = {int(parent[link])}
    return out
