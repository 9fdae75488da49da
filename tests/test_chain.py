"""Link paths (_core/paths/chain.hpp, pybullet_ccd/chain.py) against pybullet itself, and
their fits and first touches against dense sampling.

* Bullet's integration rules: every link's frame rebuilt at tau = 0 from the state
  after a step matches getLinkState before it, at tau = 1 after it, and at any tau
  matches pybullet's own forward kinematics of the joints put at q(tau).
* The fit's error bound holds at dense samples for random fast chains (and is not
  vacuous); the pieces keep the growth within the fit tolerance.
* The first touch of link boxes (against static, free and link boxes) is never later
  than the first sampled touch of the exact paths, and never misses one.
"""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest
from scipy.spatial.transform import Rotation

from bullet_boxccd import _core
from bullet_boxccd.pybullet_ccd.chain import read_base_state, read_chain, read_joint_state
from bullet_boxccd.testing import SIGNS, sat_gap

DT = 1.0 / 240.0
FIT_TOLERANCE = 0.05
Q_SIZE = {0: 1, 1: 1, 2: 4, 4: 0}
QDOT_SIZE = {0: 1, 1: 1, 2: 3, 4: 0}
URDFS = ["r2d2.urdf", "cartpole.urdf", "kuka_iiwa/model.urdf", "humanoid/humanoid.urdf"]


# Rotations through scipy on purpose: an independent reference for the core's frames (not
# bullet_boxccd.motion's quaternion helpers, which the plugin uses).
def random_quat(rng, n=None):
    return Rotation.random(n, random_state=rng).as_quat()


def rotation_gap(q_a, q_b):
    """Largest entry of the difference of the two rotations' matrices."""
    return float(np.abs(Rotation.from_quat(q_a).as_matrix() - Rotation.from_quat(q_b).as_matrix()).max())


def pose_gap(poses, link_states):
    """Largest position or rotation-matrix entry difference of (n, 7) poses from getLinkState's [0:2]."""
    gap = 0.0
    for pose, state in zip(poses, link_states):
        gap = max(gap, float(np.abs(pose[:3] - state[0]).max()), rotation_gap(pose[3:], state[1]))
    return gap


# --- pybullet bodies ---------------------------------------------------------------------------------------


def random_multibody(cid, rng, n, fixed_base, max_joint_velocity=1e4):
    """A createMultiBody body of n box links with random frames, inertial offsets, joint
    types (revolute, prismatic, spherical, fixed), axes and parents, no damping."""
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(DT, physicsClientId=cid)
    p.setGravity(0, 0, -9.81, physicsClientId=cid)
    box = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05, 0.04, 0.03], physicsClientId=cid)
    kinds = rng.choice([p.JOINT_REVOLUTE, p.JOINT_PRISMATIC, p.JOINT_SPHERICAL, p.JOINT_FIXED], n)
    body = p.createMultiBody(
        0.0 if fixed_base else 1.0, box, basePosition=rng.uniform(-1, 1, 3), baseOrientation=random_quat(rng),
        baseInertialFramePosition=rng.uniform(-0.2, 0.2, 3), baseInertialFrameOrientation=random_quat(rng),
        linkMasses=list(rng.uniform(0.2, 2.0, n)), linkCollisionShapeIndices=[box] * n,
        linkVisualShapeIndices=[-1] * n, linkPositions=list(rng.uniform(-0.5, 0.5, (n, 3))),
        linkOrientations=list(random_quat(rng, n)), linkInertialFramePositions=list(rng.uniform(-0.3, 0.3, (n, 3))),
        linkInertialFrameOrientations=list(random_quat(rng, n)),
        linkParentIndices=[int(rng.integers(0, i + 1)) for i in range(n)], linkJointTypes=[int(k) for k in kinds],
        linkJointAxis=list(rng.normal(size=(n, 3))), physicsClientId=cid)
    p.changeDynamics(body, -1, linearDamping=0, angularDamping=0, physicsClientId=cid)
    for j in range(n):
        p.changeDynamics(body, j, linearDamping=0, angularDamping=0, jointDamping=0,
                         maxJointVelocity=max_joint_velocity, physicsClientId=cid)
    return body


