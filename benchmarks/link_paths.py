"""Link paths, measured: Bullet's rules against pybullet, the fit bound's tightness, timings.

What it measures
----------------
1. ``rule``: ``--bodies`` random createMultiBody bodies (1-8 links, joint types
   revolute, prismatic, spherical and fixed with random frames, inertial offsets and
   axes; a quarter with a fixed base; joint and base rates up to 20 or 400 rad/s,
   i.e. above the pi/4-per-step clamp; every fifth with pybullet's default joint
   velocity limit of 100) are stepped once at 1/240 s. From the state after the step,
   the core rebuilds the start (tau = 0); each row is the largest disagreement with
   what pybullet reported before the step: the base's position and rotation (matrix
   entries), each joint kind's coordinates (a spherical joint's rotation as a
   matrix), and every link's centre-of-mass frame (getLinkState, computeForward-
   Kinematics=1), at tau = 0 and tau = 1.
2. ``fit``: random chains of 5-10 links (mostly serial, some branches), joint and
   base rates up to 200 rad/s at 1/240 s; per case one link, a radius r in [0, 0.5] m
   and 40 points at distance r: bound / (largest error of the points' fitted places
   over 101 samples), over the whole step and over one of the pieces that
   ``LinkBoxPath.pieces(0.05)`` picks for a random box on that link; and the pieces
   picked.
3. ``time``: median over ``--repeats`` runs of the calls from Python (call overhead
   included; ``base_pose`` is the baseline of a call that does almost nothing):
   ``link_poses`` of a 7- and a 15-link chain, ``LinkBoxPath.fit`` of the last link,
   ``paths_first_touch`` of a box on the last link against a static box (touching and
   missing pairs at 200 rad/s).

Output: the table on stdout and benchmarks/results/link_paths.csv.

Run
---
    python benchmarks/link_paths.py            # ~30 s
"""

from __future__ import annotations

import argparse
import csv
import os
import time

import numpy as np
import pybullet as p
from scipy.spatial.transform import Rotation

from bullet_boxccd import _core
from bullet_boxccd.pybullet_ccd.chain import read_base_state, read_chain, read_joint_state

DT = 1.0 / 240.0
Q_SIZE = {0: 1, 1: 1, 2: 4, 4: 0}
QDOT_SIZE = {0: 1, 1: 1, 2: 3, 4: 0}
KIND = {0: "revolute", 1: "prismatic", 2: "spherical"}


def matrix(q):
    """scipy's rotation matrix of a quaternion: independent of the core and of bullet_boxccd.motion."""
    return Rotation.from_quat(q).as_matrix()


def stats(values):
    v = np.asarray(values, dtype=float)
    return [len(v), v.min(), np.median(v), np.percentile(v, 90), v.max()]


# --- 1. the rule -------------------------------------------------------------------------------------------


def random_body(cid, rng):
    n = int(rng.integers(1, 9))
    fixed = rng.random() < 0.25
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(DT, physicsClientId=cid)
    p.setGravity(0, 0, -9.81, physicsClientId=cid)
    box = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05, 0.04, 0.03], physicsClientId=cid)
    q = Rotation.random(2 * n + 2, random_state=rng).as_quat()
    body = p.createMultiBody(
        0.0 if fixed else 1.0, box, basePosition=rng.uniform(-1, 1, 3), baseOrientation=q[0],
        baseInertialFramePosition=rng.uniform(-0.2, 0.2, 3), baseInertialFrameOrientation=q[1],
        linkMasses=list(rng.uniform(0.2, 2.0, n)), linkCollisionShapeIndices=[box] * n,
        linkVisualShapeIndices=[-1] * n, linkPositions=list(rng.uniform(-0.5, 0.5, (n, 3))),
        linkOrientations=list(q[2:n + 2]), linkInertialFramePositions=list(rng.uniform(-0.3, 0.3, (n, 3))),
        linkInertialFrameOrientations=list(q[n + 2:]),
        linkParentIndices=[int(rng.integers(0, i + 1)) for i in range(n)],
        linkJointTypes=[int(k) for k in rng.choice([0, 1, 2, 4], n)], linkJointAxis=list(rng.normal(size=(n, 3))),
        physicsClientId=cid)
    return body, n


