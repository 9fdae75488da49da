"""The core's step-path functions (the pybullet plugin's per-step work) against
independent references: scipy's rotations for the exact path, the oracle's
separating-axis gap for contact, brute force for the broad phase.
(The path itself is checked against pybullet's integration in test_pybullet_ccd.)"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bullet_boxccd import Outcome, _core
from bullet_boxccd.testing import SIGNS, sat_gap

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


def _pairs_brute_force(bounds, n_fast, frame, frame_body, self_collides, group, mask, mode):
    """The candidate pairs by testing every pair, in the order (i, j)."""
    want = []
    for i in range(n_fast):
        for j in range(len(bounds)):
            fi, fj = frame[i], frame[j]
            meet = np.all(bounds[i, :3] <= bounds[j, 3:]) and np.all(bounds[j, :3] <= bounds[i, 3:])
            ab, ba = (group[fi] & mask[fj]) != 0, (group[fj] & mask[fi]) != 0
            allowed = (ab or ba) if mode == 1 else (ab and ba)
            if (j == i or (j < n_fast and j < i) or not meet or fi == fj or not allowed
                    or (frame_body[fi] == frame_body[fj] and not self_collides[fi])):
                continue
            want.append((i, j))
    return want


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
        got = [tuple(x) for x in _core.candidate_pairs(bounds, n_fast, frame, frame_body, self_collides, group, mask,
                                                       mode).tolist()]
        assert got == _pairs_brute_force(bounds, n_fast, frame, frame_body, self_collides, group, mask, mode)


def test_candidate_pairs_of_many_boxes_match_brute_force():
    """Worlds large enough for the sorted sweep: the same pairs in the same order as
    testing every pair, with bounds that share their ends, touch exactly, or hold a NaN."""
    rng = np.random.default_rng(11)
    for trial in range(30):
        n = int(rng.integers(60, 300))
        n_fast = int(rng.integers(20, n + 1))
        n_frames = int(rng.integers(n // 2, n + 1))
        centre, half = rng.uniform(0.0, 2.0, (n, 3)), rng.uniform(0.0, 0.2, (n, 3))
        if trial % 2:  # on a grid: equal ends and exactly touching bounds
            centre, half = np.round(centre, 1), np.full((n, 3), 0.05)
        bounds = np.hstack([centre - half, centre + half])
        bounds[rng.integers(0, n, 3), rng.integers(0, 6, 3)] = np.nan
        frame = rng.integers(0, n_frames, n).astype(np.int64)
        frame_body = rng.integers(0, 40, n_frames).astype(np.int64)
        self_collides = (rng.random(n_frames) < 0.5).astype(np.uint8)
        group = rng.choice([1, 2, 4, 0], n_frames).astype(np.int64)
        mask = rng.choice([-1, -3, 1, 0, 6], n_frames).astype(np.int64)
        mode = trial % 2
        got = [tuple(x) for x in _core.candidate_pairs(bounds, n_fast, frame, frame_body, self_collides, group, mask,
                                                       mode).tolist()]
        want = _pairs_brute_force(bounds, n_fast, frame, frame_body, self_collides, group, mask, mode)
        assert got == want and len(want) > 0


def test_swept_bounds_contain_the_exact_path():
    rng = np.random.default_rng(5)
    for _ in range(100):
        state = random_state(rng, 3 * np.pi / DT)
        X_CS, half = random_box(rng)
        b = _core.swept_bounds(rows_of([state], [(0, X_CS, half)]))[0]
        V = exact_vertices(state, X_CS, half, np.linspace(0, 1, 201)).reshape(-1, 3)
        assert np.all(V >= b[:3]) and np.all(V <= b[3:])


def sweeper_of(boxes, radius, sweep_reach, n_frames, frame_body=None, self_collides=None, group=None, mask=None,
               mode=1):
    frame = np.array([f for f, _, _ in boxes], dtype=np.int64)
    X_CS = np.array([X for _, X, _ in boxes])
    half = np.array([h for _, _, h in boxes])
    ones = np.ones(n_frames, dtype=np.int64)
    return _core.Sweeper(frame, np.asarray(radius, dtype=float), X_CS, half, np.asarray(sweep_reach, dtype=float),
                         np.arange(n_frames, dtype=np.int64) if frame_body is None else frame_body,
                         np.zeros(n_frames, dtype=np.uint8) if self_collides is None else self_collides,
                         ones if group is None else group, -ones if mask is None else mask, mode)


def test_fast_boxes_and_slack():
    """A box is fast when (|v| + |w| r) dt exceeds its threshold; the slack is the
    largest reach of the others; a non-finite state is left alone."""
    states = np.zeros((3, 13))
    states[:, 6] = 1.0
    states[0, 7] = 10.0  # 10 m/s: reach 10 dt
    states[1, 12] = 100.0  # 100 rad/s at r = 0.2: reach 20 dt
    states[2, 7] = np.nan
    boxes = [(f, np.eye(4), np.full(3, 0.1)) for f in range(3)]
    sweeper = sweeper_of(boxes, np.full(3, 0.2), [15 * DT, 15 * DT, 0.0], 3)
    sweeper.state[:] = states
    fast, slack, frames, broken, clamped = sweeper.fast(DT)
    assert fast == [1] and frames == [1] and slack == pytest.approx(10 * DT) and broken == [2] and clamped == []
    # With a clamp speed: frame 1 turns at 100 rad/s, frame 0 moves at 10 m/s; frame 2 (not
    # finite) is neither.
    assert sweeper.fast(DT, clamp=100.0)[4] == [1] and sweeper.fast(DT, clamp=10.0)[4] == [0, 1]
    # pybullet's velocity reads written first: frame 1 stops, frame 0 speeds up to 20 m/s.
    fast, _, frames, _, _ = sweeper.fast(DT, [0, 1], [((20.0, 0.0, 0.0), (0.0, 0.0, 0.0)), ((0.0,) * 3, (0.0,) * 3)])
    assert fast == [0] and frames == [0] and sweeper.state[0, 7] == 20.0 and sweeper.state[1, 12] == 0.0
    sweeper.state[0, 7] = 0.0
    assert sweeper.fast(DT) == ([], 0.0, [], [2], [])  # nothing fast, one frame not finite
    sweeper.state[2, 7] = 0.0
    assert sweeper.fast(DT) is None
    sweeper.state[0, 7] = 10.0  # slow, at a clamp of 10 m/s
    assert sweeper.fast(DT) is None and sweeper.fast(DT, clamp=10.0) == ([], pytest.approx(10 * DT), [], [], [0])


@pytest.mark.parametrize("all_others", [False, True])
def test_sweeper_touches_is_its_parts(all_others):
    """The sweeper's one call gives what its parts give: path rows of the boxes (the
    fast ones first, then the given others or every other box), candidate pairs, and
    first touches (each part is checked against its reference above)."""
    rng = np.random.default_rng(11)
    tol = _core.Tolerances()
    touched = 0
    for trial in range(30):
        n_frames = 6
        states = np.array([random_state(rng, 60.0) for _ in range(n_frames)])
        states[:, :3] *= 0.15
        boxes = [(int(rng.integers(0, n_frames)), *random_box(rng)) for _ in range(9)]
        frame_body = rng.integers(0, 4, n_frames).astype(np.int64)
        group = rng.choice([1, 2, 3], n_frames).astype(np.int64)
        mask = rng.choice([-1, 1, 2], n_frames).astype(np.int64)
        self_collides = (rng.random(n_frames) < 0.5).astype(np.uint8)
        sw = sweeper_of(boxes, np.full(9, 0.3), np.zeros(9), n_frames, frame_body, self_collides, group, mask,
                        trial % 2)
        order = rng.permutation(9).astype(np.int64)
        n_fast = int(rng.integers(1, 5))
        given = order[:n_fast] if all_others else order[:n_fast + int(rng.integers(0, 9 - n_fast))]
        sw.state[:] = states
        outcomes = np.zeros(len(Outcome), dtype=np.int64)
        n_pairs, solves, found = sw.touches(DT, given.tolist(), n_fast, all_others, FIT_TOLERANCE, tol, 0.0, 0.02,
                                            outcomes)
        want_boxes = np.concatenate([given, np.setdiff1d(np.arange(9), given)]) if all_others else given
        rows = rows_of(states, boxes)[want_boxes]
        frame = np.array([f for f, _, _ in boxes], dtype=np.int64)[want_boxes]
        want_pairs = _core.candidate_pairs(_core.swept_bounds(rows), n_fast, frame, frame_body, self_collides, group,
                                           mask, trial % 2)
        want_tau, want_states, want_solves = _core.first_touches(rows, want_pairs, FIT_TOLERANCE, tol, 0.0, 0.02,
                                                                 states=True)
        assert n_pairs == len(want_pairs) and solves == want_solves
        # Every candidate pair's outcome is counted; a touch is never counted as SEPARATED.
        assert outcomes.tolist() == np.bincount(want_states, minlength=len(Outcome)).tolist()
        assert np.array_equal(np.isin(want_states, [Outcome.SEPARATED, Outcome.NON_FINITE]), np.isnan(want_tau))
        hit = ~np.isnan(want_tau)
        if not hit.any():
            assert found is None
            continue
        touched += 1
        got_boxes, got_rows, pairs, hits = found
        assert got_boxes.tolist() == want_boxes.tolist()
        np.testing.assert_array_equal(got_rows, rows)
        np.testing.assert_array_equal(pairs, want_pairs)
        assert hits == [(i, j, t) for (i, j), t in zip(want_pairs[hit].tolist(), want_tau[hit].tolist())]
    assert touched >= 5


def test_first_depth_finds_the_first_time_the_depth_reaches_the_target():
    """first_depth against a dense scan (every 1/4000 of the window): where the scan sees
    the depth reach the target, first_depth answers no later; where first_depth answers,
    the depth is at the target there and no scanned sample before it reaches it (an
    excursion between two of its look-ahead samples, a box passing through and out again,
    is found). The depth never grows faster than the boxes' travel (the bound its skips
    and its splits of a gap rely on)."""
    rng = np.random.default_rng(17)
    found = 0
    for _ in range(150):
        states = np.array([random_state(rng, 80.0) for _ in range(2)])
        states[:, :3] *= 0.1
        boxes = rows_of(states, [(0, *random_box(rng)), (1, *random_box(rng))])
        tau_from = float(rng.choice([0.0, rng.uniform(0, 0.9)]))
        pair = _core.RowBoxPath(boxes[0]), _core.RowBoxPath(boxes[1])
        target = max(_core.paths_separation(*pair, tau_from)[0], 0.0) + rng.uniform(1e-4, 0.02)
        got = _core.paths_first_depth(*pair, tau_from, target)
        taus = np.linspace(tau_from, 1.0, 4001)[1:]
        scan = np.array([_core.paths_separation(*pair, t)[0] for t in taus])
        reached = taus[scan >= target]
        if len(reached):
            assert got <= reached[0], (got, reached[0])
        if not np.isnan(got):
            assert _core.paths_separation(*pair, got)[0] >= target - 1e-12
            assert not np.any(scan[taus < got - 1e-9] >= target)
        found += not np.isnan(got)
        col = {k: slice(*v) for k, v in _core.layouts()["path_row"].items()}
        reach = [np.linalg.norm(b[col["box_in_frame"]].reshape(4, 4)[:3, 3]) + np.linalg.norm(b[col["half_extents"]])
                 for b in boxes]
        travel = sum(np.linalg.norm(b[col["displacement"]]) + abs(b[col["angle"]][0]) * r for b, r in zip(boxes, reach))
        grid = np.linspace(0, 1, 101)
        depth = np.maximum([_core.paths_separation(*pair, t)[0] for t in grid], 0.0)
        assert np.all(np.abs(np.diff(depth)) <= travel * np.diff(grid) + 1e-12)
    assert found >= 20


def test_reads_go_into_the_frame_state_rows():
    """pybullet's read tuples go into the named columns of the sweeper's rows (a view
    that stays valid); bad reads raise."""
    sweeper = sweeper_of([(f, np.eye(4), np.full(3, 0.1)) for f in range(3)], np.ones(3), np.ones(3), 3)
    rows = sweeper.state
    assert rows[:, :7].tolist() == [[0, 0, 0, 0, 0, 0, 1]] * 3  # at the origin, unturned
    sweeper.put_poses([2, 0], [((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0)), ((4.0, 5.0, 6.0), (1.0, 0.0, 0.0, 0.0))])
    assert rows[2, :7].tolist() == [1, 2, 3, 0, 0, 0, 1] and rows[0, :7].tolist() == [4, 5, 6, 1, 0, 0, 0]
    sweeper.put_twists([1, 0], [((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)), ((0.0, 2.0, 0.0), (3.0, 0.0, 0.0))])
    assert rows[1, 7:].tolist() == [1, 0, 0, 0, 0, 1] and rows[0, 7:].tolist() == [0, 2, 0, 3, 0, 0]
    del sweeper  # the view keeps the rows alive
    assert rows[1, 12] == 1.0
    sweeper = sweeper_of([(0, np.eye(4), np.full(3, 0.1))], np.ones(1), np.ones(1), 1)
    with pytest.raises(ValueError, match="equal length"):
        sweeper.put_poses([0, 0], [((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0))])
    with pytest.raises(IndexError, match="frame index 5"):
        sweeper.put_poses([5], [((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0))])
    with pytest.raises(IndexError, match="box index 3"):
        sweeper.touches(DT, [3], 1, True, FIT_TOLERANCE, _core.Tolerances(), 0.0, 0.02)


def test_bad_indices_raise_index_error():
    states = np.zeros((1, 13))
    with pytest.raises(IndexError, match="frame index 3"):
        _core.frame_poses(states, DT, np.array([3], dtype=np.int64), np.zeros(1))
    rows = rows_of(states, [(0, np.eye(4), np.ones(3))])
    with pytest.raises(IndexError, match="row index 1"):
        _core.first_touches(rows, np.array([[0, 1]], dtype=np.int64), FIT_TOLERANCE, _core.Tolerances())