def set_random_velocities(cid, body, chain, rng, rate):
    """Random joint coordinates and velocities up to `rate` (rad/s or m/s), base velocity too."""
    for j, kind in enumerate(chain.joint_type):
        if kind == p.JOINT_SPHERICAL:
            w = rng.normal(size=3)
            p.resetJointStateMultiDof(body, j, random_quat(rng), w / np.linalg.norm(w) * rng.uniform(0, rate),
                                      physicsClientId=cid)
        elif kind != p.JOINT_FIXED:
            p.resetJointState(body, j, rng.normal(), rng.uniform(-rate, rate), physicsClientId=cid)
            p.setJointMotorControl2(body, j, p.VELOCITY_CONTROL, force=0, physicsClientId=cid)
    w = rng.normal(size=3)
    p.resetBaseVelocity(body, rng.normal(size=3) * 3, w / np.linalg.norm(w) * rng.uniform(0, rate),
                        physicsClientId=cid)


def link_states(cid, body, n):
    return [p.getLinkState(body, j, computeForwardKinematics=1, physicsClientId=cid) for j in range(n)]


def put_at(cid, body, chain, motion, tau):
    """Puts the body where the motion has it at tau (base and joints reset)."""
    base = motion.base_pose(tau)
    p.resetBasePositionAndOrientation(body, base[:3], base[3:], physicsClientId=cid)
    q = motion.joint_positions(tau)
    for j, kind in enumerate(chain.joint_type):
        if kind != p.JOINT_FIXED:
            k = chain.q_index[j]
            p.resetJointStateMultiDof(body, j, list(q[k:k + Q_SIZE[int(kind)]]), physicsClientId=cid)


def step_and_check(cid, body, chain, tolerance=1e-12):
    """Steps once and checks the rebuilt path at both ends and inside the step; returns
    the largest disagreement of each kind."""
    n = chain.n_links
    before = link_states(cid, body, n)
    base0 = p.getBasePositionAndOrientation(body, physicsClientId=cid)
    q0, _ = read_joint_state(cid, body, n)
    p.stepSimulation(physicsClientId=cid)
    after = link_states(cid, body, n)
    q1, qdot1 = read_joint_state(cid, body, n)
    motion = chain.motion(read_base_state(cid, body), q1, qdot1, DT)
    gaps = {"after": pose_gap(motion.link_poses(1.0), after), "before": pose_gap(motion.link_poses(0.0), before)}
    start = motion.base_pose(0.0)
    gaps["base"] = max(float(np.abs(start[:3] - base0[0]).max()), rotation_gap(start[3:], base0[1]))
    q_start = motion.joint_positions(0.0)
    gaps["q"] = 0.0
    for j, kind in enumerate(chain.joint_type):
        k = chain.q_index[j]
        if kind == p.JOINT_SPHERICAL:
            gaps["q"] = max(gaps["q"], rotation_gap(q_start[k:k + 4], q0[k:k + 4]))
        elif kind != p.JOINT_FIXED:
            gaps["q"] = max(gaps["q"], abs(q_start[k] - q0[k]))
    gaps["inside"] = 0.0
    for tau in (0.0, 0.3, 0.5, 0.9, 1.0):
        put_at(cid, body, chain, motion, tau)
        gaps["inside"] = max(gaps["inside"], pose_gap(motion.link_poses(tau), link_states(cid, body, n)))
    assert max(gaps.values()) <= tolerance, gaps
    return gaps


# --- Bullet's integration rules ----------------------------------------------------------------------------


@pytest.mark.parametrize("fixed_base", [False, True], ids=["free_base", "fixed_base"])
def test_random_multibodies_rebuilt_to_1e12(cid, fixed_base):
    """Random bodies of 1-8 links of every joint type, joint and base rates to 400 rad/s
    (above the pi/4-per-step clamp of spherical joints and the base): the path rebuilt
    from the state after the step agrees with pybullet at both ends and inside."""
    rng = np.random.default_rng(13 + fixed_base)
    worst = {}
    for trial in range(30):
        n = int(rng.integers(1, 9))
        body = random_multibody(cid, rng, n, fixed_base, max_joint_velocity=100.0 if trial % 5 == 0 else 1e4)
        chain = read_chain(cid, body)
        set_random_velocities(cid, body, chain, rng, rate=400.0 if trial % 2 else 20.0)
        for k, v in step_and_check(cid, body, chain).items():
            worst[k] = max(worst.get(k, 0.0), v)
    assert worst["after"] < 1e-13 and worst["before"] < 1e-13, worst


