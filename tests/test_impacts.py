"""Impacts that look right (issue 12): against plain pybullet, a fine-step pybullet
reference and the laws an impact must keep. A restitution-0 cube thrown down at a
table stays down; restitution 1 and 0.5 against a thin wall never gain energy and
rebound within restitution; a puck sliding and a die tumbling on a box ground follow
plain pybullet exactly (nothing of theirs can tunnel, so the plugin must change
nothing), and so stay as close to the fine-step reference as plain pybullet is."""

from __future__ import annotations

import os

import numpy as np
import pybullet as p
import pybullet_data
import pytest

from bullet_boxccd import BoxCCD

DT = 1 / 240
DATA = pybullet_data.getDataPath()


def reset(cid, gravity, dt=DT):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(dt, physicsClientId=cid)
    p.setGravity(0, 0, gravity, physicsClientId=cid)


def stepper(cid, use):
    ccd = BoxCCD(cid) if use else None
    return ccd, (ccd.step if ccd else (lambda: p.stepSimulation(physicsClientId=cid)))


# --------------------------------------------------------- restitution 0
def table_throw(cid, seed, use):
    """pybullet_data's cube_small thrown down at table/table.urdf at 80-200 m/s with a
    spin up to 20 rad/s about each axis. Returns (the fastest rise while over the top
    after the impact, whether the centre crossed the top's mid-plane inside its outline)."""
    reset(cid, -9.81)
    rng = np.random.default_rng(seed)
    table = p.loadURDF(os.path.join(DATA, "table/table.urdf"), [0, 0, 0], physicsClientId=cid)
    (x0, y0, z0), (x1, y1, z1) = p.getAABB(table, -1, physicsClientId=cid)
    mid = 0.5 * (z0 + z1)
    cube = p.loadURDF(os.path.join(DATA, "cube_small.urdf"), [rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), z1 + 0.5],
                      physicsClientId=cid)
    p.changeDynamics(cube, -1, maxJointVelocity=10000, physicsClientId=cid)
    p.resetBaseVelocity(cube, [0, 0, -rng.uniform(80, 200)], rng.uniform(-20, 20, 3).tolist(), physicsClientId=cid)
    _, step = stepper(cid, use)
    rise, through, hit = 0.0, False, False
    prev = np.array(p.getBasePositionAndOrientation(cube, physicsClientId=cid)[0])
    for _ in range(120):
        step()
        pos = np.array(p.getBasePositionAndOrientation(cube, physicsClientId=cid)[0])
        if prev[2] > mid >= pos[2]:
            c = prev + (pos - prev) * (prev[2] - mid) / (prev[2] - pos[2])
            through |= bool(x0 < c[0] < x1 and y0 < c[1] < y1)
        hit |= bool(pos[2] < z1 + 0.1)
        if hit and x0 < pos[0] < x1 and y0 < pos[1] < y1:
            rise = max(rise, p.getBaseVelocity(cube, physicsClientId=cid)[0][2])
        prev = pos
    return rise, through


def test_restitution_zero_table_throw_stays_down(cid):
    plain = [table_throw(cid, s, False) for s in range(12)]
    plugin = [table_throw(cid, s, True) for s in range(12)]
    assert sum(t for _, t in plain) >= 6  # the scene is one plain pybullet fails
    assert not any(t for _, t in plugin)
    assert max(r for r, _ in plugin) <= 1.5


# ---------------------------------------------------- restitution 1 and 0.5
def wall_strike(cid, seed, e, use):
    """A 0.1 m cube at 20-300 m/s with a spin up to 20 rad/s about each axis at a wall
    1 cm thick, both of restitution e. Returns (the largest kinetic energy over the
    launch's, the rebound's speed over the approach's, whether it got through)."""
    reset(cid, 0.0)
    rng = np.random.default_rng(seed)
    wall = p.createMultiBody(0, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.005, 1, 1], physicsClientId=cid),
                             physicsClientId=cid)
    p.changeDynamics(wall, -1, restitution=e, physicsClientId=cid)
    cube = p.createMultiBody(1, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid),
                             basePosition=[-0.3 - 0.5 * rng.uniform(), rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3)],
                             baseOrientation=p.getQuaternionFromEuler(rng.uniform(-0.5, 0.5, 3)), physicsClientId=cid)
    p.changeDynamics(cube, -1, restitution=e, linearDamping=0, angularDamping=0, maxJointVelocity=10000,
                     physicsClientId=cid)
    speed, spin = rng.uniform(20, 300), rng.uniform(-20, 20, 3)
    p.resetBaseVelocity(cube, [speed, 0, 0], spin.tolist(), physicsClientId=cid)
    inertia = np.array(p.getDynamicsInfo(cube, -1, physicsClientId=cid)[2])

    def energy():
        v, w = p.getBaseVelocity(cube, physicsClientId=cid)
        return 0.5 * np.dot(v, v) + 0.5 * np.dot(inertia, np.square(w))

    launch = 0.5 * speed ** 2 + 0.5 * np.dot(inertia, spin ** 2)
    _, step = stepper(cid, use)
    most, through = 0.0, False
    for _ in range(int(1.0 / (speed * DT)) + 40):
        step()
        most = max(most, energy())
        through |= p.getBasePositionAndOrientation(cube, physicsClientId=cid)[0][0] > 0.0
    return most / launch, -p.getBaseVelocity(cube, physicsClientId=cid)[0][0] / speed, through