def measure_rule(cid, rng, bodies):
    gaps = {}

    def note(key, value):
        gaps.setdefault(key, []).append(float(value))

    for trial in range(bodies):
        body, n = random_body(cid, rng)
        limit = 100.0 if trial % 5 == 0 else 1e4
        p.changeDynamics(body, -1, linearDamping=0, angularDamping=0, physicsClientId=cid)
        chain = read_chain(cid, body)
        rate = 400.0 if trial % 2 else 20.0
        for j, kind in enumerate(chain.joint_type):
            p.changeDynamics(body, j, linearDamping=0, angularDamping=0, jointDamping=0, maxJointVelocity=limit,
                             physicsClientId=cid)
            if kind == 2:
                w = rng.normal(size=3)
                p.resetJointStateMultiDof(body, j, Rotation.random(random_state=rng).as_quat(),
                                          w / np.linalg.norm(w) * rng.uniform(0, rate), physicsClientId=cid)
            elif kind != 4:
                p.resetJointState(body, j, rng.normal(), rng.uniform(-rate, rate), physicsClientId=cid)
                p.setJointMotorControl2(body, j, p.VELOCITY_CONTROL, force=0, physicsClientId=cid)
        w = rng.normal(size=3)
        p.resetBaseVelocity(body, rng.normal(size=3) * 3, w / np.linalg.norm(w) * rng.uniform(0, rate),
                            physicsClientId=cid)
        before = [p.getLinkState(body, j, computeForwardKinematics=1, physicsClientId=cid) for j in range(n)]
        base0 = p.getBasePositionAndOrientation(body, physicsClientId=cid)
        q0, _ = read_joint_state(cid, body, n)
        p.stepSimulation(physicsClientId=cid)
        after = [p.getLinkState(body, j, computeForwardKinematics=1, physicsClientId=cid) for j in range(n)]
        q1, qdot1 = read_joint_state(cid, body, n)
        motion = chain.motion(read_base_state(cid, body), q1, qdot1, DT)
        start = motion.base_pose(0.0)
        note("base position", np.abs(start[:3] - base0[0]).max())
        note("base rotation", np.abs(matrix(start[3:]) - matrix(base0[1])).max())
        q_start = motion.joint_positions(0.0)
        for j, kind in enumerate(chain.joint_type):
            k = chain.q_index[j]
            if kind == 2:
                note("spherical q", np.abs(matrix(q_start[k:k + 4]) - matrix(q0[k:k + 4])).max())
            elif kind != 4:
                note(f"{KIND[int(kind)]} q", abs(q_start[k] - q0[k]))
        for tau, states in ((0.0, before), (1.0, after)):
            poses = motion.link_poses(tau)
            note(f"links at tau = {tau:g}", max(max(np.abs(x[:3] - s[0]).max(),
                                                   np.abs(matrix(x[3:]) - matrix(s[1])).max())
                                               for x, s in zip(poses, states)))
    return [["rule", key, *stats(v)] for key, v in gaps.items()]


# --- 2. the fit bound --------------------------------------------------------------------------------------


def random_chain(rng, n):
    parent = np.array([i - 1 if rng.random() < 0.7 else int(rng.integers(-1, i)) for i in range(n)], np.int64)
    kinds = rng.choice([0, 1, 2, 4], n, p=[0.5, 0.15, 0.25, 0.1]).astype(np.int64)
    q_index = np.concatenate([[0], np.cumsum([Q_SIZE[int(k)] for k in kinds])[:-1]]).astype(np.int64)
    qdot_index = np.concatenate([[0], np.cumsum([QDOT_SIZE[int(k)] for k in kinds])[:-1]]).astype(np.int64)
    chain = _core.Chain(parent, kinds, rng.normal(size=(n, 3)), rng.uniform(-0.3, 0.3, (n, 3)),
                        Rotation.random(n, random_state=rng).as_quat(), rng.uniform(-0.15, 0.15, (n, 3)),
                        Rotation.random(n, random_state=rng).as_quat(), q_index, qdot_index)
    q, qdot = np.zeros(chain.n_q), np.zeros(chain.n_qdot)
    for j, kind in enumerate(kinds):
        k, u = q_index[j], qdot_index[j]
        if kind in (0, 1):
            q[k], qdot[u] = rng.normal(), rng.uniform(-200, 200) * (0.1 if kind == 1 else 1.0)
        elif kind == 2:
            w = rng.normal(size=3)
            q[k:k + 4], qdot[u:u + 3] = Rotation.random(random_state=rng).as_quat(), w / np.linalg.norm(w) * 200
    w = rng.normal(size=3)
    state = np.concatenate([rng.uniform(-1, 1, 3), Rotation.random(random_state=rng).as_quat(),
                            rng.normal(size=3) * 3, w / np.linalg.norm(w) * rng.uniform(0, 200)])
    return chain, _core.ChainMotion(chain, state, q, qdot, DT)