@pytest.mark.parametrize("name", URDFS)
def test_urdf_models_rebuilt_to_1e12(cid, name):
    """pybullet_data's robots (fixed, revolute, prismatic and spherical joints; inertial
    frames off the link frames), free and fixed base, several steps."""
    rng = np.random.default_rng(len(name))
    for fixed_base in (False, True):
        p.resetSimulation(physicsClientId=cid)
        p.setTimeStep(DT, physicsClientId=cid)
        body = p.loadURDF(name, [0.1, 0.2, 1.0], random_quat(rng), useFixedBase=fixed_base, physicsClientId=cid)
        chain = read_chain(cid, body)
        set_random_velocities(cid, body, chain, rng, rate=30.0)
        for _ in range(3):
            step_and_check(cid, body, chain)


def test_fixed_base_stays_put_unless_given_a_velocity(cid):
    """A fixed base with no velocity does not move; given one (resetBaseVelocity), Bullet
    moves it by the free-frame rule and getBaseVelocity reports it, so the rebuilt path
    needs no special case."""
    rng = np.random.default_rng(5)
    body = random_multibody(cid, rng, 3, fixed_base=True)
    chain = read_chain(cid, body)
    before = p.getBasePositionAndOrientation(body, physicsClientId=cid)
    for _ in range(5):
        p.stepSimulation(physicsClientId=cid)
    assert p.getBasePositionAndOrientation(body, physicsClientId=cid) == before
    assert np.all(read_base_state(cid, body)[7:] == 0.0)
    p.resetBaseVelocity(body, [1.0, 0.0, 0.0], [0.0, 0.0, 300.0], physicsClientId=cid)
    gaps = step_and_check(cid, body, chain)
    moved = p.getBasePositionAndOrientation(body, physicsClientId=cid)[0][0] - before[0][0]
    assert moved > 0.003 and gaps["base"] < 1e-14


def test_link_frame_is_com_frame_times_inverse_inertial(cid):
    """getLinkState's [4:6] (the URDF link frame) is the centre-of-mass frame [0:2] times
    the inverse of getDynamicsInfo's local inertial frame; pybullet rounds [4:6] to
    float32 (and [0:2] not)."""
    rng = np.random.default_rng(3)
    body = random_multibody(cid, rng, 6, fixed_base=False)
    chain = read_chain(cid, body)
    set_random_velocities(cid, body, chain, rng, rate=10.0)
    p.stepSimulation(physicsClientId=cid)
    q, qdot = read_joint_state(cid, body)
    poses = chain.link_poses(read_base_state(cid, body), q, qdot, DT, 1.0)
    inertial = chain.local_inertial_matrices()
    for j, state in enumerate(link_states(cid, body, chain.n_links)):
        X_WC = np.eye(4)
        X_WC[:3, :3] = Rotation.from_quat(poses[j, 3:]).as_matrix()
        X_WC[:3, 3] = poses[j, :3]
        X_WL = X_WC @ np.linalg.inv(inertial[j])
        assert all(x == float(np.float32(x)) for x in (*state[4], *state[5]))
        assert np.abs(X_WL[:3, 3] - state[4]).max() < 1e-6
        assert np.abs(X_WL[:3, :3] - Rotation.from_quat(state[5]).as_matrix()).max() < 1e-6


PLANAR_URDF = """<?xml version="1.0"?>
<robot name="planar">
  <link name="base"><inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>
  </inertial></link>
  <link name="slider"><inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>
  </inertial></link>
  <joint name="j" type="planar"><parent link="base"/><child link="slider"/><axis xyz="0 0 1"/></joint>
</robot>
"""


