"""BoxCCD as a drop-in for ordinary pybullet worlds: nothing to call but ``step()``.

Each behaviour is checked against pybullet itself, with the plain-pybullet contrast in
the same test: maximal-coordinate bodies, collision filters set with pybullet's own
calls, kinematic bodies the user moves, bodies removed and re-created under the same
id, masses changed, substeps, and every bad argument."""

from __future__ import annotations

import itertools
import math
import os
import subprocess
import sys
import warnings

import numpy as np
import pybullet as p
import pybullet_data
import pytest
from capture import CFile
from pybullet_utils import bullet_client

from bullet_boxccd import BoxCCD, InvalidInputError, _core
from bullet_boxccd.pybullet_ccd import BoxCCDWarning, layout
from bullet_boxccd.pybullet_ccd.shapes import probe_boxes
from bullet_boxccd.pybullet_ccd.world import restitution

DT = 1 / 240
CUBE_SMALL = os.path.join(pybullet_data.getDataPath(), "cube_small.urdf")


def reset(cid, gravity=0.0):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(DT, physicsClientId=cid)
    p.setGravity(0, 0, gravity, physicsClientId=cid)


def box(cid, half, pos, mass=1.0, maximal=False, orn=(0, 0, 0, 1), **kw):
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid, **kw)
    b = p.createMultiBody(mass, col, basePosition=pos, baseOrientation=orn, useMaximalCoordinates=maximal,
                          physicsClientId=cid)
    if mass > 0:
        p.changeDynamics(b, -1, linearDamping=0, angularDamping=0, maxJointVelocity=10000, physicsClientId=cid)
    return b


def x_of(cid, b):
    return p.getBasePositionAndOrientation(b, physicsClientId=cid)[0][0]


def throw(cid, cube, speed=100.0, spin=(3.0, -2.0, 5.0)):
    p.resetBaseVelocity(cube, [speed, 0, 0], list(spin), physicsClientId=cid)


def run(cid, use, steps, before_step=None):
    ccd = BoxCCD(cid) if use else None
    for k in range(steps):
        if before_step:
            before_step(k)
        ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
    return ccd


# ------------------------------------------------------ maximal coordinates
def maximal_cube_through_wall(cid, use, make, phase):
    reset(cid)
    box(cid, [0.0005, 1, 1], [0, 0, 0], mass=0.0)
    cube = make(cid, [-0.3 - phase * 100 * DT, 0.1, 0.05])
    throw(cid, cube)
    run(cid, use, 40)
    return x_of(cid, cube) > 0.0


MAXIMAL = {
    "createMultiBody": lambda cid, pos: box(cid, [0.05] * 3, pos, maximal=True),
    "loadURDF cube_small": lambda cid, pos: p.loadURDF(CUBE_SMALL, pos, useMaximalCoordinates=True,
                                                       physicsClientId=cid),
}


@pytest.mark.parametrize("name", sorted(MAXIMAL))
def test_maximal_bodies_are_found_and_swept_without_a_c_level_print(cid, name):
    phases = np.linspace(0, 1, 6, endpoint=False)
    plain = sum(maximal_cube_through_wall(cid, False, MAXIMAL[name], ph) for ph in phases)
    with CFile() as out, warnings.catch_warnings():
        warnings.simplefilter("error", BoxCCDWarning)
        through = sum(maximal_cube_through_wall(cid, True, MAXIMAL[name], ph) for ph in phases)
    assert through == 0 and plain >= 3, (through, plain)
    assert "failed" not in out.text, out.text


def test_a_maximal_bodys_restitution_is_its_own_where_pybullet_reports_none(cid, tmp_path):
    """pybullet's getDynamicsInfo leaves a maximal-coordinate body's restitution as its
    previous answer had it (here that of a body of restitution 1 read just before). The
    restitution BoxCCD's impacts read is the body's own: its URDF's until the user gives it
    another through changeDynamics; a multibody's as pybullet reports it; and none for a
    maximal body made before the import and not given one since (its impacts then get
    none), which the warning naming bodies made unseen says."""
    urdf = tmp_path / "bouncy.urdf"
    urdf.write_text('<robot name="bouncy"><link name="base"><contact><restitution value="0.6"/></contact>'
                    '<inertial><mass value="1"/><inertia ixx="0.0067" iyy="0.0067" izz="0.0067" ixy="0" ixz="0" '
                    'iyz="0"/></inertial><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>'
                    '</link></robot>')
    reset(cid)
    trap = box(cid, [0.05] * 3, [0, 5, 0], mass=0.0)
    p.changeDynamics(trap, -1, restitution=1.0, physicsClientId=cid)
    cube = p.loadURDF(str(urdf), [0, 0, 0], useMaximalCoordinates=True, physicsClientId=cid)
    twin = p.loadURDF(str(urdf), [0, 2, 0], physicsClientId=cid)
    unseen = p._bullet_boxccd_originals["createMultiBody"](
        1.0, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.1] * 3, physicsClientId=cid),
        basePosition=[0, -2, 0], useMaximalCoordinates=True, physicsClientId=cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", BoxCCDWarning)
        BoxCCD(cid).step()  # reads the world
    said = " ".join(str(w.message) for w in caught)
    assert f"the restitution of [{unseen}]" in said and f"restitution of [{cube}" not in said, said

    def read(b):
        p.getDynamicsInfo(trap, -1, physicsClientId=cid)
        info = p.getDynamicsInfo(b, -1, physicsClientId=cid)
        return info[5], restitution(cid, (b, -1), info)

    assert read(cube) == pytest.approx((1.0, 0.6))  # pybullet's answer is the trap's
    assert read(twin) == pytest.approx((0.6, 0.6))
    p.changeDynamics(cube, -1, restitution=0.2, physicsClientId=cid)
    assert read(cube) == pytest.approx((1.0, 0.2))
    assert read(unseen) == (1.0, None)


def test_a_maximal_body_is_read_in_a_client_of_its_own_after_the_user_disconnects_that_one(cid):
    """BoxCCD's private client, disconnected by a user closing client ids, is never used
    under its old id, which pybullet gives the user's next connection: that world is left
    as the user made it, and a maximal box made afterwards is still read and swept."""
    reset(cid)
    box(cid, [0.0005, 1, 1], [0, 0, 0], mass=0.0)
    box(cid, [0.05] * 3, [-3, 0, 0], maximal=True)
    ccd = BoxCCD(cid)
    ccd.step()  # reads the maximal box in a private client
    ours = [i for i in range(64) if i != cid and p.getConnectionInfo(i)["isConnected"]]
    for i in ours:
        p.disconnect(physicsClientId=i)
    theirs = p.connect(p.DIRECT)
    try:
        assert theirs in ours  # pybullet hands out the lowest free id
        first_shape = p.createCollisionShape(p.GEOM_SPHERE, radius=0.1, physicsClientId=theirs)
        cube = box(cid, [0.05] * 3, [-0.3, 0.1, 0.05], maximal=True)
        throw(cid, cube)
        for _ in range(40):
            ccd.step()
        assert x_of(cid, cube) < 0.0  # read and swept: stopped at the wall
        assert p.getNumBodies(physicsClientId=theirs) == 0
        assert p.createCollisionShape(p.GEOM_SPHERE, radius=0.1, physicsClientId=theirs) == first_shape + 1
    finally:
        p.disconnect(physicsClientId=theirs)


def test_worlds_of_maximal_bodies_made_again_and_again_add_no_client(cid):
    """An episode loop (the world reset and built again, a BoxCCD made for it) with a
    maximal-coordinate box: the private client that reads such boxes is one for the whole
    process, not one more per BoxCCD."""

    def connected():
        return sum(p.getConnectionInfo(physicsClientId=i)["isConnected"] for i in range(256))

    counts = []
    for _ in range(4):
        reset(cid)
        box(cid, [0.05] * 3, [0, 0, 0], maximal=True)
        BoxCCD(cid).step()
        counts.append(connected())
    assert counts == [counts[0]] * 4, counts


def test_a_client_given_a_closed_clients_id_has_its_own_maximal_boxes_read(cid):
    """Clients connected and closed in turn are given the same id, and their first shapes the
    same index: a maximal-coordinate box made in the second is read at its own size, not at
    the size of the first's box made from the shape of that index."""
    sizes = []
    for half in (0.05, 0.2):
        other = p.connect(p.DIRECT)
        try:
            col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[half] * 3, physicsClientId=other)
            p.createMultiBody(1.0, col, basePosition=[0, 0, 0], useMaximalCoordinates=True, physicsClientId=other)
            ccd = BoxCCD(other)
            ccd.step()
            sizes.append((other, col, ccd.world.tables.half.tolist()))
        finally:
            p.disconnect(physicsClientId=other)
    (a, col_a, half_a), (b, col_b, half_b) = sizes
    assert (a, col_a) == (b, col_b)  # the case: the same client id and shape index
    assert np.allclose(half_a, 0.05) and np.allclose(half_b, 0.2), sizes


def test_probes_read_a_maximal_body_made_unseen_exactly(cid):
    """A maximal body made through pybullet's original function (as before bullet_boxccd
    was imported) is read by closest-point probes: its corners match the same box made
    as a multibody, to 1e-9 of its size, for offsets of collision and inertial frames."""
    raw_create = p._bullet_boxccd_originals["createMultiBody"]
    rng = np.random.default_rng(11)
    reset(cid)
    probe = p.createCollisionShape(p.GEOM_SPHERE, radius=1e-3, physicsClientId=cid)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    for _ in range(8):
        half = rng.uniform(0.01, 0.5, 3)  # thicker than twice the 1 mm margin
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half.tolist(),
                                     collisionFramePosition=rng.uniform(-0.1, 0.1, 3).tolist(),
                                     collisionFrameOrientation=p.getQuaternionFromEuler(rng.uniform(-3, 3, 3)),
                                     physicsClientId=cid)
        kw = dict(baseMass=1.0, baseCollisionShapeIndex=col, basePosition=rng.uniform(-50, 50, 3).tolist(),
                  baseOrientation=p.getQuaternionFromEuler(rng.uniform(-3, 3, 3)),
                  baseInertialFramePosition=rng.uniform(-0.1, 0.1, 3).tolist(),
                  baseInertialFrameOrientation=p.getQuaternionFromEuler(rng.uniform(-3, 3, 3)), physicsClientId=cid)
        maximal = raw_create(useMaximalCoordinates=True, **kw)
        twin = p.createMultiBody(**kw)

        def corners(b, h, X_CS):  # poses through pybullet's own quaternion matrix: the independent reference
            pos, q = p.getBasePositionAndOrientation(b, physicsClientId=cid)
            X = np.eye(4)
            X[:3, :3] = np.array(p.getMatrixFromQuaternion(q)).reshape(3, 3)
            X[:3, 3] = pos
            return np.sort(((X @ X_CS) @ np.c_[signs * h, np.ones(8)].T).T[:, :3], axis=0)

        pos, q = p.getBasePositionAndOrientation(maximal, physicsClientId=cid)
        X_WC = np.eye(4)
        X_WC[:3, :3], X_WC[:3, 3] = np.array(p.getMatrixFromQuaternion(q)).reshape(3, 3), pos
        (h, X_CS), = probe_boxes(cid, maximal, -1, X_WC, probe)[0]
        d = p.getCollisionShapeData(twin, -1, physicsClientId=cid)[0]
        X_twin = np.eye(4)
        X_twin[:3, :3], X_twin[:3, 3] = np.array(p.getMatrixFromQuaternion(d[6])).reshape(3, 3), d[5]
        assert np.abs(corners(maximal, h, X_CS) - corners(twin, 0.5 * np.array(d[3]), X_twin)).max() <= 1e-9 * (
            np.linalg.norm(half))


