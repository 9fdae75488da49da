"""The sweep of one step: which boxes moved fast, their exact paths, their partners
(pybullet's own broad phase on the swept bounds), and each candidate pair's first
touch. The numerics run in the core (``_core.Sweeper``: the fast boxes, then path
rows, swept bounds, candidate pairs and first touches in one call); this module
decides what to read and what to ask.

A box is swept when its fastest point moves more than ``sweep_threshold`` of its
smallest extent in the step (a slower one overlaps anything it meets in some step, so
pybullet's discrete contacts catch it). Static frames have a constant path, but for a
kinematic one (``state``), given a velocity, which Bullet moves like any other body.
A kinematic frame's jump (the user's teleport before the step) is swept apart, in
``jump_sweep``, against the free bodies where the step found them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import partial

import numpy as np

from .. import _core
from ._hooks import raw
from .layout import PATH_ROW, POSE, TWIST
from .world import FREE

__all__ = ["Sweep", "sweep", "jump_sweep", "moves_into", "CREEP", "overlap_query", "meet"]

# A pair touching when the step (or a window of it) begins is a contact pybullet holds
# unless it presses in by more than this fraction of the thinner box's half extent.
CREEP = 0.02

# A broad-phase query box reaches this far (relative to its coordinates' magnitude)
# beyond the swept bounds and the slack, so that a partner whose AABB only touches
# them is not lost to the rounding of either; relative, so that a scene far from the
# origin keeps the margin's meaning (1e-9 m for a box near 1 m from the origin).
_QUERY_WIDEN = 1e-9


def overlap_query(cid, box, slack):
    """pybullet's getOverlappingObjects on bounds ``box`` = (x0, y0, z0, x1, y1, z1)
    widened by ``slack`` (and ``_QUERY_WIDEN``); () when none."""
    w = slack + _QUERY_WIDEN * max(abs(x) for x in box)
    lo, hi = [x - w for x in box[:3]], [x + w for x in box[3:]]
    return raw.getOverlappingObjects(lo, hi, physicsClientId=cid) or ()


@dataclass
class Sweep:
    """A step's sweep: path rows of the boxes involved, the candidate pairs, and those
    that touched."""

    rows: np.ndarray  # (n, 42) path rows
    boxes: np.ndarray  # (n,) their box indices
    pairs: np.ndarray  # (m, 2) candidate pairs of rows
    hits: list  # (row a, row b, first touch as a step fraction), in the order found


# A step's partners of the fast boxes come from pybullet's broad phase (one
# getOverlappingObjects per fast box) unless reading every moving frame's pose costs
# less: measured on pybullet 3.2.7, the query costs about as much as 4 pose reads; the
# world's boxes then pass through the core's own broad phase (a sorted sweep).
_READS_PER_QUERY = 4


def sweep(cid, tables, state, dt, fit_tolerance, tolerances, penetration, stats, t0, fast=None, fast_seen=None,
          near_unswept=None):
    """Sweep the step just taken (``state`` holds the velocities of the moving frames and
    the kinematic frames' poses; ``fast`` what ``state.sweeper.fast`` found, if it was
    asked already). Returns a Sweep, or None if nothing touched. The fast frames are told
    to ``fast_seen`` (their velocities read); ``near_unswept`` is told the shapes left to
    pybullet (``tables.unswept``) that pybullet's broad phase finds within the reach of
    the fast boxes whose centres can cross them (``_centre_travel``)."""
    sweeper = state.sweeper
    if fast is None:
        fast = state.fast(dt)
        if fast is None:
            stats.seconds["state"] += time.perf_counter() - t0
            return None
    fast, slack, fast_frames = fast
    if fast_seen is not None:
        fast_seen(fast_frames)
    state.read_poses(state.stale(fast_frames))
    stats.swept_boxes += len(fast)
    bounds = None  # the fast boxes' swept bounds, once asked for
    if near_unswept is not None:
        rows, bounds = sweeper.rows(dt, fast)
        through = np.flatnonzero(_centre_travel(rows) > rows[:, PATH_ROW["half_extents"]].min(axis=1))
        if len(through):
            near = unswept_near(cid, tables, tables.box_frame[np.asarray(fast)[through]].tolist(), bounds[through],
                                slack)
            if near:
                near_unswept(near)
    t1 = time.perf_counter()
    stats.seconds["state"] += t1 - t0
    boxes, all_others = fast, False
    if len(state.moving) <= len(fast_frames) + _READS_PER_QUERY * len(fast):
        # Every moving frame where the step left it, and the core's broad phase.
        state.read_poses(state.stale(state.moving))
        all_others = True
    else:
        # Only the partners pybullet's own broad phase finds near the fast boxes' swept
        # bounds (a slow body can be anywhere within its reach of the pose it knows, so
        # the query is widened by the largest such reach).
        if bounds is None:
            _, bounds = sweeper.rows(dt, fast)
        partners = _partners(cid, tables, bounds, slack, fast_frames)
        state.read_poses(state.stale(partners))
        boxes = fast + [b for f in partners for b in tables.frame_boxes[f]]
    t2 = time.perf_counter()
    stats.seconds["broad_phase"] += t2 - t1
    n_pairs, solves, found = sweeper.touches(dt, boxes, len(fast), all_others, fit_tolerance, tolerances._core,
                                             penetration, CREEP, stats.outcomes)
    stats.candidate_pairs += n_pairs
    stats.solver_rows += solves
    stats.seconds["solve"] += time.perf_counter() - t2
    if found is None:
        return None
    boxes, rows, pairs, hits = found
    f = tables.filters
    if f.rules:
        frames = tables.box_frame[boxes]
        pairs = pairs[f.allowed_pairs(frames[pairs[:, 0]], frames[pairs[:, 1]])]
        allowed = set(map(tuple, pairs.tolist()))
        hits = [h for h in hits if h[:2] in allowed]
    return Sweep(rows, boxes, pairs, hits) if hits else None


def _centre_travel(rows):
    """How far each path row's box centre can get from where it starts the step (a bound: the
    frame's displacement, and the arc of the centre's turn about the frame's origin). A
    box whose centre moves less than its smallest half extent cannot cross even a shape of
    no thickness (a mesh's face, a heightfield) within the step."""
    offset = np.linalg.norm(rows[:, PATH_ROW["box_in_frame"]].reshape(-1, 4, 4)[:, :3, 3], axis=1)
    return np.linalg.norm(rows[:, PATH_ROW["displacement"]], axis=1) + np.abs(rows[:, PATH_ROW["angle"]][:, 0]) * offset


def unswept_near(cid, tables, frames, bounds, slack):
    """The shapes left to pybullet (``tables.unswept``) within a fast box's own swept
    bounds (n, 6), widened by ``slack``, that pybullet lets that box's frame (``frames``,
    (n,)) collide with: of another body, and not filtered out."""
    reach = bounds[:, :3].min(axis=0).tolist() + bounds[:, 3:].max(axis=0).tolist()
    near = [key for key in map(tuple, overlap_query(cid, reach, slack)) if key in tables.unswept]
    if not near:
        return []
    # Each box's bounds widened as overlap_query widens them. The union can span a room:
    # where it holds more shapes than there are boxes, each box's own query narrows them
    # down (pybullet's broad phase holds a shape's AABB within its own).
    w = slack + _QUERY_WIDEN * np.abs(bounds).max(axis=1, keepdims=True)
    widened = np.concatenate((bounds[:, :3] - w, bounds[:, 3:] + w), axis=1).tolist()
    rows = range(len(frames))
    if len(frames) < len(near):
        ask = {key: [] for key in near}
        for k, box in enumerate(bounds.tolist()):
            for key in map(tuple, overlap_query(cid, box, slack)):
                if key in ask:
                    ask[key].append(k)
        near = [key for key, ks in ask.items() if ks]
    else:
        ask = dict.fromkeys(near, rows)
    out, allowed, body = [], tables.filters.allowed_shape, tables.body
    for key in near:
        lo, hi = raw.getAABB(*key, physicsClientId=cid)
        if any(body[frames[k]] != key[0] and meet(widened[k], (*lo, *hi)) and allowed(frames[k], key)
               for k in ask[key]):
            out.append(key)
    return out


def meet(a, b):
    """Whether two bounds [lo (3), hi (3)] overlap."""
    return a[0] <= b[3] and b[0] <= a[3] and a[1] <= b[4] and b[1] <= a[4] and a[2] <= b[5] and b[2] <= a[5]


def _partners(cid, tables, bounds, slack, exclude):
    """Frames pybullet's broad phase finds within ``slack`` of the given bounds."""
    near, index = set(), tables.index
    for box in bounds.tolist():
        near.update(index[key] for key in overlap_query(cid, box, slack) if key in index)
    return sorted(near.difference(exclude))


def _pairs(tables, boxes, bounds, n_moving):
    """The candidate pairs (rows into ``boxes``) of the first ``n_moving`` boxes with
    the others and each other: bounds overlap, and pybullet's filters let them collide."""
    f, frames = tables.filters, tables.box_frame[boxes]
    pairs = _core.candidate_pairs(bounds, n_moving, frames, tables.body, tables.self_collides, f.group, f.mask,
                                  f.mode)
    if f.rules and len(pairs):
        pairs = pairs[f.allowed_pairs(frames[pairs[:, 0]], frames[pairs[:, 1]])]
    return pairs


def _hits(pairs, tau):
    """(row a, row b, first touch as a step fraction) of the pairs that touch."""
    hit = np.flatnonzero(~np.isnan(tau))
    return [(i, j, t) for (i, j), t in zip(pairs[hit].tolist(), tau[hit].tolist())] if len(hit) else []


def moves_into(cid, tables, moves, frozen_of, widen, fit_tolerance, tolerances, penetration, stats,
               near_unswept=None):
    """Kinematic frames moving straight from pose to pose (``moves``: {frame: (pose0,
    pose1)}) against the free bodies standing still: ``frozen_of(partners)`` gives the
    (F, 13) state of the free frames pybullet's broad phase finds within ``widen`` of the
    moves. A Sweep whose first rows are the moving boxes and whose hits have a moving box
    first; None if nothing was met. ``near_unswept`` is told the shapes left to pybullet
    within a moving box's reach (pybullet sees nothing of such a move)."""
    if not moves:
        return None
    frames = sorted(moves)
    moving = np.array([b for f in frames for b in tables.frame_boxes[f]], dtype=np.int64)
    poses0, poses1 = np.zeros((len(tables.keys), 7)), np.zeros((len(tables.keys), 7))
    for f in frames:
        poses0[f], poses1[f] = moves[f]
    rows = _core.path_rows_between(poses0, poses1, moving, tables.box_frame, tables.X_CS, tables.half)
    bounds = _core.swept_bounds(rows)
    if near_unswept is not None:
        near = unswept_near(cid, tables, tables.box_frame[moving].tolist(), bounds, 0.0)
        if near:
            near_unswept(near)
    near = _still_near(cid, tables, rows, moving, bounds, frozen_of, widen, frames)
    if near is None:
        return None
    rows, boxes, pairs = near
    tau, states, solves = _core.first_touches(rows, pairs, fit_tolerance, tolerances._core, penetration, CREEP,
                                              states=True)
    stats.solver_rows += solves
    stats.count(states)
    hits = _hits(pairs, tau)
    return Sweep(rows, boxes, pairs, hits) if hits else None


def _still_near(cid, tables, rows, moving, bounds, frozen_of, widen, exclude):
    """The free frames (not in ``exclude``) that pybullet's broad phase finds within
    ``widen`` of the swept ``bounds`` of boxes ``moving`` (path rows ``rows``), standing
    still in the state ``frozen_of(frames)`` gives them: (rows, boxes, candidate pairs)
    with the moving boxes first and each pair (moving row, still row), or None."""
    partners = [f for f in _partners(cid, tables, bounds, widen, exclude) if tables.kind[f] == FREE]
    if not partners:
        return None
    still = frozen_of(partners).copy()
    still[:, TWIST] = 0.0
    more = np.array([b for f in partners for b in tables.frame_boxes[f]], dtype=np.int64)
    more_rows = _core.path_rows(still, 1.0, more, tables.box_frame, tables.X_CS, tables.half)
    boxes, rows = np.concatenate([moving, more]), np.concatenate([rows, more_rows])
    pairs = _pairs(tables, boxes, np.concatenate([bounds, _core.swept_bounds(more_rows)]), len(moving))
    pairs = pairs[pairs[:, 1] >= len(moving)] if len(pairs) else pairs
    return (rows, boxes, pairs) if len(pairs) else None


def step_reach(state, tables, dt):
    """The farthest any box's point moves in the step."""
    if not len(tables.radius):
        return 0.0
    twist = state.rows[tables.box_frame]
    return float(np.max((np.linalg.norm(twist[:, 7:10], axis=1) + np.linalg.norm(twist[:, 10:13], axis=1)
                         * tables.radius) * dt))


def jump_sweep(cid, tables, state, dt, fit_tolerance, tolerances, penetration, stats, near_unswept=None):
    """The kinematic frames' jumps (from E0 to P1, before the step's physics) against the
    free bodies where the step started (on Bullet's path at tau = 0); ``near_unswept``: as
    for ``moves_into``."""
    if not state.jumps:
        return None
    return moves_into(cid, tables, state.jumps, partial(_at_start, state, dt), step_reach(state, tables, dt),
                      fit_tolerance, tolerances, penetration, stats, near_unswept)


def ride_near(cid, tables, state, dt, rides, boxes, exclude):
    """The free frames (not in ``exclude``) standing where the step began that boxes
    riding on a kinematic jump can meet (``rides``: their path rows, of ``boxes``): as
    ``_still_near``."""
    return _still_near(cid, tables, rides, np.asarray(boxes, dtype=np.int64), _core.swept_bounds(rides),
                       partial(_at_start, state, dt), step_reach(state, tables, dt), exclude)


def _at_start(state, dt, partners):
    """The frame state with the ``partners``' poses where the step began (on Bullet's path at
    tau = 0)."""
    state.read_poses(state.stale(partners))
    start = state.rows.copy()
    start[partners, POSE] = _core.frame_poses(state.rows, dt, np.array(partners, dtype=np.int64),
                                              np.zeros(len(partners)))
    return start