def test_planar_joint_is_refused(cid, tmp_path):
    """pybullet reports 2 of a planar joint's 3 coordinates and no axis: no path can be rebuilt."""
    path = tmp_path / "planar.urdf"
    path.write_text(PLANAR_URDF)
    p.resetSimulation(physicsClientId=cid)
    body = p.loadURDF(str(path), physicsClientId=cid)
    assert len(p.getJointStatesMultiDof(body, [0], physicsClientId=cid)[0][0]) == 2  # the fact behind it
    with pytest.raises(ValueError, match="link 0: planar joints are not supported"):
        read_chain(cid, body)


# --- random chains without pybullet ------------------------------------------------------------------------


def random_chain(rng, n, kinds=(0, 1, 2, 4), weights=(0.5, 0.15, 0.25, 0.1)):
    """A core Chain of n links (mostly a serial chain, some branches) and its joint types."""
    parent = np.array([i - 1 if rng.random() < 0.7 else int(rng.integers(-1, i)) for i in range(n)], np.int64)
    joint_type = rng.choice(kinds, n, p=np.divide(weights, sum(weights))).astype(np.int64)
    q_size = np.array([Q_SIZE[int(k)] for k in joint_type])
    qdot_size = np.array([QDOT_SIZE[int(k)] for k in joint_type])
    q_index = np.concatenate([[0], np.cumsum(q_size)[:-1]]).astype(np.int64)
    qdot_index = np.concatenate([[0], np.cumsum(qdot_size)[:-1]]).astype(np.int64)
    chain = _core.Chain(parent, joint_type, rng.normal(size=(n, 3)), rng.uniform(-0.3, 0.3, (n, 3)),
                        random_quat(rng, n), rng.uniform(-0.15, 0.15, (n, 3)), random_quat(rng, n), q_index,
                        qdot_index)
    return chain, joint_type, q_index, qdot_index


def random_motion(rng, chain, joint_type, q_index, qdot_index, rate):
    """The chain over a step of DT with joint and base rates up to `rate` (rad/s; prismatic m/s / 10)."""
    q, qdot = np.zeros(chain.n_q), np.zeros(chain.n_qdot)
    for j, kind in enumerate(joint_type):
        k, u = q_index[j], qdot_index[j]
        if kind in (0, 1):
            q[k] = rng.normal()
            qdot[u] = rng.uniform(-rate, rate) * (0.1 if kind == 1 else 1.0)
        elif kind == 2:
            w = rng.normal(size=3)
            q[k:k + 4] = random_quat(rng)
            qdot[u:u + 3] = w / np.linalg.norm(w) * rng.uniform(0, rate)
    w = rng.normal(size=3)
    state = np.concatenate([rng.uniform(-1, 1, 3), random_quat(rng), rng.normal(size=3) * 3,
                            w / np.linalg.norm(w) * rng.uniform(0, rate)])
    return _core.ChainMotion(chain, state, q, qdot, DT)


def fit_errors(motion, link, lo, hi, coeffs, points, samples=101):
    """Largest distance of the points (m, 3; in the link's frame) and of the 3x3 part
    (spectral norm) from their fitted places over [lo, hi]."""
    s = np.linspace(0.0, 1.0, samples)
    X = _core.LinkBoxPath(motion, link, np.eye(4), np.ones(3)).poses(lo + s * (hi - lo))  # the link's frame
    M = coeffs[0] + s[:, None, None] * coeffs[1] + (s * s)[:, None, None] * coeffs[2]
    true = np.einsum("nij,mj->nmi", X[:, :3, :3], points) + X[:, None, :3, 3]
    fitted = np.einsum("nij,mj->nmi", M[:, :3, :3], points) + M[:, None, :3, 3]
    worst_point = float(np.linalg.norm(true - fitted, axis=2).max())
    worst_rotation = float(np.linalg.norm(X[:, :3, :3] - M[:, :3, :3], 2, axis=(1, 2)).max())
    return worst_point, worst_rotation