def test_unreadable_maximal_box_is_named_in_one_warning(cid):
    """A maximal body made unseen whose box is thinner than twice its collision margin
    cannot be read by probes: one BoxCCDWarning names body and link; a sphere is left
    to pybullet without a warning."""
    raw_create = p._bullet_boxccd_originals["createMultiBody"]
    reset(cid)
    plate = raw_create(1.0, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.3, 0.2, 0.0004], physicsClientId=cid),
                       useMaximalCoordinates=True, physicsClientId=cid)
    raw_create(1.0, p.createCollisionShape(p.GEOM_SPHERE, radius=0.1, physicsClientId=cid),
               basePosition=[2, 0, 0], useMaximalCoordinates=True, physicsClientId=cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ccd = BoxCCD(cid)
        ccd.step()
        ccd.step()
    unreadable = [w for w in caught if issubclass(w.category, BoxCCDWarning) and "cannot be read" in str(w.message)]
    assert len(unreadable) == 1 and f"body {plate} link -1" in str(unreadable[0].message)
    assert "sphere" in ccd.summary()
    ccd.register_box(plate, -1, [0.3, 0.2, 0.0004])  # what the warning suggests
    assert ccd.stats.tracked_boxes == 1


# ------------------------------------------------------------------ filters
def filtered_wall(cid, use, how):
    reset(cid)
    wall = box(cid, [0.0005, 1, 1], [0, 0, 0], mass=0.0)
    cube = box(cid, [0.05] * 3, [-0.3, 0.1, 0.05])
    if how == "pair":
        p.setCollisionFilterPair(wall, cube, -1, -1, 0, physicsClientId=cid)
    elif how == "disjoint groups":
        p.setCollisionFilterGroupMask(wall, -1, 0b01, 0b01, physicsClientId=cid)
        p.setCollisionFilterGroupMask(cube, -1, 0b10, 0b10, physicsClientId=cid)
    elif how == "trigger":  # group 0 / mask 0: collides with nothing
        p.setCollisionFilterGroupMask(wall, -1, 0, 0, physicsClientId=cid)
    throw(cid, cube)
    traj = []
    run(cid, use, 30, before_step=lambda k: traj.append(p.getBasePositionAndOrientation(cube, physicsClientId=cid)))
    return np.array([list(a) + list(b) for a, b in traj])


@pytest.mark.parametrize("how", ["pair", "disjoint groups", "trigger"])
def test_filters_set_with_pybullet_behave_exactly_as_in_plain_pybullet(cid, how):
    plain = filtered_wall(cid, False, how)
    with_ccd = filtered_wall(cid, True, how)
    assert plain[-1, 0] > 1.0  # pybullet lets the cube through the filtered wall
    assert np.array_equal(plain, with_ccd)  # and so does the plugin, bit for bit
    assert filtered_wall(cid, True, None)[-1, 0] < 0.0  # the contrast: unfiltered, it is stopped


def test_filter_modes_and_rules_outliving_a_removed_body(cid):
    """collisionFilterMode 0 (AND) against pybullet's default 1 (OR), and a pair rule on
    a removed body's id, which pybullet applies to the body that reuses the id."""
    for mode in (0, 1):
        reset(cid)
        p.setPhysicsEngineParameter(collisionFilterMode=mode, physicsClientId=cid)
        wall = box(cid, [0.0005, 1, 1], [0, 0, 0], mass=0.0)
        cube = box(cid, [0.05] * 3, [-0.3, 0.1, 0.05])
        p.setCollisionFilterGroupMask(wall, -1, 1, 1, physicsClientId=cid)  # cube: group 1, mask -1
        p.setCollisionFilterGroupMask(cube, -1, 1, 2, physicsClientId=cid)  # wall group 1 & cube mask 2 = 0
        throw(cid, cube)
        run(cid, True, 30)
        assert (x_of(cid, cube) > 1.0) == (mode == 0), mode  # AND: one failing test filters; OR: both must
    reset(cid)
    wall = box(cid, [0.0005, 1, 1], [0, 0, 0], mass=0.0)
    old = box(cid, [0.05] * 3, [-3, 0, 0])
    p.setCollisionFilterPair(wall, old, -1, -1, 0, physicsClientId=cid)
    ccd = BoxCCD(cid)
    p.removeBody(old, physicsClientId=cid)
    cube = box(cid, [0.05] * 3, [-0.3, 0.1, 0.05])
    assert cube == old
    throw(cid, cube)
    for _ in range(30):
        ccd.step()
    assert x_of(cid, cube) > 1.0  # as pybullet itself does


def test_a_bullet_client_passes_its_client_id_through_the_wrapped_functions():
    """pybullet_utils' BulletClient adds physicsClientId only to builtins: the wrappers are
    builtins, so its calls reach (and are journaled for) its own client."""
    pb = bullet_client.BulletClient(connection_mode=p.DIRECT)
    pb.setTimeStep(DT)
    wall = pb.createMultiBody(0, pb.createCollisionShape(p.GEOM_BOX, halfExtents=[0.0005, 1, 1]))
    cube = pb.createMultiBody(1, pb.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3),
                              basePosition=[-0.3, 0.1, 0.05])
    pb.setCollisionFilterPair(wall, cube, -1, -1, 0)
    pb.resetBaseVelocity(cube, [100, 0, 0], [0, 0, 0])
    ccd = BoxCCD(pb._client)
    for _ in range(30):
        ccd.step()
    assert pb.getBasePositionAndOrientation(cube)[0][0] > 1.0


# ------------------------------------------------------------ kinematic bodies
def paddle_scene(cid, seed, mode, use):
    """A paddle (2 cm thick) driven at 20-30 m/s through a row of 6 cube_small on the
    ground: teleported each step, teleported with its velocity set, or dragged by a
    fixed constraint (pybullet's mocap pattern). Returns (cubes behind the paddle,
    deepest overlap of a cube and the paddle at the end, the paddle's lag behind its
    target at the end, deepest overlap of two cubes at the end)."""
    reset(cid, gravity=-9.81)
    rng = np.random.default_rng(seed)
    box(cid, [20, 2, 0.05], [0, 0, -0.05], mass=0.0)
    cubes = [p.loadURDF(CUBE_SMALL, [0.5 + 0.3 * k + rng.uniform(-0.05, 0.05), rng.uniform(-0.1, 0.1), 0.025],
                        physicsClientId=cid) for k in range(6)]
    for c in cubes:
        p.changeDynamics(c, -1, maxJointVelocity=1000, physicsClientId=cid)
    speed, x = rng.uniform(20, 30), -0.2
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.01, 0.3, 0.1], physicsClientId=cid)
    paddle = p.createMultiBody(1.0 if mode == "constraint" else 0.0, col, basePosition=[x, 0, 0.1],
                               physicsClientId=cid)
    if mode == "constraint":
        p.changeDynamics(paddle, -1, maxJointVelocity=1000, physicsClientId=cid)
        con = p.createConstraint(paddle, -1, -1, -1, p.JOINT_FIXED, [0, 0, 0], [0, 0, 0], [x, 0, 0.1],
                                 physicsClientId=cid)
    for _ in range(20):
        p.stepSimulation(physicsClientId=cid)

    def drive(k):
        target = x + (k + 1) * speed * DT
        if mode == "constraint":
            p.changeConstraint(con, [target, 0, 0.1], maxForce=5000, physicsClientId=cid)
        else:
            p.resetBasePositionAndOrientation(paddle, [target, 0, 0.1], [0, 0, 0, 1], physicsClientId=cid)
            if mode == "teleport with velocity":
                p.resetBaseVelocity(paddle, [speed, 0, 0], [0, 0, 0], physicsClientId=cid)

    n = int(2.6 / (speed * DT))
    run(cid, use, n, drive)
    px = x_of(cid, paddle)
    behind = sum(x_of(cid, c) < px for c in cubes)
    pts = [q for c in cubes for q in p.getClosestPoints(paddle, c, 0.0, physicsClientId=cid)]
    among = [q for a, b in itertools.combinations(cubes, 2) for q in p.getClosestPoints(a, b, 0.0, physicsClientId=cid)]
    return (behind, -min((q[8] for q in pts), default=0.0), x + n * speed * DT - px,
            -min((q[8] for q in among), default=0.0))


@pytest.mark.parametrize("mode", ["teleport", "teleport with velocity", "constraint"])
def test_kinematic_and_mocap_paddles_leave_no_cube_behind_and_never_stick(cid, mode):
    plain = sum(paddle_scene(cid, seed, mode, False)[0] for seed in range(4))
    assert plain >= 4, f"plain pybullet left only {plain} cubes behind: the test shows nothing"
    for seed in range(4):
        behind, deepest, lag, among = paddle_scene(cid, seed, mode, True)
        assert behind == 0, (mode, seed)
        assert deepest < 0.03, (mode, seed, deepest)  # no cube held inside the paddle
        assert lag < 1.2, (mode, seed, lag)  # the paddle is not held back (plain lags up to 0.5 m)
        assert among < 0.005, (mode, seed, among)  # a pushed cube pushes the next: none inside another


def _obstacle_moved(cid, use, moves, fine=1, substeps=0):
    """A cube_small resting on a box floor and a mass-0 box (4 x 60 x 40 cm) resting against
    it that the user moves to each of ``moves`` (x positions, one before each step of DT,
    None: not moved; with ``fine``, in as many even increments a step), with pybullet's
    ``substeps``. Returns the cube's pose and velocity after the moves and 4 steps more."""
    reset(cid, -10.0)
    box(cid, [5, 5, 0.05], [0, 0, -0.05], mass=0.0)
    obstacle = box(cid, [0.02, 0.3, 0.2], [-0.045, 0, 0.2], mass=0.0)
    cube = p.loadURDF(CUBE_SMALL, [0, 0, 0.025], physicsClientId=cid)
    for _ in range(20):
        p.stepSimulation(physicsClientId=cid)
    p.setPhysicsEngineParameter(fixedTimeStep=DT / fine, numSubSteps=substeps, physicsClientId=cid)
    ccd = BoxCCD(cid) if use else None
    x = -0.045
    for target in list(moves) + [None] * 4:
        for i in range(fine):
            if target is not None:
                p.resetBasePositionAndOrientation(obstacle, [x + (target - x) * (i + 1) / fine, 0, 0.2], [0, 0, 0, 1],
                                                  physicsClientId=cid)
            ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
        x = x if target is None else target
    return p.getBasePositionAndOrientation(cube, physicsClientId=cid) + p.getBaseVelocity(cube, physicsClientId=cid)


def test_a_fixed_body_teleported_faster_than_a_box_can_be_pushed_passes_it(cid):
    """A teleport is swept as the body's move over the user's step, and a box it meets is
    carried ahead of it at its speed, but not faster than pybullet's velocity clamp lets
    the box move: an obstacle an episode's reset puts 2 m away, across the cube it rested
    against (480 m/s), passes it, and the cube stays where plain pybullet leaves it, bit
    for bit (it was thrown at 480 m/s). Driven at 6 m/s from where it rests, also with 4
    substeps, the obstacle pushes the cube at its speed from the first step, as pybullet
    teleporting it in 128 increments a step does (plain pybullet leaves it behind); the
    cube ends within 1 cm of where that reference has it (with substeps, within the
    obstacle's move in a step: it rides the whole move in the step's first substep and
    runs on at its speed in the others); driven at the cube's clamp itself, it pushes the
    cube at it."""
    for moves in ([None, 2.0], [None, 2.0, None, -2.0, None, 2.0]):
        assert _obstacle_moved(cid, True, moves) == _obstacle_moved(cid, False, moves)
    drive = [-0.045 + 6.0 * DT * (k + 1) for k in range(12)]
    for substeps, near in ((0, 0.01), (4, 6.0 * DT)):
        mine, ref = (_obstacle_moved(cid, use, drive, fine, substeps) for use, fine in ((True, 1), (False, 128)))
        assert abs(mine[0][0] - ref[0][0]) < near and abs(mine[2][0] - ref[2][0]) < 0.1, (substeps, mine, ref)
    plain = _obstacle_moved(cid, False, drive)
    assert plain[0][0] < drive[-1], "plain pybullet pushed the cube: the test shows nothing"
    # At the cube's clamp itself (100 m/s, to rounding) the cube is still pushed at it.
    drive = [-0.045 + 100.0 * DT * (k + 1) for k in range(6)]
    mine, ref = (_obstacle_moved(cid, use, drive, fine) for use, fine in ((True, 1), (False, 128)))
    assert mine[0][0] > drive[-1] and abs(mine[2][0] - ref[2][0]) < 1.0, (mine, ref)


def test_a_step_after_restorestate_or_a_reset_body_is_pybullets(cid):
    """A plank thrown end first at a box floor turns on its landing, and BoxCCD takes the
    steps after it in pieces while it does; after restoreState to a calm world, or the
    plank put back at rest by the user, the next steps are plain pybullet's, bit for bit."""
    raw = p._bullet_boxccd_originals["stepSimulation"]

    def calm_world():
        reset(cid, -10.0)
        box(cid, [5, 5, 0.01], [0, 0, -0.01], mass=0.0)
        plank = p.createMultiBody(1, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.4, 0.025, 0.025],
                                                            physicsClientId=cid),
                                  basePosition=[0, 0, 0.025], physicsClientId=cid)
        for _ in range(30):
            raw(physicsClientId=cid)
        return plank, p.saveState(physicsClientId=cid)

    def state(plank):
        return p.getBasePositionAndOrientation(plank, physicsClientId=cid) + \
            p.getBaseVelocity(plank, physicsClientId=cid)

    def land(ccd, plank):
        p.resetBasePositionAndOrientation(plank, [0, 0, 1.0], p.getQuaternionFromEuler([0, 0.9, 0]),
                                          physicsClientId=cid)
        p.resetBaseVelocity(plank, [0, 0, -14], [0, 20, 0], physicsClientId=cid)
        while not ccd.stats.rewinds:
            ccd.step()

    for back in ("restoreState", "reset"):
        plank, calm = calm_world()
        ccd = BoxCCD(cid)
        land(ccd, plank)
        if back == "restoreState":
            p.restoreState(calm, physicsClientId=cid)
        else:
            p.resetBasePositionAndOrientation(plank, [0, 0, 0.0249875], [0, 0, 0, 1], physicsClientId=cid)
            p.resetBaseVelocity(plank, [0, 0, 0], [0, 0, 0], physicsClientId=cid)
        start, pieces = p.saveState(physicsClientId=cid), ccd.stats.pieces
        mine, plain = [], []
        for _ in range(3):
            ccd.step()
            mine.append(state(plank))
        p.restoreState(start, physicsClientId=cid)
        for _ in range(3):
            raw(physicsClientId=cid)
            plain.append(state(plank))
        assert ccd.stats.pieces == pieces and mine == plain, back


def _teleported_paddle(cid, use, fine=1, velocity=False, maximal=False):
    """A mass-0 paddle (0.1 x 0.6 x 0.6 m) teleported along +x at 20 m/s for 0.04 s into two
    free 0.1 m cubes 0.2 m apart (restitution 0.5 on all, no gravity): at every step of
    DT, or of DT / fine in as many increments; with ``velocity``, given its velocity too;
    with ``maximal``, every body in maximal coordinates. Returns the cubes' x velocities
    after 0.06 s."""
    reset(cid)
    paddle = box(cid, [0.05, 0.3, 0.3], [-0.3, 0, 0], mass=0.0, maximal=maximal)
    cubes = [box(cid, [0.05] * 3, [0.2 + 0.2 * i, 0.03 * i, 0], maximal=maximal) for i in range(2)]
    for body in [paddle] + cubes:
        p.changeDynamics(body, -1, restitution=0.5, physicsClientId=cid)
    ccd = BoxCCD(cid) if use else None
    h = DT / fine
    for k in range(round(0.06 / h)):
        t = (k + 1) * h
        p.resetBasePositionAndOrientation(paddle, [-0.3 + 20.0 * min(t, 0.04), 0, 0], [0, 0, 0, 1],
                                          physicsClientId=cid)
        if velocity:
            p.resetBaseVelocity(paddle, [20.0 if t <= 0.04 + 1e-12 else 0.0, 0, 0], [0, 0, 0], physicsClientId=cid)
        if fine > 1:
            p.setTimeStep(h, physicsClientId=cid)
        ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
    return [p.getBaseVelocity(c, physicsClientId=cid)[0][0] for c in cubes]


@pytest.mark.parametrize("velocity", [False, True])
def test_a_teleported_paddle_pushes_as_pybullet_teleporting_it_in_fine_steps(cid, velocity):
    """pybullet gives a body the user only teleports no velocity to rebound from: teleported
    in 128 increments a step, the paddle of ``_teleported_paddle`` pushes the first cube out
    of its overlap at its own 20 m/s, and that cube strikes the second with their
    restitution. BoxCCD carries the first cube at the paddle's speed and the second leaves
    the first as it strikes it, each within 3 % of 20 m/s of that; given its velocity too,
    the paddle strikes with the restitution (plain pybullet at DT: both cubes pass through
    or are left behind)."""
    got = _teleported_paddle(cid, True, velocity=velocity)
    ref = _teleported_paddle(cid, False, 128, velocity)
    assert np.allclose(got, ref, atol=0.03 * 20.0), (got, ref)
    assert not np.allclose(_teleported_paddle(cid, False, velocity=velocity), ref, atol=0.1 * 20.0)


