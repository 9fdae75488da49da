"""The sweep of one step: which boxes moved fast, their exact paths, their partners
(pybullet's own broad phase on the swept bounds), and each candidate pair's first
touch. The numerics run in the core (``_core``: fast_boxes, path_rows, swept_bounds,
candidate_pairs, first_touches); this module decides what to read and what to ask.

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

import numpy as np

from .. import _core
from ._hooks import raw
from .layout import POSE, TWIST
from .world import FREE

__all__ = ["Sweep", "sweep", "jump_sweep", "moves_into", "CREEP"]

_WIDEN = np.array([-1.0, -1.0, -1.0, 1.0, 1.0, 1.0])  # lo, hi bounds widened by a scalar
# A pair touching when the step (or a window of it) begins is a contact pybullet holds
# unless it presses in by more than this fraction of the thinner box's half extent.
CREEP = 0.02


@dataclass
class Sweep:
    """A step's sweep: path rows of the boxes involved, the candidate pairs, and those
    that touched."""

    rows: np.ndarray  # (n, 42) path rows
    boxes: np.ndarray  # (n,) their box indices
    pairs: np.ndarray  # (m, 2) candidate pairs of rows
    hits: list  # (row a, row b, first touch as a step fraction), in the order found

    @property
    def pair_index(self) -> dict:
        return {(int(i), int(j)): q for q, (i, j) in enumerate(self.pairs.tolist())}


def sweep(cid, tables, state, dt, sweep_reach, fit_tolerance, tolerances, penetration, stats, t0):
    """Sweep the step just taken (``state`` holds the velocities of the moving frames and
    the kinematic frames' poses). Returns a Sweep, or None if nothing was fast."""
    fast, slack = _core.fast_boxes(state.rows, dt, tables.box_frame, tables.radius, sweep_reach)
    if not len(fast):
        stats.seconds["state"] += time.perf_counter() - t0
        return None
    # Poses: the fast frames, then only the partners pybullet's own broad phase finds
    # near their swept bounds (a slow body can be anywhere within its reach of the
    # pose it knows, so the query is widened by the largest such reach).
    fast_frames = sorted(set(tables.box_frame[fast].tolist()))
    state.read_poses(state.stale(fast_frames))
    rows = _core.path_rows(state.rows, dt, fast, tables.box_frame, tables.X_CS, tables.half)
    bounds = _core.swept_bounds(rows)
    partners = _partners(cid, tables, bounds, slack, fast_frames)
    state.read_poses(state.stale(partners))
    t1 = time.perf_counter()
    stats.seconds["state"] += t1 - t0
    stats.swept_boxes += len(fast)
    boxes = np.array(fast.tolist() + [b for f in partners for b in tables.frame_boxes[f]], dtype=np.int64)
    if len(boxes) > len(fast):
        more = _core.path_rows(state.rows, dt, boxes[len(fast):], tables.box_frame, tables.X_CS, tables.half)
        rows, bounds = np.concatenate([rows, more]), np.concatenate([bounds, _core.swept_bounds(more)])
    f = tables.filters
    pairs = _core.candidate_pairs(bounds, len(fast), tables.box_frame[boxes], tables.body,
                                  tables.self_collides.view(np.uint8), f.group, f.mask, f.mode)
    if f.rules and len(pairs):
        frames = tables.box_frame[boxes]
        pairs = pairs[f.allowed_pairs(frames[pairs[:, 0]], frames[pairs[:, 1]])]
    t2 = time.perf_counter()
    stats.seconds["broad_phase"] += t2 - t1
    stats.candidate_pairs += len(pairs)
    hits = []
    if len(pairs):
        # First contact of each pair on the fitted (conservative) motions.
        tau, solves = _core.first_touches(rows, pairs, fit_tolerance, tolerances._core, penetration, CREEP)
        stats.solver_rows += solves
        hit = np.flatnonzero(~np.isnan(tau))
        hits = [(i, j, t) for (i, j), t in zip(pairs[hit].tolist(), tau[hit].tolist())]
    stats.seconds["solve"] += time.perf_counter() - t2
    return Sweep(rows, boxes, pairs, hits)


def _partners(cid, tables, bounds, slack, exclude):
    """Frames pybullet's broad phase finds within ``slack`` of the given bounds."""
    near = set()
    for b in (bounds + _WIDEN * (slack + 1e-9)).tolist():
        found = raw.getOverlappingObjects(b[:3], b[3:], physicsClientId=cid) or ()
        near.update(tables.index[key] for key in found if key in tables.index)
    return sorted(near.difference(exclude))


def moves_into(cid, tables, moves, frozen_of, widen, fit_tolerance, tolerances, penetration, stats):
    """Kinematic frames moving straight from pose to pose (``moves``: {frame: (pose0,
    pose1)}) against the free bodies standing still: ``frozen_of(partners)`` gives the
    (F, 13) state of the free frames pybullet's broad phase finds within ``widen`` of the
    moves. A Sweep whose first rows are the moving boxes and whose hits have a moving box
    first; None if nothing was met."""
    if not moves:
        return None
    frames = sorted(moves)
    moving = np.array([b for f in frames for b in tables.frame_boxes[f]], dtype=np.int64)
    poses0, poses1 = np.zeros((len(tables.keys), 7)), np.zeros((len(tables.keys), 7))
    for f in frames:
        poses0[f], poses1[f] = moves[f]
    rows = _core.path_rows_between(poses0, poses1, moving, tables.box_frame, tables.X_CS, tables.half)
    bounds = _core.swept_bounds(rows)
    partners = [f for f in _partners(cid, tables, bounds, widen, frames) if tables.kind[f] == FREE]
    if not partners:
        return None
    still = frozen_of(partners).copy()
    still[:, TWIST] = 0.0
    boxes = np.array(moving.tolist() + [b for f in partners for b in tables.frame_boxes[f]], dtype=np.int64)
    more = _core.path_rows(still, 1.0, boxes[len(moving):], tables.box_frame, tables.X_CS, tables.half)
    rows, bounds = np.concatenate([rows, more]), np.concatenate([bounds, _core.swept_bounds(more)])
    f = tables.filters
    pairs = _core.candidate_pairs(bounds, len(moving), tables.box_frame[boxes], tables.body,
                                  tables.self_collides.view(np.uint8), f.group, f.mask, f.mode)
    pairs = pairs[pairs[:, 1] >= len(moving)] if len(pairs) else pairs
    if f.rules and len(pairs):
        fr = tables.box_frame[boxes]
        pairs = pairs[f.allowed_pairs(fr[pairs[:, 0]], fr[pairs[:, 1]])]
    if not len(pairs):
        return None
    tau, solves = _core.first_touches(rows, pairs, fit_tolerance, tolerances._core, penetration, CREEP)
    stats.solver_rows += solves
    hit = np.flatnonzero(~np.isnan(tau))
    hits = [(i, j, t) for (i, j), t in zip(pairs[hit].tolist(), tau[hit].tolist())]
    return Sweep(rows, boxes, pairs, hits) if hits else None


def step_reach(state, tables, dt):
    """The farthest any box's point moves in the step."""
    if not len(tables.radius):
        return 0.0
    twist = state.rows[tables.box_frame]
    return float(np.max((np.linalg.norm(twist[:, 7:10], axis=1) + np.linalg.norm(twist[:, 10:13], axis=1)
                         * tables.radius) * dt))


def jump_sweep(cid, tables, state, dt, fit_tolerance, tolerances, penetration, stats):
    """The kinematic frames' jumps (from E0 to P1, before the step's physics) against the
    free bodies where the step started (on Bullet's path at tau = 0)."""
    if not state.jumps:
        return None

    def at_start(partners):
        state.read_poses(state.stale(partners))
        start = state.rows.copy()
        start[partners, POSE] = _core.frame_poses(state.rows, dt, np.array(partners, dtype=np.int64),
                                                  np.zeros(len(partners)))
        return start

    return moves_into(cid, tables, state.jumps, at_start, step_reach(state, tables, dt), fit_tolerance, tolerances,
                      penetration, stats)