def random_fit(rng, n_links, rate, pieces_from, r_max, n_points):
    """A random chain's motion at up to ``rate``, one of its links, a random piece of the
    step (1/pieces, pieces drawn from ``pieces_from``), n_points points at a random
    r <= r_max from the link's origin, and ``motion.fit`` there: (motion, link, lo, hi,
    points, (coeffs, bound, rotation, sweep))."""
    chain, *tables = random_chain(rng, n_links)
    motion = random_motion(rng, chain, *tables, rate=rate)
    link = int(rng.integers(0, chain.n_links))
    pieces = int(rng.choice(pieces_from))
    k = int(rng.integers(0, pieces))
    lo, hi = k / pieces, (k + 1) / pieces
    r = rng.uniform(0.0, r_max)
    fit = motion.fit(link, lo, hi, r)
    directions = rng.normal(size=(n_points, 3))
    return motion, link, lo, hi, directions / np.linalg.norm(directions, axis=1)[:, None] * r, fit


def test_fit_bound_holds_for_fast_chains():
    """Chains of 5-10 links, joint and base rates to 200 rad/s at 1/240 s (up to 0.83 rad
    a step each), whole steps and pieces: every point within r of the link's origin stays
    within the bound of its fitted place, the 3x3 part within `rotation`, and within
    `sweep` of its place at the piece's middle; and the bound is useful: its median
    ratio to the worst sampled error is below 2.5."""
    rng = np.random.default_rng(2024)
    ratios = []
    for _ in range(300):
        motion, link, lo, hi, points, (coeffs, bound, rotation, sweep) = random_fit(
            rng, int(rng.integers(5, 11)), 200.0, [1, 2, 4, 16], 0.5, 40)
        worst_point, worst_rotation = fit_errors(motion, link, lo, hi, coeffs, points)
        assert worst_point <= bound, (worst_point, bound)
        assert worst_rotation <= rotation * (1 + 1e-9) + 1e-15, (worst_rotation, rotation)
        ratios.append(bound / worst_point)
        still = np.repeat(coeffs[:1] + 0.5 * coeffs[1] + 0.25 * coeffs[2], 3, axis=0)  # the middle pose, held
        still[1:] = 0.0
        worst_sweep, _ = fit_errors(motion, link, lo, hi, still, points)
        assert worst_sweep <= sweep, (worst_sweep, sweep)
    assert np.median(ratios) < 2.5, np.percentile(ratios, [0, 50, 90, 100])  # measured 1.58


@pytest.mark.stress
def test_fit_bound_holds_stress():
    """The bound over 20000 cases: 1-12 links, rates to 1000 rad/s (4 rad a step), pieces of
    1/1 to 1/64 of the step, points to 2 m from the link's origin."""
    rng = np.random.default_rng(99)
    for _ in range(20000):
        motion, link, lo, hi, points, (coeffs, bound, rotation, _) = random_fit(
            rng, int(rng.integers(1, 13)), float(rng.choice([10.0, 200.0, 1000.0])), [1, 2, 8, 64], 2.0, 20)
        worst_point, worst_rotation = fit_errors(motion, link, lo, hi, coeffs, points, samples=65)
        assert worst_point <= bound, (worst_point, bound)
        assert worst_rotation <= rotation * (1 + 1e-9) + 1e-15, (worst_rotation, rotation)


def test_fit_bound_is_exact_for_one_turn():
    """One revolute link turning at w about an axis at distance rho from its centre of
    mass: the bound is w^3 rho sqrt(3)/216, the error of a circle's quadratic fit to
    within the third derivative's variation (ratio within 1 + (w/2)^2)."""
    parent, kind = np.array([-1]), np.array([0])
    chain = _core.Chain(parent, kind, np.array([[0.0, 0.0, 1.0]]), np.zeros((1, 3)), np.array([[0, 0, 0, 1.0]]),
                        np.array([[0.4, 0.0, 0.0]]), np.array([[0, 0, 0, 1.0]]), np.array([0]), np.array([0]))
    base = np.array([0, 0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 0, 0])
    for w in (0.1, 0.5, 1.0):
        motion = _core.ChainMotion(chain, base, np.array([0.3]), np.array([w / DT]), DT)
        coeffs, point0, *_ = motion.fit(0, 0.0, 1.0, 0.0)
        assert point0 == pytest.approx(w**3 * 0.4 * np.sqrt(3) / 216, rel=1e-9)
        worst, _ = fit_errors(motion, 0, 0.0, 1.0, coeffs, np.zeros((1, 3)), samples=2001)
        assert point0 / (1 + (w / 2) ** 2) <= worst <= point0