def test_a_fixed_maximal_paddle_given_a_velocity_pushes_as_one_only_teleported(cid):
    """pybullet neither moves a fixed maximal-coordinate body by the velocity the user gives
    it nor lets its contacts see it: teleported in 128 increments a step, the paddle of
    ``_teleported_paddle`` in maximal coordinates pushes the cubes alike with its velocity
    given and without. So does BoxCCD (it struck the first cube at the velocity's
    restitution: 3.8 and 31.8 m/s), within the 4 % of the second cube's impact speed that
    an impact of maximal-coordinate bodies is resolved below the converged engine's mean."""
    ref = _teleported_paddle(cid, False, 128, True, True)
    assert np.allclose(ref, _teleported_paddle(cid, False, 128, False, True), atol=1e-6)
    got = _teleported_paddle(cid, True, velocity=True, maximal=True)
    assert np.allclose(got, _teleported_paddle(cid, True, velocity=False, maximal=True), atol=1e-9)
    assert np.allclose(got, ref, atol=0.04 * 20.0), (got, ref)


def test_fixed_maximal_bodies_given_a_velocity_stay_where_pybullet_keeps_them(cid):
    """pybullet does not move a fixed maximal-coordinate body by a velocity the user gives
    it, nor one made fixed and given a mass since (pybullet integrates a rigid body only if
    it was made with a mass): a sphere (no box) and boxes so given stay put in plain
    pybullet, and under BoxCCD while cubes striking a wall take the world back, each pose
    bit for bit plain pybullet's."""

    def run(use):
        reset(cid)
        box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
        sphere = p.createMultiBody(0, p.createCollisionShape(p.GEOM_SPHERE, radius=0.1, physicsClientId=cid),
                                   basePosition=[0, 5, 0], useMaximalCoordinates=True, physicsClientId=cid)
        block = box(cid, [0.1] * 3, [0, -5, 0], mass=0.0, maximal=True)
        massed = box(cid, [0.1] * 3, [0, -8, 0], mass=0.0, maximal=True)
        p.changeDynamics(massed, -1, mass=1.0, physicsClientId=cid)
        for b in (sphere, block, massed):
            p.resetBaseVelocity(b, [0, 0, 5.0], [0, 0, 0], physicsClientId=cid)
        for i in range(3):
            cube = box(cid, [0.05] * 3, [-0.3 - 0.7 * i, 0.3 * i - 0.3, 0.05])
            p.resetBaseVelocity(cube, [60, 0, 0], [0, 0, 0], physicsClientId=cid)
        ccd = BoxCCD(cid) if use else None
        for _ in range(24):
            ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
        return [p.getBasePositionAndOrientation(b, physicsClientId=cid) for b in (sphere, block, massed)], ccd

    plain, _ = run(False)
    mine, ccd = run(True)
    assert ccd.stats.rewinds > 0
    assert mine == plain


def _elevator(cid, use, speed, fine=1, velocity=False, dt=DT):
    """A cube (0.1 m, 1 kg) resting on a mass-0 plate 10 cm thick that the user teleports up
    at ``speed`` m/s to its pose at the end of every step of dt (or of dt / fine), with
    ``velocity`` also given that velocity, with gravity, for 0.5 s. Returns (the cube's
    height above the plate and its vertical velocity at the end, the deepest overlap of
    plate and cube where a step of dt ends)."""
    reset(cid, gravity=-9.81)
    plate = box(cid, [0.4, 0.4, 0.05], [0, 0, -0.05], mass=0.0)
    cube = box(cid, [0.05] * 3, [0.2, 0, 0.05])
    ccd = BoxCCD(cid) if use else None
    h, deepest = dt / fine, 0.0
    p.setTimeStep(h, physicsClientId=cid)
    for k in range(round(0.5 / dt) * fine):
        p.resetBasePositionAndOrientation(plate, [0, 0, -0.05 + speed * (k + 1) * h], [0, 0, 0, 1],
                                          physicsClientId=cid)
        if velocity:
            p.resetBaseVelocity(plate, [0, 0, speed], [0, 0, 0], physicsClientId=cid)
        ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
        if (k + 1) % fine == 0:
            deepest = max([deepest] + [-c[8] for c in p.getClosestPoints(plate, cube, 0.0, physicsClientId=cid)])
    gap = p.getBasePositionAndOrientation(cube, physicsClientId=cid)[0][2] - 0.05 \
        - (p.getBasePositionAndOrientation(plate, physicsClientId=cid)[0][2] + 0.05)
    return gap, p.getBaseVelocity(cube, physicsClientId=cid)[0][2], deepest


def test_a_box_on_a_teleported_elevator_rides_it_as_the_converged_engine(cid):
    """pybullet gives a teleport no velocity: its solver pushes the cube out of the overlap
    each teleport makes by contact ERP x that overlap a step only, so on a plate teleported
    up by 8.3 mm a step (2 m/s at 240 Hz) the cube sinks until it is 8.3 mm / ERP deep, and
    falls through the plate. A jump that would leave a box deeper than a free box may move
    unswept in a step is carried: the cube rides the plate as pybullet teleporting it 64
    times a step has it (its height above the plate within 1 cm, its speed within 0.05
    m/s), no step ending deeper than 1 cm. At 0.05 m/s (2.6 mm deep in plain pybullet) the
    world is plain pybullet's, bit for bit."""
    z, vz, deepest = _elevator(cid, True, 2.0)
    z_ref, vz_ref, deepest_ref = _elevator(cid, False, 2.0, 64)
    assert deepest_ref < 0.002  # 8.3 mm / 64 / ERP
    assert abs(z - z_ref) < 0.01 and abs(vz - vz_ref) < 0.05, (z, vz, z_ref, vz_ref)
    assert deepest < 0.01, deepest
    assert _elevator(cid, False, 2.0)[0] < -0.1  # plain pybullet: through the plate
    assert _elevator(cid, True, 0.05) == _elevator(cid, False, 0.05)


def test_a_plate_teleported_ahead_and_given_its_velocity_lifts_a_box_at_its_speed(cid):
    """Teleported to its pose at the end of each step and given its velocity too, the plate
    of ``_elevator`` moves twice in the first step (the teleport, then its velocity): the
    cube it strikes is struck at the teleport's speed, not at that of both moves (struck
    so, it left at 7.3 m/s and flew 30 cm off the plate). At 4 m/s and 60 Hz it rides the
    plate as pybullet teleporting it 64 times a step has it (its speed within 0.05 m/s, its
    height above the plate within 1 cm)."""
    z, vz, _ = _elevator(cid, True, 4.0, velocity=True, dt=1 / 60)
    z_ref, vz_ref, _ = _elevator(cid, False, 4.0, 64, True, 1 / 60)
    assert abs(vz - vz_ref) < 0.05 and abs(z - z_ref) < 0.01, (z, vz, z_ref, vz_ref)


def _turning_paddle(cid, use, fine=1, phase=0.0):
    """A mass-0 bar (0.4 x 0.02 x 0.1 m) turned about its end at the origin at 55 rad/s
    (22 m/s at its tip) by a teleport to its pose and its velocity and spin at every step
    of 1/60 s (or of 1/60 / fine, after a first step of ``phase`` of one), sweeping a free
    5 cm, 50 g cube (restitution 0, friction 0.5, no gravity) out along it and off its
    end. Returns (the cube's velocity in the plane after 8 steps, the deepest overlap of
    bar and cube where a step of 1/60 s ends)."""
    reset(cid)
    dt, omega = 1 / 60, 55.0
    angle = lambda t: -0.6 + omega * t  # noqa: E731
    bar = box(cid, [0.2, 0.01, 0.05], [0.2 * np.cos(angle(0)), 0.2 * np.sin(angle(0)), 0], mass=0.0,
              orn=p.getQuaternionFromEuler([0, 0, angle(0)]))
    cube = box(cid, [0.025] * 3, [0.3, 0.15, 0], mass=0.05)
    for body in (bar, cube):
        p.changeDynamics(body, -1, restitution=0.0, lateralFriction=0.5, physicsClientId=cid)
    ccd = BoxCCD(cid) if use else None
    h, t, deepest = dt / fine, 0.0, 0.0
    for k in range(8 * fine + (1 if phase else 0)):
        step = phase * h if phase and k == 0 else h
        t += step
        a = angle(t)
        p.resetBasePositionAndOrientation(bar, [0.2 * np.cos(a), 0.2 * np.sin(a), 0],
                                          p.getQuaternionFromEuler([0, 0, a]), physicsClientId=cid)
        p.resetBaseVelocity(bar, [-0.2 * omega * np.sin(a), 0.2 * omega * np.cos(a), 0], [0, 0, omega],
                            physicsClientId=cid)
        p.setTimeStep(step, physicsClientId=cid)
        ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
        if abs(t / dt - round(t / dt)) < 1e-9:
            deepest = max([deepest] + [-c[8] for c in p.getClosestPoints(bar, cube, 0.0, physicsClientId=cid)])
    return np.array(p.getBaseVelocity(cube, physicsClientId=cid)[0][:2]), deepest


def test_a_cube_swept_by_a_turning_paddle_leaves_it_as_the_converged_engines(cid):
    """The bar of ``_turning_paddle``, given its velocity and spin, strikes the cube and
    sweeps it out along its face and off its end. No step ends deeper than 1 cm, and the
    cube leaves within 0.15 of the tip's speed of the converged engine's velocity (pybullet
    at a 256 times finer step, 4 offsets of its grid)."""
    v, deepest = _turning_paddle(cid, True)
    refs = [_turning_paddle(cid, False, 256, k / 4) for k in range(4)]
    v_ref = np.mean([r[0] for r in refs], axis=0)
    assert max(r[1] for r in refs) < 0.005
    assert deepest < 0.01, deepest
    assert np.linalg.norm(v - v_ref) < 0.15 * 22.0, (v, v_ref)


def test_partial_steps_taken_again_shorter_leave_the_rest_of_the_world_as_pybullet_moves_it(cid):
    """A mass-0 box given a velocity before every step (pybullet moves it by v dt) and a free
    box flying far away while a spinning cube strikes a wall corner first: the partial
    steps after the strike, taken again shorter when it spins the cube past ``max_turn``
    until they are used up, end every step at its end, with both boxes exactly where plain
    pybullet puts them."""
    reset(cid)
    box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
    carrier = box(cid, [0.1, 0.1, 0.1], [-1.0, 3.0, 0], mass=0.0)
    flyer = box(cid, [0.1, 0.1, 0.1], [-1.0, -3.0, 0])
    p.resetBaseVelocity(flyer, [3.0, 0, 0], [0, 0, 0], physicsClientId=cid)
    cube = box(cid, [0.05] * 3, [-0.5, 0.0, 0.0], orn=p.getQuaternionFromEuler([0.3, 0.5, 0.2]))
    throw(cid, cube, speed=200.0, spin=(20.0, -30.0, 10.0))
    ccd = BoxCCD(cid, max_turn=0.05)
    struck = 0
    for _ in range(12):
        p.resetBaseVelocity(carrier, [10.0, 0, 0], [0, 0, 0], physicsClientId=cid)
        struck += len(ccd.step())
    assert struck and ccd.stats.partial_steps > ccd.stats.rewinds  # struck, in pieces
    assert x_of(cid, carrier) == pytest.approx(-1.0 + 12 * 10.0 * DT, abs=1e-9)
    assert x_of(cid, flyer) == pytest.approx(-1.0 + 12 * 3.0 * DT, abs=1e-9)