def fit_ratio(motion, link, lo, hi, r, rng):
    coeffs, bound, *_ = motion.fit(link, lo, hi, r)
    d = rng.normal(size=(40, 3))
    points = d / np.linalg.norm(d, axis=1)[:, None] * r
    s = np.linspace(0, 1, 101)
    X = _core.LinkBoxPath(motion, link, np.eye(4), np.ones(3)).poses(lo + s * (hi - lo))
    M = coeffs[0] + s[:, None, None] * coeffs[1] + (s * s)[:, None, None] * coeffs[2]
    err = np.einsum("nij,mj->nmi", X[:, :3, :3] - M[:, :3, :3], points) + (X[:, None, :3, 3] - M[:, None, :3, 3])
    return bound / np.linalg.norm(err, axis=2).max()


def measure_fit(rng, cases):
    whole, pieced, counts = [], [], []
    for _ in range(cases):
        chain, motion = random_chain(rng, int(rng.integers(5, 11)))
        link = int(rng.integers(0, chain.n_links))
        r = rng.uniform(0, 0.5)
        whole.append(fit_ratio(motion, link, 0.0, 1.0, r, rng))
        X_CS = np.eye(4)
        X_CS[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        half = rng.uniform(0.01, 0.1, 3)
        n = _core.LinkBoxPath(motion, link, X_CS, half).pieces(0.05)
        counts.append(n)
        k = int(rng.integers(0, n))
        pieced.append(fit_ratio(motion, link, k / n, (k + 1) / n, r, rng))
    return [["fit", "bound / observed, whole step", *stats(whole)],
            ["fit", "bound / observed, one of pieces(0.05)", *stats(pieced)],
            ["fit", "pieces(0.05)", *stats(counts)]]


# --- 3. timings --------------------------------------------------------------------------------------------


def median_us(fn, repeats):
    for _ in range(max(10, repeats // 10)):  # warm-up
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e6 * float(np.median(times))


def measure_time(rng, repeats):
    rows = []
    tol = _core.Tolerances()

    def timed(item, count, us):
        rows.append(["time", item + " [us]", count, "", us, "", ""])

    for n in (7, 15):
        chain, motion = random_chain(rng, n)
        timed(f"base_pose (baseline), {n} links", repeats, median_us(lambda: motion.base_pose(0.5), repeats))
        timed(f"link_poses, {n} links", repeats, median_us(lambda: motion.link_poses(0.5), repeats))
        box = _core.LinkBoxPath(motion, n - 1, np.eye(4), np.array([0.05, 0.04, 0.03]))
        timed(f"LinkBoxPath.fit, link {n - 1} of {n}", repeats, median_us(lambda b=box: b.fit(0.0, 1.0), repeats))
        for label, distance in (("touching", 0.0), ("missing", 0.5)):
            times, counts = [], []
            for _ in range(20):
                chain, motion = random_chain(rng, n)
                box = _core.LinkBoxPath(motion, n - 1, np.eye(4), np.array([0.05, 0.04, 0.03]))
                X = box.pose(rng.uniform(0, 1))
                state = np.concatenate([X[:3, 3] + [distance + 0.06, 0, 0], [0, 0, 0, 1.0], np.zeros(6)])
                row = _core.path_rows(state[None], DT, np.array([0]), np.array([0]), np.eye(4)[None],
                                      np.array([[0.05, 0.05, 0.05]]))[0]
                other = _core.RowBoxPath(row)
                times.append(median_us(lambda b=box, o=other: _core.paths_first_touch(b, o, 0.05, tol),
                                       max(10, repeats // 20)))
                counts.append(box.pieces(0.05))
            timed(f"paths_first_touch, {label}, link {n - 1} of {n} (pieces {min(counts)}-{max(counts)})", 20,
                  float(np.median(times)))
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--bodies", type=int, default=400)
    parser.add_argument("--cases", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=2000)
    parser.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results", "link_paths.csv"))
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    cid = p.connect(p.DIRECT)
    rows = measure_rule(cid, rng, args.bodies) + measure_fit(rng, args.cases) + measure_time(rng, args.repeats)
    p.disconnect(cid)
    header = ["section", "item", "count", "min", "median", "p90", "max"]
    with open(args.out, "w", newline="") as f:
        csv.writer(f).writerows([header, *rows])
    for row in rows:
        print(f"{row[0]:5s} {row[1]:66s} " + " ".join(f"{x:10.3g}" if isinstance(x, float) else f"{x:>10}"
                                                     for x in row[2:]))


if __name__ == "__main__":
    main()
