"""The core's step-path functions (the pybullet plugin's per-step work) against
independent references: scipy's rotations for the exact path, the oracle's
separating-axis gap for contact, brute force for the broad phase.
(The path itself is checked against pybullet's integration in test_pybullet_ccd.)"""

from __future__ import annotations

import numpy as np
import pytest
from oracle import SIGNS, sat_gap
from scipy.spatial.transform import Rotation

from bullet_boxccd import _core

DT = 1.0 / 240.0
FIT_TOLERANCE = 0.05


def bullet_angle(speed, dt):
    a = speed * dt
    return 2 * np.arctan(a / (np.pi / 4) * np.tan(np.pi / 8)) if a > np.pi / 4 else a


def random_state(rng, max_spin):
    q = rng.normal(size=4)
    w = rng.normal(size=3)
    w *= rng.uniform(0, max_spin) / np.linalg.norm(w)
    return np.concatenate([rng.uniform(-1, 1, 3), q / np.linalg.norm(q), rng.uniform(-30, 30, 3), w])


def random_box(rng):
    X = np.eye(4)
    X[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    X[:3, 3] = rng.uniform(-0.1, 0.1, 3) * rng.integers(0, 2)  # half of them at the centre of mass
    return X, rng.uniform(0.01, 0.1, 3)


def exact_vertices(state, X_CS, half, taus):
    """(len(taus), 8, 3) world corners at the step fractions taus: the frame turned
    back about w by (1 - tau) of Bullet's step angle and moved back by (1 - tau) v dt."""
    taus = np.atleast_1d(np.asarray(taus, dtype=float))
    w = state[10:]
    speed = np.linalg.norm(w)
    axis = w / speed if speed else np.zeros(3)
    turn = Rotation.from_rotvec(np.outer((taus - 1) * bullet_angle(speed, DT), axis))
    R = (turn * Rotation.from_quat(state[3:7])).as_matrix() @ X_CS[:3, :3]  # (n, 3, 3)
    origin = state[:3] + np.outer(taus - 1, state[7:10] * DT)
    centre = origin + (turn * Rotation.from_quat(state[3:7])).apply(X_CS[:3, 3])
    return np.einsum("nij,vj->nvi", R, SIGNS * half) + centre[:, None, :]


def rows_of(states, boxes):
    """Path rows of boxes [(frame, X_CS, half)] on frames with the given states."""
    frame = np.array([f for f, _, _ in boxes], dtype=np.int64)
    X_CS = np.array([X for _, X, _ in boxes])
    half = np.array([h for _, _, h in boxes])
    return _core.path_rows(np.asarray(states), DT, np.arange(len(boxes), dtype=np.int64), frame, X_CS, half)


def test_fit_error_bound_holds():
    """Every corner of the fitted motion stays within error * r of the exact path
    (r: the corner's distance from the frame's origin), for spins up to 4x Bullet's
    clamp and windows of the whole step and parts of it."""
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(300):
        state = random_state(rng, max_spin=4 * np.pi / DT)
        X_CS, half = random_box(rng)
        row = rows_of([state], [(0, X_CS, half)])[0]
        lo, hi = sorted(rng.uniform(0, 1, 2)) if rng.random() < 0.5 else (0.0, 1.0)
        coeffs, err = _core.fit_path(row, lo, hi)
        assert 0 <= err < 0.5
        r = np.linalg.norm((SIGNS * half) @ X_CS[:3, :3].T + X_CS[:3, 3], axis=1)
        for t in np.linspace(0, 1, 41):
            M = coeffs[0] + t * coeffs[1] + t * t * coeffs[2]
            fitted = (SIGNS * half) @ M[:3, :3].T + M[:3, 3]
            dev = np.linalg.norm(fitted - exact_vertices(state, X_CS, half, lo + t * (hi - lo))[0], axis=1)
            assert np.all(dev <= err * r * (1 + 1e-9) + 1e-12), (dev, err * r)
            worst = max(worst, float(np.max(dev / np.maximum(err * r, 1e-300))))
    assert worst > 0.3  # the bound is not vacuous: some corner comes within a factor 3 of it


def first_true_touch(states, boxes, n=4001):
    """(first sampled tau with sat_gap <= 0 or None, gaps at the samples) on the exact path."""
    taus = np.linspace(0, 1, n)
    (fa, Xa, ha), (fb, Xb, hb) = boxes
    gaps = sat_gap(exact_vertices(states[fa], Xa, ha, taus), exact_vertices(states[fb], Xb, hb, taus))
    inside = np.flatnonzero(gaps <= 0)
    return (taus[inside[0]] if len(inside) else None), taus, gaps


@pytest.mark.parametrize("seed", range(4))
def test_first_touch_is_never_late_and_never_missed(seed):
    """first_touches on random fast pairs (one spinning up to 3x the clamp and thrown
    at the other, which may move too): no sampled overlap on the exact path before
    the answer, none at all when it says apart, and the boxes at most a few fit
    tolerances apart at the answer."""
    rng = np.random.default_rng(100 + seed)
    hits = misses = 0
    for _ in range(40):
        sa, sb = random_state(rng, 3 * np.pi / DT), random_state(rng, 50.0 * rng.integers(0, 2))
        # Aim A at B: its step displacement ends near B's centre.
        sa[:3] = sb[:3] + rng.uniform(-0.1, 0.1, 3)
        sa[7:10] = rng.uniform(-1, 1, 3) * 200.0
        boxes = [(0, *random_box(rng)), (1, *random_box(rng))]
        rows = rows_of([sa, sb], boxes)
        taus, solves = _core.first_touches(rows, np.array([[0, 1]], dtype=np.int64), FIT_TOLERANCE,
                                           _core.Tolerances())
        tau = taus[0]
        assert solves >= 1
        true_tau, taus, gaps = first_true_touch([sa, sb], boxes)
        if np.isnan(tau):
            misses += 1
            assert true_tau is None, f"missed a touch at tau {true_tau}"
            continue
        hits += 1
        assert np.all(gaps[taus < tau - 1e-12] > -1e-12), "late: the exact boxes overlap before the answer"
        VA, VB = (exact_vertices([sa, sb][f], X, h, tau) for f, X, h in boxes)
        slack = 0.3 * (boxes[0][2].min() + boxes[1][2].min())
        assert sat_gap(VA, VB)[0] <= slack
    assert hits >= 10 and misses >= 3


def test_candidate_pairs_match_brute_force():
    """Pairs whose swept bounds meet, at least one fast, each once, with the frame,
    body, self-collision and collision-filter rules (groups and masks in both of
    pybullet's modes), against a brute-force loop."""
    rng = np.random.default_rng(3)
    for trial in range(40):
        n_frames = 8
        states = np.array([random_state(rng, 100.0) for _ in range(n_frames)])
        states[:, :3] *= 0.3
        frame_body = rng.integers(0, 5, n_frames).astype(np.int64)
        self_collides = (rng.random(n_frames) < 0.5).astype(np.uint8)
        group = rng.choice([1, 2, 4, 0], n_frames).astype(np.int64)
        mask = rng.choice([-1, -3, 1, 0, 6], n_frames).astype(np.int64)
        mode = trial % 2
        boxes = [(int(rng.integers(0, n_frames)), *random_box(rng)) for _ in range(12)]
        rows = rows_of(states, boxes)
        n_fast = int(rng.integers(0, 6))
        frame = np.array([f for f, _, _ in boxes], dtype=np.int64)
        bounds = _core.swept_bounds(rows)
        got = {tuple(x) for x in _core.candidate_pairs(bounds, n_fast, frame, frame_body, self_collides, group, mask,
                                                       mode).tolist()}
        want = set()
        for i in range(n_fast):
            for j in range(len(boxes)):
                fi, fj = frame[i], frame[j]
                meet = np.all(bounds[i, :3] <= bounds[j, 3:]) and np.all(bounds[j, :3] <= bounds[i, 3:])
                ab, ba = (group[fi] & mask[fj]) != 0, (group[fj] & mask[fi]) != 0
                allowed = (ab or ba) if mode == 1 else (ab and ba)
                if (j == i or (j < n_fast and j < i) or not meet or fi == fj or not allowed
                        or (frame_body[fi] == frame_body[fj] and not self_collides[fi])):
                    continue
                want.add((i, j))
        assert got == want


def test_swept_bounds_contain_the_exact_path():
    rng = np.random.default_rng(5)
    for _ in range(100):
        state = random_state(rng, 3 * np.pi / DT)
        X_CS, half = random_box(rng)
        b = _core.swept_bounds(rows_of([state], [(0, X_CS, half)]))[0]
        V = exact_vertices(state, X_CS, half, np.linspace(0, 1, 201)).reshape(-1, 3)
        assert np.all(V >= b[:3]) and np.all(V <= b[3:])


def test_fast_boxes_and_slack():
    """A box is fast when (|v| + |w| r) dt exceeds its threshold; the slack is the
    largest reach of the others; a non-finite state is left alone."""
    states = np.zeros((3, 13))
    states[:, 6] = 1.0
    states[0, 7] = 10.0  # 10 m/s: reach 10 dt
    states[1, 12] = 100.0  # 100 rad/s at r = 0.2: reach 20 dt
    states[2, 7] = np.nan
    fast, slack = _core.fast_boxes(states, DT, np.arange(3, dtype=np.int64), np.full(3, 0.2),
                                   np.array([15 * DT, 15 * DT, 0.0]))
    assert fast.tolist() == [1] and slack == pytest.approx(10 * DT)


def test_bad_indices_raise_index_error():
    states = np.zeros((1, 13))
    with pytest.raises(IndexError, match="frame index 3"):
        _core.frame_poses(states, DT, np.array([3], dtype=np.int64), np.zeros(1))
    rows = rows_of(states, [(0, np.eye(4), np.ones(3))])
    with pytest.raises(IndexError, match="row index 1"):
        _core.first_touches(rows, np.array([[0, 1]], dtype=np.int64), FIT_TOLERANCE, _core.Tolerances())