def test_pieces_keep_growth_within_tolerance():
    """A link box's pieces keep the fit's growth on every piece below fit_tolerance times
    its smallest half extent (unless 64 pieces are not enough), and half as many pieces
    would not."""
    rng = np.random.default_rng(11)
    for _ in range(60):
        chain, *tables = random_chain(rng, int(rng.integers(1, 11)))
        motion = random_motion(rng, chain, *tables, rate=200.0)
        X_CS, half = random_box(rng)
        box = _core.LinkBoxPath(motion, int(rng.integers(0, chain.n_links)), X_CS, half)
        n = box.pieces(FIT_TOLERANCE)
        assert n in (1, 2, 4, 8, 16, 32, 64)
        growth = [box.fit(k / n, (k + 1) / n)[1] for k in range(n)]
        if n < 64:
            assert max(growth) <= FIT_TOLERANCE * half.min() * (1 + 1e-9)
        if n > 1:
            coarse = max(box.fit(k / (n // 2), (k + 1) / (n // 2))[1] for k in range(n // 2))
            assert coarse > FIT_TOLERANCE * half.min()


# --- first touch on link paths -----------------------------------------------------------------------------


def random_box(rng):
    X = np.eye(4)
    X[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    X[:3, 3] = rng.uniform(-0.1, 0.1, 3) * rng.integers(0, 2)
    return X, rng.uniform(0.01, 0.1, 3)


def sampled_vertices(path, taus):
    """(len(taus), 8, 3) world corners of a path's box."""
    half = path.half_extents
    poses = path.poses(taus)
    return np.einsum("nij,vj->nvi", poses[:, :3, :3], SIGNS * half) + poses[:, None, :3, 3]


def first_sampled_touch(path_a, path_b, samples=2001):
    """The first of `samples` step fractions at which the exact boxes touch (SAT), NaN if none."""
    taus = np.linspace(0.0, 1.0, samples)
    gap = sat_gap(sampled_vertices(path_a, taus), sampled_vertices(path_b, taus))
    touching = np.nonzero(gap <= 0.0)[0]
    return taus[touching[0]] if len(touching) else np.nan


def partner_near(rng, path, kind):
    """A box near `path`'s box at a random time: static, on a free frame's path, or on a link."""
    tau = rng.uniform(0, 1)
    X = path.pose(tau)
    size = np.linalg.norm(path.half_extents)
    X_CS, half = random_box(rng)
    d = rng.normal(size=3)
    centre = X[:3, 3] + d / np.linalg.norm(d) * rng.uniform(0.3, 1.5) * (size + np.linalg.norm(half))
    if kind == "link":
        chain, *tables = random_chain(rng, int(rng.integers(1, 6)))
        motion = random_motion(rng, chain, *tables, rate=100.0)
        link = int(rng.integers(0, chain.n_links))
        X_WC = np.eye(4)
        pose = motion.link_pose(link, tau)
        X_WC[:3, :3], X_WC[:3, 3] = Rotation.from_quat(pose[3:]).as_matrix(), pose[:3]
        X_CS = np.linalg.inv(X_WC) @ np.block([[X_CS[:3, :3], centre[:, None]], [np.zeros((1, 3)), 1.0]])
        return _core.LinkBoxPath(motion, link, X_CS, half), motion
    state = np.concatenate([centre, random_quat(rng), np.zeros(6)])
    if kind == "free":
        w = rng.normal(size=3)
        state[7:] = np.concatenate([rng.normal(size=3) * 5, w / np.linalg.norm(w) * rng.uniform(0, 200)])
        # moved so that it is at `centre` at tau
        state[:3] += (1 - tau) * state[7:10] * DT
    row = _core.path_rows(state[None], DT, np.array([0]), np.array([0]), X_CS[None], half[None])[0]
    return _core.RowBoxPath(row), None


def check_first_touches(kind, seed, cases):
    """Boxes on fast chains (5-10 links, rates to 200 rad/s) against `kind` boxes near
    their path, both orders: asserts the reported first touch is never later than the
    first sampled touch (NaN, a miss, fails that too). Returns (pairs with a sampled
    touch, how much earlier than it each was reported, hits where sampling found none)."""
    rng = np.random.default_rng(seed)
    tol = _core.Tolerances()
    touches, early, extra = 0, [], 0
    for _ in range(cases):
        chain, *tables = random_chain(rng, int(rng.integers(5, 11)))
        motion = random_motion(rng, chain, *tables, rate=200.0)
        X_CS, half = random_box(rng)
        box = _core.LinkBoxPath(motion, int(rng.integers(0, chain.n_links)), X_CS, half)
        other, _keep = partner_near(rng, box, kind)
        truth = first_sampled_touch(box, other)
        for a, b in ((box, other), (other, box)):
            t, _ = _core.paths_first_touch(a, b, FIT_TOLERANCE, tol)
            if np.isnan(truth):
                extra += not np.isnan(t)
                continue
            touches += 1
            assert t <= truth, (kind, t, truth)
            early.append(truth - t)
    return touches, early, extra


@pytest.mark.parametrize("kind", ["static", "free", "link"])
def test_link_first_touch_never_late_never_missed(kind):
    """Boxes on fast chains (5-10 links, rates to 200 rad/s) against static, free and link
    boxes near their path: the reported first touch is never later than the first of 2001
    samples at which the exact boxes touch, and a sampled touch is never missed."""
    touches, _, _ = check_first_touches(kind, {"static": 1, "free": 2, "link": 3}[kind], 40)
    assert touches >= 20  # the cases do touch


@pytest.mark.stress
@pytest.mark.parametrize("kind", ["static", "free", "link"])
def test_link_first_touch_stress(kind):
    """As above, 1000 cases of each kind."""
    check_first_touches(kind, {"static": 11, "free": 12, "link": 13}[kind], 1000)


def test_link_first_touch_beyond_quadratic_fits():
    """Revolute joints at 2e4-1e5 rad/s (80-400 rad a step: Bullet does not clamp them),
    where no quadratic fit holds even over 1/64 of the step: the link box is held at each
    piece's middle pose, grown by how far it gets from there, and the first touch is still
    never late and never missed (20001 samples)."""
    rng = np.random.default_rng(4)
    tol = _core.Tolerances()
    touches = beyond = 0
    for _ in range(20):
        chain, *tables = random_chain(rng, int(rng.integers(1, 4)), kinds=(0,), weights=(1.0,))
        motion = random_motion(rng, chain, *tables, rate=float(rng.uniform(2e4, 1e5)))
        X_CS, half = random_box(rng)
        box = _core.LinkBoxPath(motion, int(rng.integers(0, chain.n_links)), X_CS, half)
        beyond += box.pieces(FIT_TOLERANCE) == 64
        other, _ = partner_near(rng, box, "static")
        truth = first_sampled_touch(box, other, samples=20001)
        t, _ = _core.paths_first_touch(box, other, FIT_TOLERANCE, tol)
        if not np.isnan(truth):
            touches += 1
            assert t <= truth, (t, truth)
    assert touches >= 6 and beyond >= 6, (touches, beyond)


def test_generic_first_touch_equals_row_first_touch():
    """On two path rows, paths_first_touch gives exactly the plugin's first_touches (the
    same fits, growth and pieces), so the plugin may use either."""
    rng = np.random.default_rng(8)
    tol = _core.Tolerances()
    for _ in range(200):
        rows = []
        for _ in range(2):
            w = rng.normal(size=3)
            state = np.concatenate([rng.uniform(-0.3, 0.3, 3), random_quat(rng), rng.normal(size=3) * 20,
                                    w / np.linalg.norm(w) * rng.uniform(0, 600)])
            X_CS, half = random_box(rng)
            rows.append(_core.path_rows(state[None], DT, np.array([0]), np.array([0]), X_CS[None], half[None])[0])
        rows = np.array(rows)
        expected, _ = _core.first_touches(rows, np.array([[0, 1]]), FIT_TOLERANCE, tol)
        t, _ = _core.paths_first_touch(_core.RowBoxPath(rows[0]), _core.RowBoxPath(rows[1]), FIT_TOLERANCE, tol)
        assert np.array_equal([t], expected, equal_nan=True)


# --- bad input ---------------------------------------------------------------------------------------------


def chain_arrays(n=2):
    return dict(parent=np.arange(-1, n - 1, dtype=np.int64), joint_type=np.zeros(n, np.int64),
                axis=np.tile([0.0, 0.0, 1.0], (n, 1)), parent_pos=np.zeros((n, 3)),
                parent_orn=np.tile([0, 0, 0, 1.0], (n, 1)), inertial_pos=np.zeros((n, 3)),
                inertial_orn=np.tile([0, 0, 0, 1.0], (n, 1)), q_index=np.arange(n, dtype=np.int64),
                qdot_index=np.arange(n, dtype=np.int64))


@pytest.mark.parametrize("change, error, message", [
    (dict(axis=np.zeros((2, 2))), ValueError, r"axis: expected shape \(2, 3\), got \(2, 2\)"),
    (dict(parent=np.array([-1, 1])), IndexError, "link 1: parent 1 is not the base"),
    (dict(joint_type=np.array([0, 3])), ValueError, "link 1: planar joints are not supported"),
    (dict(joint_type=np.array([7, 0])), ValueError, "link 0: joint type 7 is not"),
    (dict(axis=np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])), ValueError, "link 0: a revolute joint needs"),
    (dict(parent_orn=np.zeros((2, 4))), ValueError, "link 0: parent_orn and inertial_orn must be"),
    (dict(parent_pos=np.array([[0.0, np.nan, 0.0], [0.0, 0.0, 0.0]])), ValueError, "link 0: axis, parent_pos"),
    (dict(q_index=np.array([0, -1])), IndexError, "link 1: q_index -1"),
], ids=["shape", "parent", "planar", "type", "axis", "quaternion", "nan", "index"])
def test_bad_chain_gives_typed_error(change, error, message):
    with pytest.raises(error, match=message):
        _core.Chain(**{**chain_arrays(), **change})


def test_bad_motion_and_box_give_typed_errors():
    chain = _core.Chain(**chain_arrays())
    state = np.array([0, 0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 0, 0])
    with pytest.raises(ValueError, match=r"q: expected shape \(2,\), got \(3,\)"):
        _core.ChainMotion(chain, state, np.zeros(3), np.zeros(2), DT)
    with pytest.raises(ValueError, match="dt must be finite and > 0"):
        _core.ChainMotion(chain, state, np.zeros(2), np.zeros(2), 0.0)
    with pytest.raises(ValueError, match="link 1: q and qdot must be finite"):
        _core.ChainMotion(chain, state, np.array([0.0, np.inf]), np.zeros(2), DT)
    with pytest.raises(ValueError, match="the base state must be finite"):
        _core.ChainMotion(chain, np.full(13, np.nan), np.zeros(2), np.zeros(2), DT)
    motion = _core.ChainMotion(chain, state, np.zeros(2), np.zeros(2), DT)
    with pytest.raises(IndexError, match="link 2 is not one of the chain's 2 links"):
        motion.link_pose(2, 0.5)
    with pytest.raises(ValueError, match="expected 0 <= lo < hi <= 1"):
        motion.fit(0, 0.5, 0.5)
    with pytest.raises(ValueError, match="half extents must be > 0"):
        _core.LinkBoxPath(motion, 0, np.eye(4), np.array([0.1, 0.0, 0.1]))
    with pytest.raises(ValueError, match=r"X_CS: expected shape \(4, 4\)"):
        _core.LinkBoxPath(motion, 0, np.eye(3), np.ones(3))
    with pytest.raises(ValueError, match="row: column 0 is not finite"):
        _core.RowBoxPath(np.full(42, np.nan))