def _joint_set_bar(cid, tip_speed, cubes_at=(0.2, 0.35)):
    """A mass-0 fixed base with one revolute link, a 0.5 m bar, turned about z by
    resetJointState before every step (no joint velocity) so that its tip moves at
    ``tip_speed`` over free 6 cm cubes standing on a box floor at x = ``cubes_at`` (y = 0).
    Returns the BoxCCDWarnings of 0.12 s of BoxCCD steps."""
    reset(cid, -9.81)
    box(cid, [5, 5, 0.05], [0, 0, -0.05], mass=0.0)
    for x in cubes_at:
        box(cid, [0.03] * 3, [x, 0, 0.03], mass=0.2)
    bar = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.25, 0.005, 0.05], collisionFramePosition=[0.25, 0, 0],
                                 physicsClientId=cid)
    arm = p.createMultiBody(0, -1, basePosition=[0, -0.3, 0.08], linkMasses=[0], linkCollisionShapeIndices=[bar],
                            linkVisualShapeIndices=[-1], linkPositions=[[0, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
                            linkInertialFramePositions=[[0, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                            linkParentIndices=[0], linkJointTypes=[p.JOINT_REVOLUTE], linkJointAxis=[[0, 0, 1]],
                            physicsClientId=cid)
    ccd = BoxCCD(cid)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        for k in range(int(round(0.12 / DT))):
            p.resetJointState(arm, 0, min(tip_speed / 0.5 * k * DT, math.pi / 2), physicsClientId=cid)
            ccd.step()
    return [str(w.message) for w in said if issubclass(w.category, BoxCCDWarning)]


@pytest.mark.parametrize("tip_speed", [5.0, 30.0])
def test_a_link_set_through_a_box_by_resetjointstate_is_named_once(cid, tip_speed):
    """BoxCCD sweeps what a link does within a step, not a joint the user sets between
    steps: a bar turned by resetJointState through two cubes passes them (pybullet at a
    64 times finer step, the joint set at each, throws them at several m/s), and BoxCCD
    says so once, naming the body, the link and a box it went through; turned through the
    air, the cubes out of its way, it is not named."""
    said = _joint_set_bar(cid, tip_speed)
    assert len(said) == 1 and said[0].startswith("body 3: a joint set by resetJointState between steps moved its "
                                                 "link 0"), said
    assert " through a box of body 1" in said[0] or " through a box of body 2" in said[0], said
    assert _joint_set_bar(cid, tip_speed, cubes_at=(2.0, 3.0)) == []


def _held_box(cid, use, start):
    """A cube thrown at 60 m/s at a 1 cm wall from ``start`` (it strikes late in the
    thirteenth step), while a second cube 5 m away, held to the world by a JOINT_FIXED
    constraint, has its pivot moved 0.1 m in that step. Returns the held cube's fastest
    speed over 30 steps of 1/240 s, and the BoxCCD (or None)."""
    reset(cid)
    box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
    cube = box(cid, [0.05] * 3, [start, 0, 0])
    held = box(cid, [0.05] * 3, [0, 5, 0])
    joint = p.createConstraint(held, -1, -1, -1, p.JOINT_FIXED, [0, 0, 0], [0, 0, 0], [0, 5, 0], physicsClientId=cid)

    def drive(k):
        if k == 12:
            throw(cid, cube, 60.0, (0, 0, 0))
        if k == 13:
            p.changeConstraint(joint, jointChildPivot=[0.1, 5, 0], physicsClientId=cid)

    fastest = 0.0
    ccd = BoxCCD(cid) if use else None
    for k in range(30):
        drive(k)
        ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
        fastest = max(fastest, float(np.linalg.norm(p.getBaseVelocity(held, physicsClientId=cid)[0])))
    return fastest, ccd


@pytest.mark.parametrize("start", [-0.5, -0.54, -0.548])
def test_a_constraint_far_from_an_impact_pulls_its_box_no_faster_in_partial_steps(cid, start):
    """pybullet corrects a constraint's error at erp x error / step: in the partial step of
    an impact elsewhere, a short piece at the step's end, a held box the user's pivot move
    left 0.1 m off was pulled at up to pybullet's velocity clamp. With the partial step's
    ERPs scaled to its length it moves no faster than plain pybullet moves it (4.8 m/s; the
    converged engine keeps it on its pivot)."""
    plain, _ = _held_box(cid, False, start)
    fastest, ccd = _held_box(cid, True, start)
    assert ccd.stats.partial_steps >= 1
    assert fastest <= plain + 1e-9, (fastest, plain)


def _loose_bodies(cid):
    """A sphere (spinning), a maximal-coordinate capsule (spinning about its axis), a
    free-floating two-link capsule body (its joint still), a two-link capsule arm on a
    fixed base swinging under gravity, a spinning sphere with pybullet's default damping
    and one with damping set, and a mass-0 sphere the user moves by a velocity, all far
    from any box: bodies with no box."""
    sphere = p.createCollisionShape(p.GEOM_SPHERE, radius=0.1, physicsClientId=cid)
    capsule = p.createCollisionShape(p.GEOM_CAPSULE, radius=0.05, height=0.3, physicsClientId=cid)
    ball = p.createMultiBody(1.0, sphere, basePosition=[5, 5, 5], physicsClientId=cid)
    pill = p.createMultiBody(1.0, capsule, basePosition=[5, -5, 5], useMaximalCoordinates=True, physicsClientId=cid)

    def two_link(mass, pos):
        b = p.createMultiBody(mass, capsule, basePosition=pos, linkMasses=[1.0], linkCollisionShapeIndices=[capsule],
                              linkVisualShapeIndices=[-1], linkPositions=[[0, 0, 0.4]], linkOrientations=[[0, 0, 0, 1]],
                              linkInertialFramePositions=[[0, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                              linkParentIndices=[0], linkJointTypes=[p.JOINT_REVOLUTE], linkJointAxis=[[1, 0, 0]],
                              physicsClientId=cid)
        p.setJointMotorControl2(b, 0, p.VELOCITY_CONTROL, force=0, physicsClientId=cid)
        return b

    pair, arm = two_link(1.0, [-5, 5, 5]), two_link(0.0, [-5, 0, 5])
    platform = p.createMultiBody(0.0, sphere, basePosition=[-5, -5, 5], physicsClientId=cid)
    for b, v, w in ((ball, [1, 0, 2], [3, 1, 0]), (pill, [0, 1, 2], [0, 0, 2]), (pair, [1, 1, 0], [0, 0, 0])):
        for link in range(-1, p.getNumJoints(b, physicsClientId=cid)):
            p.changeDynamics(b, link, linearDamping=0, angularDamping=0, physicsClientId=cid)
        p.resetBaseVelocity(b, v, w, physicsClientId=cid)
    p.resetJointState(arm, 0, 0.3, 1.0, physicsClientId=cid)
    damped = [p.createMultiBody(1.0, sphere, basePosition=[x, 0, 8], physicsClientId=cid) for x in (4, 6)]
    p.changeDynamics(damped[1], -1, linearDamping=0.5, angularDamping=0.3, physicsClientId=cid)
    for b in damped:
        p.resetBaseVelocity(b, [3, -1, 2], [4, 1, -2], physicsClientId=cid)
    return ball, pill, pair, arm, *damped, platform


def _state_of(cid, b):
    pos, orn = p.getBasePositionAndOrientation(b, physicsClientId=cid)
    v, w = p.getBaseVelocity(b, physicsClientId=cid)
    n = p.getNumJoints(b, physicsClientId=cid)
    joints = [x for s in p.getJointStates(b, range(n), physicsClientId=cid) for x in s[:2]] if n else []
    return np.array([*pos, *orn, *v, *w, *joints])


def test_bodies_with_no_box_go_back_with_the_world(cid):
    """When a contact takes the world back to its time, the bodies BoxCCD sweeps no box of
    go back too (the rest of the step simulated again would otherwise move them twice over
    the time gone back): a sphere, a maximal-coordinate capsule, a two-link capsule body
    and two damped spheres in free flight, and a fixed sphere given a velocity and a spin before every step
    (Bullet moves it by them, turning its velocity as it goes; so for a fixed box beside
    it), end each step where plain pybullet has them, and a fixed-base arm's base stays put.
    The cube strikes face on, so the rest of each step goes in one piece: pybullet's
    integration over it then ends a free flight exactly where the whole step does, gravity
    too."""
    ends, arm_base = {}, {}
    for use in (False, True):
        reset(cid, gravity=-9.81)
        box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
        cube = box(cid, [0.05] * 3, [-0.5, 0.0, 0.0])
        p.changeDynamics(cube, -1, restitution=0.8, physicsClientId=cid)
        throw(cid, cube, speed=200.0, spin=(0.0, 0.0, 0.0))
        carrier = box(cid, [0.1, 0.1, 0.1], [5.0, 0.0, 5.0], mass=0.0)
        loose = _loose_bodies(cid)
        moved = (loose[-1], carrier)

        def drive(k, moved=moved):
            for b in moved:
                p.resetBaseVelocity(b, [2, 1, 0], [0.5, 0, 3], physicsClientId=cid)

        ccd = run(cid, use, 12, drive)
        ends[use] = [_state_of(cid, b) for k, b in enumerate(loose) if k != 3] + [_state_of(cid, carrier)]
        arm_base[use] = _state_of(cid, loose[3])[:7]
    assert ccd.stats.rewinds and ccd.stats.partial_steps
    for plain, swept in zip(ends[False], ends[True]):
        np.testing.assert_allclose(swept, plain, rtol=0, atol=1e-9)
    # The swinging arm's joint accelerates over the step (its joint velocity goes back as it
    # is after the step); its fixed base stays exactly where it is.
    np.testing.assert_array_equal(arm_base[True], arm_base[False])


def test_a_body_that_cannot_go_back_is_named_when_the_world_goes_back(cid):
    """A maximal-coordinate body's links have no state pybullet gives: one warning names
    the body, the first time a contact takes the world back (none while none does)."""
    reset(cid)
    box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
    cube = box(cid, [0.05] * 3, [-1.5, 0.0, 0.0])
    sphere = p.createCollisionShape(p.GEOM_SPHERE, radius=0.1, physicsClientId=cid)
    chained = p.createMultiBody(1.0, sphere, basePosition=[5, 5, 5], linkMasses=[1.0],
                                linkCollisionShapeIndices=[sphere], linkVisualShapeIndices=[-1],
                                linkPositions=[[0, 0, 0.4]], linkOrientations=[[0, 0, 0, 1]],
                                linkInertialFramePositions=[[0, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                                linkParentIndices=[0], linkJointTypes=[p.JOINT_REVOLUTE], linkJointAxis=[[1, 0, 0]],
                                useMaximalCoordinates=True, physicsClientId=cid)
    ccd = BoxCCD(cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(3):
            ccd.step()
        assert not [w for w in caught if "taken back" in str(w.message)]
        throw(cid, cube, speed=100.0, spin=(0, 0, 0))
        for _ in range(40):
            ccd.step()
    assert ccd.stats.rewinds
    named = [w for w in caught if "taken back" in str(w.message)]
    assert len(named) == 1 and f"body {chained} " in str(named[0].message)


# --------------------------------------------------------------- world changes
def test_removed_and_recreated_body_with_the_same_id_is_swept(cid):
    """The usual RL reset: remove a body and create another, which pybullet gives the
    same id, between two steps."""
    through = {False: 0, True: 0}
    for use in (False, True):
        for phase in np.linspace(0, 1, 6, endpoint=False):
            reset(cid)
            box(cid, [0.0005, 1, 1], [0, 0, 0], mass=0.0)
            old = box(cid, [0.5, 0.5, 0.5], [-5, 0, 0], mass=0.0)
            ccd = BoxCCD(cid) if use else None
            ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
            p.removeBody(old, physicsClientId=cid)
            cube = box(cid, [0.05] * 3, [-0.3 - phase * 100 * DT, 0.1, 0.05])
            assert cube == old
            throw(cid, cube)
            for _ in range(30):
                ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
            through[use] += x_of(cid, cube) > 0.0
    assert through[True] == 0 and through[False] >= 3, through


def test_a_body_made_or_removed_every_step_is_read_alone_and_the_world_steps_as_plain(monkeypatch):
    """Bodies spawned and removed between steps (pybullet reuses the ids) among 40 resting
    cubes and an r2d2: BoxCCD reads the body made, not the whole world again, and every
    body ends every step bit for bit where plain pybullet, given the same calls in a
    second client, has it (nothing is fast)."""
    from bullet_boxccd.pybullet_ccd import world as W
    reads = []
    real = W.World._read_body
    monkeypatch.setattr(W.World, "_read_body", lambda self, b: reads.append(b) or real(self, b))
    a, b = p.connect(p.DIRECT), p.connect(p.DIRECT)
    try:
        rngs, spawned = {}, {}
        for c in (a, b):
            p.setGravity(0, 0, -9.81, physicsClientId=c)
            p.loadURDF(os.path.join(pybullet_data.getDataPath(), "plane.urdf"), physicsClientId=c)
            p.loadURDF(os.path.join(pybullet_data.getDataPath(), "r2d2.urdf"), [2, 2, 0.5], physicsClientId=c)
            for i in range(40):
                box(c, [0.05] * 3, [i % 8 * 0.3, i // 8 * 0.3, 0.05])
            rngs[c], spawned[c] = np.random.default_rng(5), []
        ccd = BoxCCD(b)
        p.stepSimulation(physicsClientId=a)
        ccd.step()
        reads.clear()
        for k in range(120):
            for c in (a, b):
                rng = rngs[c]
                if k % 3 != 2 or not spawned[c]:
                    spawned[c].append(box(c, [0.04] * 3, [rng.uniform(-3, -1), rng.uniform(-1, 1), 0.04]))
                else:
                    p.removeBody(spawned[c].pop(int(rng.integers(len(spawned[c])))), physicsClientId=c)
            p.stepSimulation(physicsClientId=a)
            ccd.step()
            for body in range(p.getNumBodies(physicsClientId=a)):
                uid = p.getBodyUniqueId(body, physicsClientId=a)
                assert p.getBasePositionAndOrientation(uid, physicsClientId=a) == \
                    p.getBasePositionAndOrientation(uid, physicsClientId=b), (k, uid)
                assert p.getBaseVelocity(uid, physicsClientId=a) == p.getBaseVelocity(uid, physicsClientId=b), (k, uid)
        assert len(reads) == 80, len(reads)  # the 80 bodies made, each once
        assert ccd.stats.rewinds == 0 and ccd.stats.swept_boxes == 0
    finally:
        p.disconnect(a)
        p.disconnect(b)


@pytest.mark.parametrize("substeps", [1, 4])
@pytest.mark.parametrize("given", ["force", "torque motor"])
def test_a_removed_body_takes_the_forces_given_to_it_along(cid, given, substeps):
    """A force or a torque-mode motor given to a body that is then removed, and a new body
    made under its id, in a step BoxCCD takes in pieces (substeps, or a partial step from a
    fast cube's impact): pybullet dropped the force with the body, so the pieces apply it
    to nothing, and the new body moves as in plain pybullet."""
    ends = {}
    for use in (False, True):
        reset(cid)
        box(cid, [0.005, 2, 2], [0, 0, 0], mass=0.0)
        cube = box(cid, [0.05] * 3, [-0.5, 0, 0])
        p.changeDynamics(cube, -1, maxJointVelocity=1000, physicsClientId=cid)
        p.setPhysicsEngineParameter(numSubSteps=substeps, physicsClientId=cid)
        p.resetBaseVelocity(cube, [150 if substeps == 1 else 0.5, 0, 0], physicsClientId=cid)
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.1, 0.02, 0.02], physicsClientId=cid)
        if given == "force":
            gone = box(cid, [0.05] * 3, [-0.5, 1, 0])
            p.applyExternalForce(gone, -1, [0, 0, 1000], [0, 0, 0], p.WORLD_FRAME, physicsClientId=cid)
        else:
            gone = p.createMultiBody(1, shape, basePosition=[3, 3, 0], linkMasses=[1],
                                     linkCollisionShapeIndices=[shape], linkVisualShapeIndices=[-1],
                                     linkPositions=[[0.2, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
                                     linkInertialFramePositions=[[0, 0, 0]],
                                     linkInertialFrameOrientations=[[0, 0, 0, 1]], linkParentIndices=[0],
                                     linkJointTypes=[p.JOINT_REVOLUTE], linkJointAxis=[[0, 0, 1]], physicsClientId=cid)
            p.setJointMotorControl2(gone, 0, p.TORQUE_CONTROL, force=1.0, physicsClientId=cid)
        p.removeBody(gone, physicsClientId=cid)
        new = box(cid, [0.05] * 3, [-0.5, -1, 0])
        assert new == gone
        ccd = BoxCCD(cid) if use else None
        for _ in range(3):
            ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
        if use and substeps == 1:
            assert ccd.stats.partial_steps >= 1
        ends[use] = (p.getBasePositionAndOrientation(new, physicsClientId=cid)
                     + p.getBaseVelocity(new, physicsClientId=cid))
    p.setPhysicsEngineParameter(numSubSteps=0, physicsClientId=cid)
    assert ends[True] == ends[False]


@pytest.mark.parametrize("substeps", [1, 4])
def test_forces_on_a_removed_body_are_ignored_as_by_pybullet(cid, substeps):
    """A force or torque given to a removed body (an environment's code running on after its
    projectile was removed): pybullet returns None and applies nothing; so do the hooked
    calls, and the steps after are plain pybullet's."""
    ends = {}
    for use in (False, True):
        reset(cid, gravity=-10.0)
        p.setPhysicsEngineParameter(numSubSteps=substeps, physicsClientId=cid)
        cube = box(cid, [0.05] * 3, [0, 0, 1])
        gone = box(cid, [0.05] * 3, [1, 0, 1])
        p.removeBody(gone, physicsClientId=cid)
        ccd = BoxCCD(cid) if use else None
        for _ in range(3):
            for flags in (p.WORLD_FRAME, p.LINK_FRAME):
                assert p.applyExternalForce(gone, -1, [0, 0, 50], [0, 0, 0], flags, physicsClientId=cid) is None
                assert p.applyExternalTorque(gone, -1, [0, 0, 5], flags, physicsClientId=cid) is None
            p.applyExternalForce(cube, -1, [3, 0, 0], [0, 0, 1], p.WORLD_FRAME, physicsClientId=cid)
            ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
        ends[use] = (p.getBasePositionAndOrientation(cube, physicsClientId=cid)
                     + p.getBaseVelocity(cube, physicsClientId=cid))
    p.setPhysicsEngineParameter(numSubSteps=0, physicsClientId=cid)
    assert ends[True] == ends[False]


def _flat_poses(cid, bodies):
    """The bodies' base positions and orientations, one flat list."""
    return [x for b in bodies for part in p.getBasePositionAndOrientation(b, physicsClientId=cid) for x in part]


@pytest.mark.parametrize("substeps", [0, 4])
@pytest.mark.parametrize("bad", [-DT, math.inf, math.nan])
def test_a_step_of_a_time_not_above_zero_is_pybullets(cid, substeps, bad):
    """pybullet steps whatever fixedTimeStep it is given: a step below 0 runs the world
    backwards, or, with substeps, leaves pybullet's substep clock owing that time (the next
    steps do not move until it is paid); one not finite leaves the world's state not finite.
    BoxCCD takes such a step, and after the last two kinds every later one, as pybullet does
    (r2d2 falling in the world too), and names it once."""
    ends = {}
    for use in (False, True):
        reset(cid, gravity=-9.81)
        p.setPhysicsEngineParameter(numSubSteps=substeps, physicsClientId=cid)
        box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
        cube = box(cid, [0.05] * 3, [-0.5, 0, 0])
        throw(cid, cube, speed=3.0)
        robot = p.loadURDF(os.path.join(pybullet_data.getDataPath(), "r2d2.urdf"), [0, -2, 1], physicsClientId=cid)
        ccd = BoxCCD(cid) if use else None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            states = []
            for dt in (DT, bad, DT, DT, DT):
                p.setTimeStep(dt, physicsClientId=cid)
                ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
                states.append(_flat_poses(cid, (cube, robot)))
        ends[use] = np.array(states)
        if use:
            named = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
            assert len(named) == 1 and f"fixedTimeStep is {bad!r}" in named[0], named
    p.setPhysicsEngineParameter(numSubSteps=0, physicsClientId=cid)
    np.testing.assert_array_equal(ends[True], ends[False])


def test_a_robot_given_a_velocity_not_finite_is_stepped_by_pybullet_alone(cid):
    """pybullet takes a NaN velocity and steps the body on, not finite: BoxCCD names the
    body once and leaves it to pybullet (it raised ValueError on such a robot), and the
    rest of the world goes on as in pybullet alone."""
    ends = {}
    for use in (False, True):
        reset(cid, gravity=-9.81)
        robot = p.loadURDF(os.path.join(pybullet_data.getDataPath(), "r2d2.urdf"), [0, -2, 1], physicsClientId=cid)
        cube = box(cid, [0.05] * 3, [0, 0, 0.5])
        ccd = BoxCCD(cid) if use else None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for k in range(5):
                if k == 1:
                    p.resetBaseVelocity(robot, [math.nan, 0, 0], [0, 0, 0], physicsClientId=cid)
                ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
        ends[use] = np.array(_flat_poses(cid, (robot, cube)))
        if use:
            named = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
            assert len(named) == 1 and f"body {robot}: its state in pybullet is not finite" in named[0], named
    np.testing.assert_array_equal(ends[True], ends[False])


def test_a_step_of_no_time_changes_nothing(cid):
    """pybullet's step of 0 s moves nothing: inserted after any of the steps of three cubes
    striking a 1 cm wall at 40-90 m/s, it leaves BoxCCD's run as it was (what the impact left
    for the next step stands), and is named nowhere."""
    def run(zero_after):
        reset(cid)
        box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
        rng = np.random.default_rng(4)
        cubes = [box(cid, [0.05] * 3, [-0.3 - 0.25 * i, rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3)],
                     orn=p.getQuaternionFromEuler(rng.uniform(-1, 1, 3))) for i in range(3)]
        for cube in cubes:
            p.changeDynamics(cube, -1, restitution=0.5, physicsClientId=cid)
            p.resetBaseVelocity(cube, [rng.uniform(40, 90), 0, 0], rng.normal(0, 20, 3).tolist(), physicsClientId=cid)
        ccd = BoxCCD(cid)
        with warnings.catch_warnings():
            warnings.simplefilter("error", BoxCCDWarning)
            for k in range(10):
                ccd.step()
                if k == zero_after:
                    p.setTimeStep(0.0, physicsClientId=cid)
                    ccd.step()
                    p.setTimeStep(DT, physicsClientId=cid)
        return [p.getBasePositionAndOrientation(b, physicsClientId=cid) + p.getBaseVelocity(b, physicsClientId=cid)
                for b in cubes], ccd.stats.partial_steps
    (base, partial) = run(None)
    assert partial >= 3
    for k in range(6):
        assert run(k)[0] == base, k


def batch_scene(cid, use, speed):
    """Boxes made in one createMultiBody(batchPositions=...) call (pybullet's client then
    lists only the last of them) thrown at a 1 cm wall."""
    reset(cid)
    box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid)
    ids = p.createMultiBody(1, col, batchPositions=[[-0.5, y, 0] for y in (-0.6, -0.2, 0.2, 0.6)],
                            physicsClientId=cid)
    for k, b in enumerate(ids):
        p.changeDynamics(b, -1, linearDamping=0, angularDamping=0, maxJointVelocity=1e4, physicsClientId=cid)
        p.resetBaseVelocity(b, [speed * (1 + 0.3 * k), 0, 0], [0, 0, 0], physicsClientId=cid)
    run(cid, use, 24)
    return [p.getBasePositionAndOrientation(b, physicsClientId=cid) + p.getBaseVelocity(b, physicsClientId=cid)
            for b in ids]


def test_boxes_made_in_one_batch_are_all_swept(cid):
    fast = [state[0][0] for state in batch_scene(cid, True, 150.0)]
    assert max(fast) < -0.05, fast  # every one of the batch stopped at the wall
    assert max(state[0][0] for state in batch_scene(cid, False, 150.0)) > 0.01  # plain pybullet lets them through
    assert batch_scene(cid, True, 0.5) == batch_scene(cid, False, 0.5)  # slow: bit for bit as plain pybullet


def platform_scene(cid, use, move, late=False):
    """A mass-0 platform 4 cm thick under a resting cube, moved by ``move(platform, k)``
    before every step k. ``late``: BoxCCD is made after the first move, and a body is
    added halfway (the world is read again then)."""
    reset(cid, gravity=-9.81)
    lift = box(cid, [0.5, 0.5, 0.02], [0, 0, 0.5], mass=0.0)
    cube = box(cid, [0.05] * 3, [0, 0, 0.57])
    ccd, out = None, []
    for k in range(24):
        if use and not late and ccd is None:
            ccd = BoxCCD(cid)
        move(lift, k)
        if late and k == 12:
            box(cid, [0.05] * 3, [3, 0, 0.05])
        if use and ccd is None:
            ccd = BoxCCD(cid)
        ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
        out.append(p.getBasePositionAndOrientation(cube, physicsClientId=cid) +
                   p.getBaseVelocity(cube, physicsClientId=cid))
    return out


def test_a_platform_given_a_velocity_before_boxccd_was_made_lifts_as_in_plain_pybullet(cid):
    def lift(b, k):
        p.resetBaseVelocity(b, [0, 0, 0.5], [0, 0, 0], physicsClientId=cid)

    assert platform_scene(cid, True, lift, late=True) == platform_scene(cid, False, lift, late=True)


def test_a_teleport_pybullet_holds_is_left_to_pybullet(cid):
    """0.5 mm a step: pybullet pushes the cube out of each teleport's overlap by contact ERP
    (0.08) x the overlap a step, and holds it 6 mm deep, less than a free box may move
    unswept (a quarter of its thinnest extent, 1 cm)."""
    def lift(b, k):
        p.resetBasePositionAndOrientation(b, [0, 0, 0.5 + 0.0005 * (k + 1)], [0, 0, 0, 1], physicsClientId=cid)

    assert platform_scene(cid, True, lift) == platform_scene(cid, False, lift)


def test_a_shape_left_to_pybullet_is_named_once_a_fast_box_comes_near_it(cid):
    """BoxCCD sweeps boxes against boxes: a thin static cylinder in a fast box's way is
    named (once), a sphere and a plane out of its reach are not (the sphere lies between
    the cube and a second fast box, well out of both's reach), nor is anything while the
    boxes are slow."""
    for speed, named in ((0.5, []), (100.0, ["body 0 link -1 (cylinder)"])):
        reset(cid)
        p.createMultiBody(0, p.createCollisionShape(p.GEOM_CYLINDER, radius=1.0, height=0.01, physicsClientId=cid),
                          baseOrientation=p.getQuaternionFromEuler([0, np.pi / 2, 0]), physicsClientId=cid)
        p.createMultiBody(0, p.createCollisionShape(p.GEOM_SPHERE, radius=0.5, physicsClientId=cid),
                          basePosition=[0, 10, 0], physicsClientId=cid)
        p.createMultiBody(0, p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid), basePosition=[0, 0, -5],
                          physicsClientId=cid)
        cube = box(cid, [0.05] * 3, [-1, 0, 0])
        other = box(cid, [0.05] * 3, [-1, 20, 0])
        for b in (cube, other):
            throw(cid, b, speed=speed, spin=(0, 0, 0))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            run(cid, True, 10)
        messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
        assert [m.split(" is in the reach")[0] for m in messages] == named, messages


@pytest.mark.parametrize("motion, named", [("dropped", False), ("spinning", False), ("thrown", True)])
def test_a_shape_left_to_pybullet_is_named_only_where_a_box_could_pass_through_it(cid, motion, named):
    """A 0.1 m cube over a heightfield (a surface of no thickness): dropped from 0.3 m
    (9 mm a step, swept as it moves more than 1 cm with its spin) or spinning in place at
    60 rad/s (its corners move 1.5 cm a step), its centre cannot cross the surface within a
    step: not named. Thrown down at 30 m/s (12.5 cm a step, more than its half extent):
    named."""
    reset(cid, gravity=-9.81)
    ground = p.createCollisionShape(p.GEOM_HEIGHTFIELD, meshScale=[0.1, 0.1, 1], heightfieldData=[0.0] * 64 * 64,
                                    numHeightfieldRows=64, numHeightfieldColumns=64, physicsClientId=cid)
    p.createMultiBody(0, ground, physicsClientId=cid)
    cube = box(cid, [0.05] * 3, [0, 0, 0.3 if motion == "dropped" else 0.06])
    if motion == "spinning":
        p.resetBaseVelocity(cube, [0, 0, 0], [0, 0, 60], physicsClientId=cid)
    if motion == "thrown":
        p.resetBasePositionAndOrientation(cube, [0, 0, 1.0], [0, 0, 0, 1], physicsClientId=cid)
        p.resetBaseVelocity(cube, [0, 0, -30], [0, 0, 0], physicsClientId=cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ccd = run(cid, True, 60)
    messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert ccd.stats.swept_boxes > 0
    assert [m.split(" is in the reach")[0] for m in messages] == (["body 0 link -1 (heightfield)"] if named else []), \
        messages


@pytest.mark.parametrize("shape", ["sphere", "capsule", "cylinder"])
def test_a_fast_body_with_no_box_is_named_once(cid, shape):
    """A free body with no box (BoxCCD cannot sweep it) thrown at 150 m/s through a 1 cm box
    wall, as plain pybullet lets it: named once, with its move a step; the same body
    rolling at 1 m/s (4 mm a step, less than half its 10 cm thickness) is not named."""
    make = {"sphere": dict(shapeType=p.GEOM_SPHERE, radius=0.05),
            "capsule": dict(shapeType=p.GEOM_CAPSULE, radius=0.05, height=0.2),
            "cylinder": dict(shapeType=p.GEOM_CYLINDER, radius=0.05, height=0.2)}[shape]
    for speed, named in ((1.0, False), (150.0, True)):
        reset(cid)
        box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
        body = p.createMultiBody(1, p.createCollisionShape(**make, physicsClientId=cid), basePosition=[-0.5, 0, 0],
                                 physicsClientId=cid)
        p.changeDynamics(body, -1, linearDamping=0, maxJointVelocity=1000, physicsClientId=cid)
        p.resetBaseVelocity(body, [speed, 0, 0], physicsClientId=cid)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            run(cid, True, 20)
        messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
        expected = [f"body {body} ({shape}) moves {150.0 * DT:.3g} m a step"] if named else []
        assert [m.split(", more than")[0] for m in messages] == expected, messages
        if named:
            assert x_of(cid, body) > 0.0  # pybullet let it through, as the warning says


def test_a_fast_compound_with_no_box_is_sized_by_its_smallest_shape(cid):
    """A free compound of two 1 cm spheres 52 cm apart on a diagonal (its bounding box 32 cm
    thick) is named when it moves 5 cm a step, more than a sphere's radius, and not at 4 mm
    a step: its size is its shapes', not its bounding box's."""
    for speed, named in ((1.0, False), (12.0, True)):
        reset(cid)
        box(cid, [0.001, 1, 1], [0, 0, 0], mass=0.0)
        spheres = p.createCollisionShapeArray([p.GEOM_SPHERE] * 2, radii=[0.01] * 2,
                                              collisionFramePositions=[[-0.15] * 3, [0.15] * 3], physicsClientId=cid)
        body = p.createMultiBody(1.0, spheres, basePosition=[-0.5, 0, 0], physicsClientId=cid)
        p.changeDynamics(body, -1, linearDamping=0, physicsClientId=cid)
        p.resetBaseVelocity(body, [speed, 0, 0], physicsClientId=cid)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            run(cid, True, 20)
        messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
        expected = [f"body {body} (sphere) moves {12.0 * DT:.3g} m a step, more than half the smallest extent of "
                    "its shapes (0.01 m)"] if named else []
        assert [m.split(": BoxCCD")[0] for m in messages] == expected, messages


def test_a_fast_box_with_a_sphere_beside_it_is_named_once(cid):
    """A free body of a 5 cm box and a 2 cm sphere (createCollisionShapeArray) swept as fast:
    at 150 m/s (0.625 m a step) its sphere, left to pybullet, can pass through a 1 cm wall
    while the world goes back to the box's contact: named once; at 3.6 m/s (1.5 cm a step:
    the box is swept, the sphere cannot cross itself) not."""
    for speed, named in ((3.6, False), (150.0, True)):
        reset(cid)
        box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
        shape = p.createCollisionShapeArray([p.GEOM_BOX, p.GEOM_SPHERE], halfExtents=[[0.025] * 3, [0, 0, 0]],
                                            radii=[0, 0.02], collisionFramePositions=[[0, 0, 0], [-0.05, 0, 0]],
                                            physicsClientId=cid)
        body = p.createMultiBody(0.1, shape, basePosition=[0.5, 0, 0], physicsClientId=cid)
        p.changeDynamics(body, -1, linearDamping=0, maxJointVelocity=1000, physicsClientId=cid)
        p.resetBaseVelocity(body, [-speed, 0, 0], physicsClientId=cid)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ccd = run(cid, True, 48)
        messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
        expected = [f"body {body} link -1 (sphere) moves {speed * DT:.3g} m a step with its boxes"] if named else []
        assert [m.split(", more than")[0] for m in messages] == expected, messages
        assert ccd.stats.swept_boxes > 0


def test_a_fast_body_of_links_with_no_box_is_named_once(cid):
    """Two spheres on a hinge (no box: BoxCCD cannot sweep them) thrown at 150 m/s through a
    1 cm box wall, as plain pybullet lets them: named once, with the base's move a step."""
    reset(cid)
    box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
    sphere = p.createCollisionShape(p.GEOM_SPHERE, radius=0.05, physicsClientId=cid)
    body = p.createMultiBody(1.0, sphere, basePosition=[-0.5, 0, 0], linkMasses=[1],
                             linkCollisionShapeIndices=[sphere], linkVisualShapeIndices=[-1],
                             linkPositions=[[0, 0, 0.2]], linkOrientations=[[0, 0, 0, 1]],
                             linkInertialFramePositions=[[0, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                             linkParentIndices=[0], linkJointTypes=[p.JOINT_REVOLUTE], linkJointAxis=[[1, 0, 0]],
                             physicsClientId=cid)
    p.changeDynamics(body, -1, linearDamping=0, maxJointVelocity=1000, physicsClientId=cid)
    p.resetBaseVelocity(body, [150.0, 0, 0], physicsClientId=cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run(cid, True, 20)
    messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert [m.split(", more than")[0] for m in messages] == [f"body {body} (sphere) moves {150.0 * DT:.3g} m a step"], \
        messages
    assert x_of(cid, body) > 0.0  # pybullet let it through, as the warning says


def test_steps_taken_by_pybullet_directly_are_named_once(cid):
    """The user calls p.stepSimulation between BoxCCD's steps: those steps are pybullet's alone
    (named once; not the steps taken before BoxCCD was made), and a slow world with a
    platform Bullet moves by its velocity stays bit-identical to plain pybullet stepped
    alike."""
    worlds = []
    for use in (False, True):
        reset(cid, gravity=-9.81)
        box(cid, [2, 2, 0.05], [0, 0, -0.05], mass=0.0)
        platform = box(cid, [0.2, 0.2, 0.02], [-1, 0, 0.3], mass=0.0)
        p.resetBaseVelocity(platform, [3, 0, 0], physicsClientId=cid)
        cube = box(cid, [0.05] * 3, [0.5, 0.5, 0.05])
        p.resetBaseVelocity(cube, [0, 0, 0], [0, 0, 2], physicsClientId=cid)
        p.stepSimulation(physicsClientId=cid)
        ccd = BoxCCD(cid) if use else None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for k in range(40):
                ccd.step() if use and k % 3 else p.stepSimulation(physicsClientId=cid)
        worlds.append([(p.getBasePositionAndOrientation(b, physicsClientId=cid),
                        p.getBaseVelocity(b, physicsClientId=cid)) for b in (platform, cube)])
    messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert len(messages) == 1 and messages[0].startswith("p.stepSimulation was called on this world directly"), \
        messages
    assert worlds[0] == worlds[1]


def test_settings_pybullet_does_not_report_of_a_client_connected_before_the_import_are_named(tmp_path):
    """A client connected before bullet_boxccd was imported may have a contactERP, erp,
    frictionERP and collisionFilterMode that pybullet does not report: BoxCCD names them once
    (and not those set again after the import); a client connected after the import is not
    named."""
    script = """
import warnings
import pybullet as p
before = p.connect(p.DIRECT)
p.setPhysicsEngineParameter(collisionFilterMode=0, physicsClientId=before)
again = p.connect(p.DIRECT)
from bullet_boxccd import BoxCCD
p.setPhysicsEngineParameter(contactERP=0.1, physicsClientId=again)
after = p.connect(p.DIRECT)
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    for cid in (before, again, after):
        ccd = BoxCCD(cid)
        ccd.step()
        ccd.step()
        said = [str(w.message).removeprefix(f"physics client {cid}: ") for w in caught]
        print(cid, repr([m.split(":")[0] for m in said]))
        caught.clear()
"""
    # (run outside the checkout, which would shadow the installed package)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    lines = [line for line in out.stdout.splitlines() if line[:1].isdigit()]
    named = "this client was connected before bullet_boxccd was imported, and pybullet does not report its {}"
    assert lines == [f"0 {[named.format('collisionFilterMode, contactERP, erp and frictionERP')]!r}",
                     f"1 {[named.format('collisionFilterMode, erp and frictionERP')]!r}", "2 []"], out.stdout


@pytest.mark.parametrize("case, named", [("plain", True), ("maximal", True), ("pair filter", False),
                                         ("group filter", False), ("its own", False)])
def test_a_shape_left_to_pybullet_is_named_as_pybullet_collides_it(cid, case, named):
    """A static sphere in a fast cube's way is named, made in maximal coordinates too
    (pybullet meets it alone); one the user filtered out of the cube's collisions (a pair
    rule, or groups and masks) is not: pybullet never meets it (the cube passes through it
    with no contact), and neither is a sphere of the cube's own body as one in its reach
    (it is named as a shape moving with the cube's boxes)."""
    reset(cid)
    cube = box(cid, [0.05] * 3, [-1.5, 0, 0])
    if case == "its own":
        shape = p.createCollisionShapeArray([p.GEOM_BOX, p.GEOM_SPHERE], halfExtents=[[0.05] * 3, [0] * 3],
                                            radii=[0, 0.05], collisionFramePositions=[[0] * 3, [0.3, 0, 0]],
                                            physicsClientId=cid)
        p.removeBody(cube, physicsClientId=cid)
        cube = p.createMultiBody(1, shape, basePosition=[-1.5, 0, 0], physicsClientId=cid)
    else:
        sphere = p.createMultiBody(0, p.createCollisionShape(p.GEOM_SPHERE, radius=0.3, physicsClientId=cid),
                                   useMaximalCoordinates=case == "maximal", physicsClientId=cid)
    if case == "pair filter":
        p.setCollisionFilterPair(cube, sphere, -1, -1, 0, physicsClientId=cid)
    if case == "group filter":
        p.setCollisionFilterGroupMask(sphere, -1, 2, 2, physicsClientId=cid)
        p.setCollisionFilterGroupMask(cube, -1, 1, 1, physicsClientId=cid)
    throw(cid, cube, speed=60.0, spin=(0, 0, 0))
    contacts = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run(cid, True, 12, lambda k: case != "its own" and contacts.append(
            len(p.getContactPoints(cube, sphere, physicsClientId=cid))))
    messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    if case == "its own":
        assert [m.split(" moves")[0] for m in messages] == [f"body {cube} link -1 (sphere)"], messages
    else:
        assert messages == (["body 1 link -1 (sphere) is in the reach of a fast box: BoxCCD sweeps boxes against "
                             "boxes only, so pybullet alone meets that contact and the box can pass through it"]
                            if named else []), messages
        assert (max(contacts) > 0) == named, contacts


@pytest.mark.parametrize("other_box", [True, False])
def test_a_box_link_swinging_at_a_shape_left_to_pybullet_names_it(cid, other_box):
    """A box link spun about its centre at 80 rad/s by a fixed base sweeps through a static
    sphere 15 cm from its axis: the sphere is named, as for a free box, whether or not the
    world holds another box the robot could meet."""
    reset(cid)
    link = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.2, 0.02, 0.02], physicsClientId=cid)
    base = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid)
    arm = p.createMultiBody(0, base, linkMasses=[1.0], linkCollisionShapeIndices=[link], linkVisualShapeIndices=[-1],
                            linkPositions=[[0.3, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
                            linkInertialFramePositions=[[0, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                            linkParentIndices=[0], linkJointTypes=[p.JOINT_REVOLUTE], linkJointAxis=[[0, 0, 1]],
                            physicsClientId=cid)
    p.setJointMotorControl2(arm, 0, p.VELOCITY_CONTROL, force=0, physicsClientId=cid)
    sphere = p.createMultiBody(0, p.createCollisionShape(p.GEOM_SPHERE, radius=0.03, physicsClientId=cid),
                               basePosition=[0.3, 0.15, 0], physicsClientId=cid)
    if other_box:
        box(cid, [0.05] * 3, [3, 3, 3], mass=0.0)
    p.resetJointState(arm, 0, 0, 80, physicsClientId=cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run(cid, True, 8)
    messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert [m.split(" is in the reach")[0] for m in messages] == [f"body {sphere} link -1 (sphere)"], messages


def test_a_kinematic_box_teleported_through_a_shape_left_to_pybullet_names_it(cid):
    """A mass-0 plate the user teleports 0.3 m a step (pybullet sees no motion) passes a
    sphere on its way: the sphere is named in the step of that jump, not before."""
    reset(cid)
    plate = box(cid, [0.05, 0.3, 0.3], [-1.5, 0, 0], mass=0.0)
    sphere = p.createMultiBody(0.1, p.createCollisionShape(p.GEOM_SPHERE, radius=0.05, physicsClientId=cid),
                               physicsClientId=cid)
    ccd = BoxCCD(cid)
    named = []
    for k in range(8):
        x = -1.5 + 0.3 * (k + 1)
        p.resetBasePositionAndOrientation(plate, [x, 0, 0], [0, 0, 0, 1], physicsClientId=cid)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ccd.step()
        named += [(k, round(x, 2), str(w.message).split(" is in")[0]) for w in caught]
    assert named == [(4, 0.0, f"body {sphere} link -1 (sphere)")], named


def test_a_box_whose_state_is_not_finite_is_named_once_and_left_to_pybullet(cid):
    """A free box given a NaN velocity is named in one warning and left to pybullet; a fast
    cube beside it is still stopped at the wall."""
    reset(cid)
    box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
    broken = box(cid, [0.05] * 3, [-1.0, 0.5, 0])
    cube = box(cid, [0.05] * 3, [-0.5, 0, 0])
    throw(cid, cube)
    p.resetBaseVelocity(broken, [float("nan"), 0, 0], physicsClientId=cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run(cid, True, 10)
    messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert messages == [f"body {broken}: its state in pybullet is not finite (NaN or infinite): pybullet steps it "
                        "alone, unswept"], messages
    assert x_of(cid, cube) < 0.0


@pytest.mark.parametrize("when", ["before", "after"])
def test_a_fixed_wall_placed_at_nan_is_named_once(cid, when):
    """A static wall the user places at a NaN position, before BoxCCD is made or after,
    meets nothing in pybullet, and a cube thrown at it passes where it was, as in plain
    pybullet: BoxCCD names the wall once, as it names a free box left not finite."""
    ends = []
    for use in (False, True):
        reset(cid)
        wall = box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
        cube = box(cid, [0.05] * 3, [-0.5, 0, 0])
        throw(cid, cube)
        if when == "before":
            p.resetBasePositionAndOrientation(wall, [float("nan"), 0, 0], [0, 0, 0, 1], physicsClientId=cid)

        def place(k, wall=wall):
            if when == "after" and k == 1:
                p.resetBasePositionAndOrientation(wall, [float("nan"), 0, 0], [0, 0, 0, 1], physicsClientId=cid)

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            run(cid, use, 10, place)
        messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
        assert messages == ([f"body {wall}: its state in pybullet is not finite (NaN or infinite): pybullet steps "
                             "it alone, unswept"] if use else []), messages
        ends.append(x_of(cid, cube))
    assert ends[0] == ends[1] > 0.5


@pytest.mark.parametrize("where", [[float("nan"), 0, 0], [0, 0, float("inf")]])
def test_a_free_box_teleported_to_a_pose_not_finite_is_named_once(cid, where):
    """A free box the user places at a NaN or infinite position is named once, as one
    whose velocity is not finite; a fast cube beside it is still stopped at the wall."""
    reset(cid)
    box(cid, [0.005, 1, 1], [0, 0, 0], mass=0.0)
    broken = box(cid, [0.05] * 3, [-1.0, 0.5, 0])
    cube = box(cid, [0.05] * 3, [-0.5, 0, 0])
    throw(cid, cube)

    def place(k):
        if k == 1:
            p.resetBasePositionAndOrientation(broken, where, [0, 0, 0, 1], physicsClientId=cid)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run(cid, True, 10, place)
    messages = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert messages == [f"body {broken}: its state in pybullet is not finite (NaN or infinite): pybullet steps it "
                        "alone, unswept"], messages
    assert x_of(cid, cube) < 0.0


@pytest.mark.parametrize("how", ["urdf", "changeDynamics", "none"])
def test_joint_damping_with_substeps_is_named(cid, how):
    """pybullet computes a joint's damping once per stepSimulation, from the joint velocities
    the step starts with, and keeps it through the step's substeps; BoxCCD's substeps
    compute it again each (a swinging link damped at 0.5 N m s ends 10 steps of 2
    substeps 7 % faster than in plain pybullet). A robot with joint damping, from its URDF
    or changeDynamics, in a world BoxCCD substeps (a box on the floor) is named once; one
    without, or a world without substeps, is not."""
    said = []
    for substeps in (2, 0):
        reset(cid, gravity=-9.81)
        p.setPhysicsEngineParameter(numSubSteps=substeps, physicsClientId=cid)
        box(cid, [1, 1, 0.05], [0, 0, -0.05], mass=0.0)
        box(cid, [0.05] * 3, [1.5, 0, 0.05])
        if how == "urdf":
            robot = p.loadURDF(os.path.join(pybullet_data.getDataPath(), "kuka_iiwa/model.urdf"), [0, 0, 0],
                               useFixedBase=True, physicsClientId=cid)
        else:
            robot = p.loadURDF(os.path.join(pybullet_data.getDataPath(), "r2d2.urdf"), [0, 2, 0.5],
                               physicsClientId=cid)
        ccd = BoxCCD(cid)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ccd.step()
            if how == "changeDynamics":
                p.changeDynamics(robot, 1, jointDamping=0.3, physicsClientId=cid)
            for _ in range(3):
                ccd.step()
        said.append([str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)])
    assert said[1] == []
    if how == "none":
        assert said[0] == []
    else:
        assert len(said[0]) == 1 and f"the joint damping of body {robot} " in said[0][0], said


def test_a_plane_of_normal_zero_is_left_to_pybullet_unnamed(cid):
    """Bullet's plane of normal 0 meets nothing: a box falls through it as in pybullet,
    and nothing is named (its half-space has no side to be under)."""
    paths, caught = [], []
    for use in (False, True):
        reset(cid, gravity=-9.81)
        p.createMultiBody(0, p.createCollisionShape(p.GEOM_PLANE, planeNormal=[0, 0, 0], physicsClientId=cid),
                          physicsClientId=cid)
        cube = box(cid, [0.05] * 3, [0, 0, 0.5])
        p.resetBaseVelocity(cube, [0, 0, -30], physicsClientId=cid)
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            run(cid, use, 20)
        caught += [str(x.message) for x in w if issubclass(x.category, BoxCCDWarning)]
        paths.append(p.getBasePositionAndOrientation(cube, physicsClientId=cid))
    assert paths[0] == paths[1] and paths[0][0][2] < -1.0 and not caught, (paths, caught)


def test_body_made_dynamic_with_change_dynamics_is_swept(cid):
    through = {False: 0, True: 0}
    for use in (False, True):
        for phase in np.linspace(0, 1, 6, endpoint=False):
            reset(cid)
            box(cid, [0.0005, 1, 1], [0, 0, 0], mass=0.0)
            cube = box(cid, [0.05] * 3, [-0.3 - phase * 100 * DT, 0.1, 0.05], mass=0.0)
            ccd = BoxCCD(cid) if use else None
            p.changeDynamics(cube, -1, mass=1.0, physicsClientId=cid)
            throw(cid, cube)
            for _ in range(30):
                ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
            through[use] += x_of(cid, cube) > 0.0
    assert through[True] == 0 and through[False] >= 3, through


# ------------------------------------------------------------------ substeps
def quiet_scene(cid, use, substeps, force):
    reset(cid, gravity=-9.81)
    p.setPhysicsEngineParameter(numSubSteps=substeps, physicsClientId=cid)
    box(cid, [2, 2, 0.05], [0, 0, -0.05], mass=0.0)
    stack = [box(cid, [0.1, 0.1, 0.05], [0.01 * i, 0, 0.05 + 0.1 * i]) for i in range(5)]
    slider = box(cid, [0.1, 0.1, 0.1], [1.0, 0, 0.1])
    p.resetBaseVelocity(slider, [0.5, 0, 0], [0, 0, 0], physicsClientId=cid)
    traj = []

    def push(k):
        if force:  # pybullet clears forces after every stepSimulation: the plugin replays them per substep
            p.applyExternalForce(slider, -1, [3, 0, 0], [1.0, 0.02, 0.15], p.WORLD_FRAME, physicsClientId=cid)
            p.applyExternalTorque(stack[-1], -1, [0, 0, 0.2], p.WORLD_FRAME, physicsClientId=cid)
        traj.append([p.getBasePositionAndOrientation(b, physicsClientId=cid)[0] for b in stack + [slider]])

    run(cid, use, 300, push)
    params = p.getPhysicsEngineParameters(physicsClientId=cid)
    assert params["numSubSteps"] == substeps and params["fixedTimeStep"] == DT  # the user's settings, restored
    return np.array(traj)


@pytest.mark.parametrize("substeps", [2, 4])
def test_substeps_follow_plain_substepped_pybullet(cid, substeps):
    for force in (False, True):
        plain = quiet_scene(cid, False, substeps, force)
        with_ccd = quiet_scene(cid, True, substeps, force)
        assert np.abs(plain - with_ccd).max() <= 1e-9, (substeps, force)


@pytest.mark.parametrize("substeps", [2, 4])
def test_substeps_are_each_swept(cid, substeps):
    through = {False: 0, True: 0}
    for use in (False, True):
        for phase in np.linspace(0, 1, 6, endpoint=False):
            reset(cid)
            p.setPhysicsEngineParameter(numSubSteps=substeps, physicsClientId=cid)
            box(cid, [0.0005, 1, 1], [0, 0, 0], mass=0.0)
            cube = box(cid, [0.05] * 3, [-0.3 - phase * 300 * DT, 0.1, 0.05])
            throw(cid, cube, speed=300.0)
            ccd = BoxCCD(cid) if use else None
            for _ in range(12):
                ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
            through[use] += x_of(cid, cube) > 0.0
    assert through[True] == 0 and through[False] >= 3, through


# ----------------------------------------------------------------- arguments
@pytest.mark.parametrize("kwargs", [
    dict(sweep_threshold=float("nan")), dict(sweep_threshold=-0.1), dict(sweep_threshold=float("inf")),
    dict(fit_tolerance=0.0), dict(fit_tolerance=2.0), dict(penetration=1.0), dict(penetration=0.0),
    dict(penetration=float("nan")), dict(impact_depth=0.0), dict(impact_depth=0.1), dict(max_partial_steps=-1),
    dict(max_partial_steps=2.5),
    dict(depth_tolerance=-1.0), dict(depth_tolerance=float("nan")), dict(sweep_distance=-0.01),
    dict(sweep_distance="far"), dict(self_collision_bodies=[999]), dict(self_collision_bodies=5),
    dict(tolerances=1e-12), dict(max_turn=0.0),
    dict(max_turn=1.0), dict(max_turn=float("nan")),
])
def test_bad_arguments_raise_naming_argument_and_value(cid, kwargs):
    reset(cid)
    box(cid, [0.1] * 3, [0, 0, 0])
    name = next(iter(kwargs))
    with pytest.raises(InvalidInputError, match=name):
        BoxCCD(cid, **kwargs)


def test_bad_calls_raise(cid):
    reset(cid)
    cube = box(cid, [0.1] * 3, [0, 0, 0])
    plate = p._bullet_boxccd_originals["createMultiBody"](
        1.0, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.3, 0.2, 0.0004], physicsClientId=cid),
        basePosition=[2, 0, 0], useMaximalCoordinates=True, physicsClientId=cid)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BoxCCDWarning)
        ccd = BoxCCD(cid)
    with pytest.raises(InvalidInputError, match="999"):
        ccd.register_box(999, -1, [0.1] * 3)
    with pytest.raises(InvalidInputError, match="link 3"):
        ccd.register_box(plate, 3, [0.1] * 3)
    with pytest.raises(InvalidInputError, match="readable"):
        ccd.register_box(cube, -1, [0.1] * 3)
    with pytest.raises(InvalidInputError, match="half_extents"):
        ccd.register_box(plate, -1, [0.1, -1, 0.1])
    ccd.register_box(plate, -1, [0.3, 0.2, 0.0004])
    with pytest.raises(InvalidInputError, match="registered already"):
        ccd.register_box(plate, -1, [0.3, 0.2, 0.0004])
    with pytest.raises(InvalidInputError, match="999"):
        ccd.set_collision_filter_pair(999, cube, -1, -1, False)
    for bad in (12345, -1, 2 ** 40, 1.0):
        with pytest.raises(InvalidInputError, match="physics_client_id"):
            BoxCCD(bad)


def test_max_partial_steps_zero_still_steps(cid):
    reset(cid)
    cube = box(cid, [0.1] * 3, [0, 0, 0])
    p.resetBaseVelocity(cube, [1, 0, 0], [0, 0, 0], physicsClientId=cid)
    ccd = BoxCCD(cid, max_partial_steps=0)
    for _ in range(10):
        ccd.step()
    assert x_of(cid, cube) > 0.04


# ----------------------------------------------------------------- lifecycle
def test_a_disconnected_client_is_a_typed_error_and_a_reconnected_one_is_named():
    from bullet_boxccd import ClientDisconnectedError

    cid = p.connect(p.DIRECT)
    box(cid, [0.1] * 3, [0, 0, 0])
    ccd = BoxCCD(cid)
    ccd.step()
    p.disconnect(cid)
    for call in (ccd.step, ccd.refresh):
        with pytest.raises(ClientDisconnectedError, match=f"physics client {cid} was disconnected"):
            call()
    again = p.connect(p.DIRECT)  # pybullet reuses the freed id: another, empty world
    try:
        assert again == cid
        for call in (ccd.step, ccd.refresh):
            with pytest.raises(ClientDisconnectedError, match="a new world connected under its id"):
                call()
    finally:
        p.disconnect(again)


def test_the_same_warning_of_two_clients_is_shown_for_each(cid):
    """Two worlds stepped on one line, each with a box at pybullet's velocity clamp: under
    Python's default warning filter (a message once per line) both are shown, the second
    naming its client."""
    other = p.connect(p.DIRECT)
    try:
        ccds = []
        for c in (cid, other):
            reset(c)
            cube = p.loadURDF(os.path.join(pybullet_data.getDataPath(), "cube_small.urdf"), physicsClientId=c)
            p.resetBaseVelocity(cube, [150, 0, 0], [0, 0, 0], physicsClientId=c)
            ccds.append(BoxCCD(c))
        with warnings.catch_warnings(record=True) as caught:
            warnings.resetwarnings()
            warnings.simplefilter("default")
            for _ in range(3):
                for ccd in ccds:
                    ccd.step()
        said = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
        first = "" if cid == 0 else f"physics client {cid}: "
        assert [m.split(" moves or turns")[0] for m in said] == [first + "body 0", f"physics client {other}: body 0"]
    finally:
        p.disconnect(other)


@pytest.mark.parametrize("substeps", [0, 2])
@pytest.mark.parametrize("given", [(150.0, 0.0, 0.0), (110.0, 30.0, -20.0)])
def test_a_fast_box_at_pybullets_velocity_clamp_is_named_once(cid, given, substeps):
    """pybullet clamps each component of a body's velocity to 100 m/s by default
    (maxJointVelocity): a box given 150 m/s, or (110, 30, -20) (cut to (100, 29.4,
    -19.6), its speed 105.7), moves at the clamp along x, and BoxCCD says so once; one
    given as much with the clamp lifted moves faster and nothing is said; nor of one
    given (60, 60, 60) (104 m/s, no component at the clamp). With two substeps the first
    cuts the box to the clamp and the second damps it below: named all the same."""
    reset(cid)
    p.setPhysicsEngineParameter(numSubSteps=substeps, physicsClientId=cid)
    data = pybullet_data.getDataPath()
    clamped = p.loadURDF(os.path.join(data, "cube_small.urdf"), [0, 0, 0], physicsClientId=cid)
    lifted = p.loadURDF(os.path.join(data, "cube_small.urdf"), [0, 5, 0], physicsClientId=cid)
    under = p.loadURDF(os.path.join(data, "cube_small.urdf"), [0, -5, 0], physicsClientId=cid)
    p.changeDynamics(lifted, -1, maxJointVelocity=1000, physicsClientId=cid)
    for b in (clamped, lifted):
        p.resetBaseVelocity(b, given, [0, 0, 0], physicsClientId=cid)
    p.resetBaseVelocity(under, [60, 60, 60], [0, 0, 0], physicsClientId=cid)
    ccd = BoxCCD(cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(4):
            ccd.step()
    said = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert len(said) == 1 and f"body {clamped} " in said[0] and "maxJointVelocity" in said[0], said
    assert caught[0].filename == __file__
    assert p.getBaseVelocity(lifted, physicsClientId=cid)[0][0] > 100.5  # not clamped (damped a little)


def test_a_box_at_a_velocity_clamp_it_was_given_is_named_with_that_clamp(cid):
    """A cube given 1500 m/s with its clamp raised to 1000 (changeDynamics maxJointVelocity)
    is cut to 1000 by pybullet: named once, with its clamp; one given 900 m/s under the
    same clamp is not."""
    reset(cid)
    cut = p.loadURDF(CUBE_SMALL, [0, 0, 0], physicsClientId=cid)
    under = p.loadURDF(CUBE_SMALL, [0, 5, 0], physicsClientId=cid)
    for b, speed in ((cut, 1500.0), (under, 900.0)):
        p.changeDynamics(b, -1, maxJointVelocity=1000, linearDamping=0, physicsClientId=cid)
        p.resetBaseVelocity(b, [speed, 0, 0], [0, 0, 0], physicsClientId=cid)
    ccd = BoxCCD(cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(3):
            ccd.step()
    said = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert [m.split(" (m/s")[0] for m in said] == [f"body {cut} moves or turns at 1000"], said
    assert "maxJointVelocity" in said[0]
    assert p.getBaseVelocity(cut, physicsClientId=cid)[0][0] == pytest.approx(1000.0)


def test_a_velocity_given_above_the_clamp_is_named_though_a_contact_slows_it_below(cid):
    """A cube given 150 m/s along a floor is cut to 100 by pybullet and slowed below it by
    friction in the same step (99.96): it is named all the same, once; so is one whose
    clamp was raised to 120, with that clamp; one given as much with its clamp lifted to
    1000 is not, nor one given 150 m/s and removed before the step."""
    reset(cid, -9.81)
    p.loadURDF(os.path.join(pybullet_data.getDataPath(), "plane.urdf"), physicsClientId=cid)
    clamped = p.loadURDF(CUBE_SMALL, [0, 0, 0.025], physicsClientId=cid)
    lifted = p.loadURDF(CUBE_SMALL, [0, 1, 0.025], physicsClientId=cid)
    gone = p.loadURDF(CUBE_SMALL, [0, 2, 0.025], physicsClientId=cid)
    raised = p.loadURDF(CUBE_SMALL, [0, 3, 0.025], physicsClientId=cid)
    p.changeDynamics(lifted, -1, maxJointVelocity=1000, physicsClientId=cid)
    p.changeDynamics(raised, -1, maxJointVelocity=120, physicsClientId=cid)
    for b in (clamped, lifted, gone, raised):
        p.resetBaseVelocity(b, np.array([150.0, 0, 0]), np.zeros(3), physicsClientId=cid)  # as arrays too
    p.removeBody(gone, physicsClientId=cid)
    ccd = BoxCCD(cid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ccd.step()
        first = p.getBaseVelocity(clamped, physicsClientId=cid)[0][0]
        for _ in range(2):
            ccd.step()
    said = [str(w.message) for w in caught if issubclass(w.category, BoxCCDWarning)]
    assert sorted(m.split(" (m/s")[0] for m in said) == [f"body {clamped} moves or turns at 100",
                                                         f"body {raised} moves or turns at 120"], said
    assert 99.0 < first < 100.0
    assert p.getBaseVelocity(raised, physicsClientId=cid)[0][0] < 120.0  # (slowed below its clamp)


def test_the_velocity_clamp_is_named_where_the_step_leaves_the_world_at_it(cid):
    """A cube thrown at 60-100 m/s at a wall is often spun past 100 rad/s on some axis by
    its impact, and pybullet's default clamp cuts that. Sometimes only the step
    pybullet took first is cut, and the world then goes back from that step. Sometimes
    only a later piece of the step is cut, one in which the cube no longer moves far.
    Over 24 throws, the warning comes in the step whose end finds the cube at the clamp
    (getBaseVelocity: a component at 100 or more), and only then."""
    for seed in range(24):
        rng = np.random.default_rng(seed)
        reset(cid, -9.81)
        p.setPhysicsEngineParameter(numSubSteps=0, physicsClientId=cid)
        box(cid, [0.05, 1, 1], [0, 0, 1], mass=0.0)
        p.changeDynamics(0, -1, restitution=1, physicsClientId=cid)
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid)
        turned = p.getQuaternionFromEuler(rng.uniform(-3, 3, 3))
        cube = p.createMultiBody(1, shape, basePosition=[-2, 0, 1], baseOrientation=turned, physicsClientId=cid)
        p.changeDynamics(cube, -1, restitution=rng.uniform(0, 1), physicsClientId=cid)
        p.resetBaseVelocity(cube, [rng.uniform(60, 99.9), 0, 0], rng.normal(0, 40, 3).tolist(), physicsClientId=cid)
        ccd = BoxCCD(cid)
        named, at_clamp = [], []
        for k in range(12):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                ccd.step()
            named += [k] * sum(issubclass(w.category, BoxCCDWarning) for w in caught)
            v, w = p.getBaseVelocity(cube, physicsClientId=cid)
            if max(map(abs, v + w)) >= 100.0 * (1 - 1e-9):
                at_clamp.append(k)
        assert named == at_clamp[:1], (seed, named, at_clamp)


def test_a_body_made_under_a_removed_ones_id_is_judged_and_named_as_itself(cid):
    """A cube given 150 m/s is named at the clamp. Removed, a cube made under its id
    with its clamp lifted is not cut and not named. Removed again, a third cube with
    pybullet's default clamp is cut to 100 m/s and named afresh, although the first
    cube was named under the same id and the second had its clamp lifted."""
    reset(cid)
    ccd = BoxCCD(cid)
    said, speeds = [], []
    for lifted in (False, True, False):
        cube = p.loadURDF(CUBE_SMALL, [0, 0, 0], physicsClientId=cid)
        if lifted:
            p.changeDynamics(cube, -1, maxJointVelocity=1000, physicsClientId=cid)
        p.resetBaseVelocity(cube, [150, 0, 0], [0, 0, 0], physicsClientId=cid)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ccd.step()
        said.append(sum(issubclass(w.category, BoxCCDWarning) for w in caught))
        speeds.append(p.getBaseVelocity(cube, physicsClientId=cid)[0][0])
        p.removeBody(cube, physicsClientId=cid)
    assert speeds[0] == speeds[2] == 100.0 and speeds[1] > 140.0, speeds
    assert said == [1, 0, 1], said


def test_a_boxccd_kept_across_reset_simulation_names_the_new_worlds_conditions(cid):
    """What BoxCCD said of a world is forgotten when pybullet resets it: a cube at the
    velocity clamp in each of three worlds built in turn in one client is named in each."""
    reset(cid)
    ccd = BoxCCD(cid)
    said = []
    for _ in range(3):
        reset(cid)
        cube = p.loadURDF(os.path.join(pybullet_data.getDataPath(), "cube_small.urdf"), [0, 0, 0],
                          physicsClientId=cid)
        p.resetBaseVelocity(cube, [150, 0, 0], [0, 0, 0], physicsClientId=cid)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(3):
                ccd.step()
        said.append(sum(issubclass(w.category, BoxCCDWarning) for w in caught))
    assert said == [1, 1, 1]


# -------------------------------------------------------------------- layout
def test_named_columns_agree_with_the_core():
    core = _core.layouts()
    assert {k: slice(*v) for k, v in core["frame_state"].items()} == layout.FRAME_STATE
    assert {k: slice(*v) for k, v in core["path_row"].items()} == layout.PATH_ROW
    assert max(s.stop for s in layout.FRAME_STATE.values()) == layout.STATE_SIZE
    assert max(s.stop for s in layout.PATH_ROW.values()) == layout.ROW_SIZE


def test_a_force_applied_every_step_acts_once_a_step_through_quiet_steps_and_partial_steps(cid):
    """The user's external force, applied before every step, is given again to each
    partial step of the step it was applied in, and to no other: after many quiet steps
    (nothing fast) and then a step with an impact elsewhere, the pushed cube moves as
    pybullet moves it with no impact at all."""
    def run(shoot):
        reset(cid)
        wall = box(cid, [0.005, 1, 1], [5, 0, 0], mass=0)
        pushed = box(cid, [0.05] * 3, [0, 5, 0])
        bullet = box(cid, [0.05] * 3, [4, 0, 0])
        p.changeDynamics(wall, -1, restitution=1.0, physicsClientId=cid)
        p.changeDynamics(bullet, -1, restitution=1.0, physicsClientId=cid)
        ccd = BoxCCD(cid)
        for k in range(40):
            if k == 30 and shoot:
                p.resetBaseVelocity(bullet, [300, 0, 0], [0, 0, 0], physicsClientId=cid)
            p.applyExternalForce(pushed, -1, [2.0, 0, 0], [0, 5, 0], p.WORLD_FRAME, physicsClientId=cid)
            ccd.step()
        return np.array(p.getBaseVelocity(pushed, physicsClientId=cid)[0]), ccd.stats.partial_steps, \
            p.getBasePositionAndOrientation(bullet, physicsClientId=cid)[0][0]

    v_ref, partial_ref, _ = run(False)
    v, partial, x_bullet = run(True)
    assert partial_ref == 0 and partial >= 1 and x_bullet < 5  # the bullet struck the wall and came back
    assert np.allclose(v_ref, [2.0 * 40 * DT, 0, 0], rtol=1e-9)  # F t / m, pybullet alone
    np.testing.assert_allclose(v, v_ref, rtol=1e-6, atol=1e-9)


def test_a_moving_plane_meeting_a_box_made_static_in_flight_steps(cid):
    """A call sequence found by fuzzing pybullet's API: the plane of mjcf/hello_mjcf.xml given
    a velocity, boxes made in batches, and a box far out made static (mass 0) while it falls,
    so that two bodies BoxCCD moves kinematically meet. It steps on, with true warnings only
    (the spinning plane's velocity clamp)."""
    reset(cid, -9.81)
    box(cid, [5, 5, 0.005], [0, 0, -0.005], mass=0.0)
    box(cid, [0.004, 5, 2], [1.5, 0, 2], mass=0.0)
    plane = p.loadMJCF(os.path.join(pybullet_data.getDataPath(), "mjcf/hello_mjcf.xml"), physicsClientId=cid)[0]
    p.resetBaseVelocity(plane, [-72.7, -137.0, -106.6], [-210.8, 606.3, -67.3], physicsClientId=cid)
    ccd = BoxCCD(cid)
    ccd.step()
    for row in ([[0.92, 0.33, 0.5], [-0.84, 0.47, 0.7], [0.65, 0.32, 0.9]],
                [[0.30, -0.96, 0.5], [0.07, -0.33, 0.7], [-0.68, 0.28, 0.9]]):
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid)
        p.createMultiBody(1.0, col, batchPositions=row, physicsClientId=cid)
        for _ in range(2):
            ccd.step()
    box(cid, [0.00097, 0.00134, 0.00151], [0.58, -0.78, 0.92], mass=2.94,
        orn=[-0.55406, -0.00304, -0.06894, 0.82961])
    far = box(cid, [0.0435, 0.1252, 0.0210], [10000.5, 0.93, 1.86], mass=6.04,
              orn=[0.0638, 0.6072, 0.0456, 0.7907])
    for _ in range(8):
        ccd.step()
    p.changeDynamics(far, -1, mass=0.0, physicsClientId=cid)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        for _ in range(3):
            ccd.step()
    assert all("velocity clamp" in str(w.message) for w in said), [str(w.message) for w in said]


def test_boxes_made_in_a_batch_after_a_removal_are_known_by_their_true_ids(tmp_path):
    """pybullet 3.2.x makes a batch's first bodies under ids removeBody freed but returns the
    ids below the batch's last, some of them other bodies'. Here it returns (2, 3, 4) where
    body 2 is mjcf/inverted_pendulum.xml's pendulum and the boxes are 1, 3 and 4: BoxCCD keeps
    the pendulum's record (pybullet's getCollisionShapeData on its links kills the process)
    and knows the boxes as made by the batch (no warning that they were made unseen). In a
    subprocess: plain pybullet's crash would take the test run with it."""
    script = """
import warnings
import bullet_boxccd
from bullet_boxccd import BoxCCD
import pybullet as p, pybullet_data
cid = p.connect(p.DIRECT)
p.createMultiBody(0, p.createCollisionShape(p.GEOM_BOX, halfExtents=[5, 5, 0.005]), basePosition=[0, 0, -0.005])
ids = p.loadMJCF(pybullet_data.getDataPath() + "/mjcf/inverted_pendulum.xml")
p.removeBody(ids[0])
made = p.createMultiBody(1.0, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3),
                         batchPositions=[[-0.5, -0.9, 0.5], [0.8, 0.2, 0.7], [0.7, 0.7, 0.9]])
with warnings.catch_warnings(record=True) as said:
    warnings.simplefilter("always")
    ccd = BoxCCD(cid)
    for _ in range(5):
        ccd.step()
print(ids, made, sorted(ccd.world.tables.frames_of), [str(w.message) for w in said])
"""
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[-1] == "(1, 2) (2, 3, 4) [0, 1, 3, 4] []", out.stdout  # (the pendulum has no box)


def test_removing_a_maximal_body_that_constraints_hold_is_named(tmp_path):
    """pybullet's removeBody frees a maximal-coordinate body but leaves in the world the
    constraints of its joints and the user's on it, which later steps read (a crash at
    exit in some runs). Removing r2d2 in maximal coordinates, and a
    maximal box that a fixed constraint holds, is named once each; removing a maximal box
    that nothing holds and the same r2d2 as a multibody is not. In a subprocess, which
    ends without tearing the world down."""
    script = """
import os, warnings
import bullet_boxccd
from bullet_boxccd import BoxCCD
import pybullet as p, pybullet_data
cid = p.connect(p.DIRECT)
cube = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.1] * 3)
held = p.createMultiBody(1, cube, basePosition=[0, 0, 1], useMaximalCoordinates=True)
other = p.createMultiBody(1, cube, basePosition=[1, 0, 1], useMaximalCoordinates=True)
alone = p.createMultiBody(1, cube, basePosition=[2, 0, 1], useMaximalCoordinates=True)
joint = p.createConstraint(held, -1, other, -1, p.JOINT_FIXED, [0, 0, 0], [0.5, 0, 0], [-0.5, 0, 0])
r2d2 = pybullet_data.getDataPath() + "/r2d2.urdf"
maximal = p.loadURDF(r2d2, [3, 0, 0.6], useMaximalCoordinates=True)
multibody = p.loadURDF(r2d2, [5, 0, 0.6])
ccd = BoxCCD(cid)
ccd.step()
for b in (held, alone, maximal, multibody):
    p.removeBody(b)
with warnings.catch_warnings(record=True) as said:
    warnings.simplefilter("always")
    ccd.refresh()
    ccd.refresh()
print([str(w.message).split(":")[0] for w in said], flush=True)
os._exit(0)
"""
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[-1] == str(["body 3 (in maximal coordinates, with links) was removed",
                                               "constraint 1 holds body 0 (in maximal coordinates), which was removed"
                                               ]), out.stdout