@pytest.mark.parametrize("e", [1.0, 0.5])
def test_thin_wall_impacts_keep_energy_and_restitution(cid, e):
    plain = [wall_strike(cid, s, e, False) for s in range(16)]
    plugin = [wall_strike(cid, s, e, True) for s in range(16)]
    assert sum(t for _, _, t in plain) >= 8
    assert not any(t for _, _, t in plugin)
    assert max(k for k, _, _ in plugin) <= 1.0 + 1e-9  # never above launch
    rebound = [r for _, r, _ in plugin]
    assert min(rebound) > 0.0  # every cube comes back ...
    assert max(rebound) <= e  # ... no faster than restitution allows (spin gives some to rotation)


# ---------------------------------------------------------- do no harm
def ground_scene(cid, kind, seed, ground, mode):
    """A puck sliding at 10 m/s or a die tumbling at 5-15 m/s and 20-60 rad/s on a box
    ground or plane.urdf for one second; mode "plain", "plugin" or "reference" (plain
    pybullet at 12 kHz). Returns the (240, 3) centre positions and the BoxCCD."""
    fine = 50 if mode == "reference" else 1
    reset(cid, -9.81, DT / fine)
    if ground == "plane":
        p.loadURDF(os.path.join(DATA, "plane.urdf"), physicsClientId=cid)
    else:
        p.createMultiBody(0, p.createCollisionShape(p.GEOM_BOX, halfExtents=[50, 50, 0.05], physicsClientId=cid),
                          basePosition=[0, 0, -0.05], physicsClientId=cid)
    rng = np.random.default_rng(seed)
    if kind == "slide":
        b = p.createMultiBody(1, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05, 0.05, 0.02],
                                                        physicsClientId=cid), basePosition=[0, 0, 0.02],
                              physicsClientId=cid)
        p.changeDynamics(b, -1, lateralFriction=0.3, physicsClientId=cid)
        for _ in range(5 * fine):  # settle
            p.stepSimulation(physicsClientId=cid)
        p.resetBaseVelocity(b, [10, rng.uniform(-1, 1), 0], [0, 0, 0], physicsClientId=cid)
    else:
        orn = p.getQuaternionFromEuler(rng.uniform(-3, 3, 3))
        b = p.createMultiBody(0.01, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.008] * 3, physicsClientId=cid),
                              basePosition=[0, 0, 0.05], baseOrientation=orn, physicsClientId=cid)
        v = rng.uniform(5, 15) * np.array([1, rng.uniform(-0.3, 0.3), -0.2])
        p.resetBaseVelocity(b, v.tolist(), rng.uniform(-60, 60, 3).tolist(), physicsClientId=cid)
    p.changeDynamics(b, -1, maxJointVelocity=1000, physicsClientId=cid)
    ccd, step = stepper(cid, mode == "plugin")
    path = []
    for _ in range(240):
        for _ in range(fine):
            step()
        path.append(p.getBasePositionAndOrientation(b, physicsClientId=cid)[0])
    return np.array(path), ccd


@pytest.mark.parametrize("ground", ["box", "plane"])
@pytest.mark.parametrize("kind", ["slide", "tumble"])
def test_sliding_and_tumbling_follow_plain_pybullet(cid, kind, ground):
    for seed in range(4):
        plain, _ = ground_scene(cid, kind, seed, ground, "plain")
        plugin, ccd = ground_scene(cid, kind, seed, ground, "plugin")
        reference, _ = ground_scene(cid, kind, seed, ground, "reference")
        assert ccd.stats.swept_boxes >= 100  # fast enough to be swept: the plugin looked at every step
        assert np.abs(plugin - plain).max() <= 1e-9
        assert ccd.stats.rewinds == 0
        off_plain = np.linalg.norm(plain - reference, axis=1).max()
        off_plugin = np.linalg.norm(plugin - reference, axis=1).max()
        assert off_plugin <= off_plain + 1e-9 and off_plain < 0.2


# ------------------------------------------------- a spinning box's next corners
def corner_throw(cid, seed):
    """A 0.2 m cube thrown at a 2 cm box ground at 100 m/s down and up to 40 m/s across,
    turned at random, spinning up to 15 rad/s. Returns (the deepest end-of-step penetration
    into the ground over 40 steps, the collisions the plugin resolved)."""
    reset(cid, -9.81)
    ground = p.createMultiBody(0, p.createCollisionShape(p.GEOM_BOX, halfExtents=[20, 20, 0.01], physicsClientId=cid),
                               basePosition=[0, 0, -0.01], physicsClientId=cid)
    rng = np.random.default_rng(seed)
    q = rng.normal(size=4)
    cube = p.createMultiBody(1, p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.1] * 3, physicsClientId=cid),
                             basePosition=[0, 0, 1.0], baseOrientation=(q / np.linalg.norm(q)).tolist(),
                             physicsClientId=cid)
    p.changeDynamics(cube, -1, maxJointVelocity=10000, physicsClientId=cid)
    p.resetBaseVelocity(cube, [rng.uniform(-40, 40), rng.uniform(-40, 40), -100], rng.uniform(-15, 15, 3).tolist(),
                        physicsClientId=cid)
    ccd = BoxCCD(cid)
    deepest = 0.0
    for _ in range(40):
        ccd.step()
        for c in p.getClosestPoints(cube, ground, 0.0, physicsClientId=cid):
            deepest = min(deepest, c[8])
    return -deepest, ccd.stats.held


@pytest.mark.parametrize("seed", [1, 3, 10, 11, 13, 16])
def test_the_next_corner_of_a_resolved_impact_is_a_collision_too(cid, seed):
    """When the plugin resolves an impact as a collision, the spin it leaves can bring
    another corner down within the same step: that strike is resolved too, not left to
    end the step centimetres inside (as it did on these seeds: 2 to 7 cm) because
    pybullet would push it back out the right way."""
    depth, held = corner_throw(cid, seed)
    assert held >= 1 and depth < 0.005, (depth, held)
