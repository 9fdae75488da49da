"""The plugin benchmarks' scene: a settled pile, a thin wall, a ground, and seeded shots.

Shared by ``benchmarks/plugin.py``, ``benchmarks/tradeoff.py`` and ``boxccd sweep`` (so a
trial is the same wherever it runs; ``run_trial`` runs one). All dynamic boxes are 0.1 m cubes of mass 1; the
ground is a static box 2 cm thick with its top face at z = 0 (body 0), the wall a static
box 1 cm thick in the plane x = 0, y in [-1, 1], z in [0, 1.5] (body 1). The pile (N - 4
boxes in up to 5 layers) is settled by 200 plain steps and stands away from the shots;
the 4 projectiles are parked far away and placed by ``shots(seed)`` at each trial. This
module imports pybullet (it builds pybullet worlds); nothing in the solver or in
``validate`` imports it.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pybullet as p

__all__ = ["DT", "HALF", "G", "N_PROJ", "WALL_HALF", "GROUND_HALF", "NATIVE_RADIUS", "GROUND", "WALL", "build",
           "shots", "centre", "crosses_wall", "below_ground", "min_dist", "run_trial", "close"]

DT = 1.0 / 240.0
HALF = 0.05  # half extent of every dynamic cube
G = 9.81
N_PROJ = 4
WALL_HALF = (0.005, 1.0, 0.75)  # 1 cm thick, wall plane x = 0
GROUND_HALF = (60.0, 60.0, 0.01)  # 2 cm thick, top at z = 0
NATIVE_RADIUS = 0.5 * HALF  # Bullet's swept sphere for native CCD: half the smallest half extent
GROUND, WALL = 0, 1  # body ids (created first)


def _box(cid, half, pos, mass, maximal):
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid)
    b = p.createMultiBody(mass, col, -1, basePosition=pos, useMaximalCoordinates=maximal, physicsClientId=cid)
    if mass > 0:
        p.changeDynamics(b, -1, linearDamping=0.0, angularDamping=0.0, maxJointVelocity=10000.0,
                         physicsClientId=cid)
    return b


def build(n_boxes, maximal, settle_steps=200):
    """A settled scene in a new DIRECT client; returns (cid, state id, projectile ids, pile ids)."""
    cid = p.connect(p.DIRECT)
    p.setGravity(0, 0, -G, physicsClientId=cid)
    p.setPhysicsEngineParameter(fixedTimeStep=DT, numSubSteps=0, physicsClientId=cid)
    _box(cid, GROUND_HALF, (0, 0, -GROUND_HALF[2]), 0.0, maximal)
    _box(cid, WALL_HALF, (0, 0, WALL_HALF[2]), 0.0, maximal)
    n_pile = n_boxes - N_PROJ
    layers = min(5, n_pile)
    per_layer = math.ceil(n_pile / layers)
    side = math.ceil(math.sqrt(per_layer))
    pitch = 2 * HALF + 0.002
    pile = []
    for i in range(n_pile):
        layer, r = divmod(i, per_layer)
        ix, iy = divmod(r, side)
        pile.append(_box(cid, [HALF] * 3, (-2.0 - ix * pitch, 2.0 + iy * pitch, HALF + layer * (2 * HALF + 1e-4)),
                         1.0, maximal))
    for _ in range(settle_steps):
        p.stepSimulation(physicsClientId=cid)
    # Projectiles parked high above the far corner (repositioned at every trial).
    proj = [_box(cid, [HALF] * 3, (40.0 + 2 * k, 40.0, 30.0), 1.0, maximal) for k in range(N_PROJ)]
    return cid, p.saveState(physicsClientId=cid), proj, pile


def shots(seed):
    """Seeded start poses and velocities of the projectiles: list of (pos, quat, v, w, kind).

    2 at the wall (50..150 m/s within 20 degrees of +x, reaching it at a seeded step 8..60,
    gravity compensated; one that would start below the ground comes down at the wall
    instead), 2 down at the empty ground (within 30 degrees of vertical); spins U(-20, 20)
    rad/s per component."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(N_PROJ):
        speed = rng.uniform(50.0, 150.0)
        t_hit = rng.integers(8, 61) * DT + rng.uniform(0, DT)
        if k < 2:  # at the wall, from the -x side
            aim = np.array([-WALL_HALF[0] - HALF, rng.uniform(-0.7, 0.7), rng.uniform(0.3, 1.2)])
            theta, phi = np.radians(rng.uniform(0, 20)), rng.uniform(0, 2 * np.pi)
            d = np.array([np.cos(theta), np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi)])
            kind = "wall"
            if aim[2] - speed * d[2] * t_hit + 0.5 * G * t_hit**2 < 0.3:
                d[2] = -d[2]  # it would start under the ground: come down onto the wall instead
        else:  # down at the empty ground
            aim = np.array([rng.uniform(-4.0, -1.0), rng.uniform(-3.0, -1.0), HALF])
            theta, phi = np.radians(rng.uniform(0, 30)), rng.uniform(0, 2 * np.pi)
            d = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), -np.cos(theta)])
            kind = "ground"
        v = speed * d
        pos = aim - v * t_hit + np.array([0, 0, 0.5 * G * t_hit**2])
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        w = rng.uniform(-20.0, 20.0, 3)
        out.append((pos, q, v, w, kind))
    return out


def centre(cid, b):
    return np.array(p.getBasePositionAndOrientation(b, physicsClientId=cid)[0])


def crosses_wall(c0, c1):
    """The centre went from x < 0 to x >= 0 in a step through the wall's face (not over or round it)."""
    if not (c0[0] < 0.0 <= c1[0]):
        return False
    s = -c0[0] / (c1[0] - c0[0])
    y, z = c0[1:] + s * (c1[1:] - c0[1:])
    return abs(y) <= WALL_HALF[1] and 0.0 <= z <= 2 * WALL_HALF[2]


def below_ground(c):
    return c[2] < 0.0 and abs(c[0]) < GROUND_HALF[0] and abs(c[1]) < GROUND_HALF[1]


# ---------------------------------------------------------------- one trial
def min_dist(cid, a, b, dist, la=-1, lb=-1):
    pts = p.getClosestPoints(a, b, dist, linkIndexA=la, linkIndexB=lb, physicsClientId=cid)
    return min((c[8] for c in pts), default=None)


def run_trial(world, cfg, seed, window, ccd, checks=True):
    """One trial of one configuration on a built world (cid, state, projectiles, pile).

    ``cfg`` is (name, kind, arg): kind "plain" with arg substeps, "ccd"/"ref" (stepped by
    ``ccd``), "maximal" or "native" (native CCD set on the projectiles). Returns the mean
    us per step, the tunneled projectiles [(index, aimed at, final centre)] and, with
    ``checks``, the untimed checks (``first``, ``pose``, ``deepest``: see
    ``tradeoff.grid``); without them (``benchmarks/plugin.py``) those stay empty."""
    name, kind, arg = cfg
    cid, state, proj, _ = world
    p.restoreState(state, physicsClientId=cid)
    p.setPhysicsEngineParameter(fixedTimeStep=DT, numSubSteps=arg if kind == "plain" else 0, physicsClientId=cid)
    sh = shots(seed)
    for b, (pos, q, v, w, _) in zip(proj, sh):
        p.resetBasePositionAndOrientation(b, pos.tolist(), q.tolist(), physicsClientId=cid)
        p.resetBaseVelocity(b, v.tolist(), w.tolist(), physicsClientId=cid)
        if kind == "native":
            p.changeDynamics(b, -1, ccdSweptSphereRadius=NATIVE_RADIUS, contactProcessingThreshold=0.0,
                             physicsClientId=cid)
    if ccd is not None:
        step = ccd.step
    else:
        def step():
            p.stepSimulation(physicsClientId=cid)
            return ()
    index = {b: i for i, b in enumerate(proj)}
    total, first, pose, deepest = 0.0, {}, [], math.inf
    prev = [centre(cid, b) for b in proj]
    through_wall = [False] * len(proj)
    for s in range(window):
        t0 = time.perf_counter()
        events = step()
        total += time.perf_counter() - t0
        # untimed from here
        for ev in events if checks else ():
            if ev.initial:
                continue
            pair = {ev.body_a, ev.body_b}
            moving = [index[b] for b in pair if b in index]
            if not pair & {GROUND, WALL} or len(moving) != 1:
                continue
            i = moving[0]
            if i not in first:
                first[i] = s * DT + ev.time
            if ev.rewound and ccd is not None and ccd.max_partial_steps == 0:  # the step ends at the contact
                d = min_dist(cid, ev.body_a, ev.body_b, 0.01, ev.link_a, ev.link_b)
                pose.append(0.01 if d is None else d)  # nothing within 1 cm: at least 1 cm off
        for i, b in enumerate(proj):
            c = centre(cid, b)
            through_wall[i] |= crosses_wall(prev[i], c)
            prev[i] = c
            for st in (GROUND, WALL) if checks else ():
                d = min_dist(cid, b, st, 0.0)
                if d is not None:
                    deepest = min(deepest, d)
    tunnel = [(i, sh[i][4], [float(x) for x in c]) for i, c in enumerate(prev)
              if (through_wall[i] and c[0] > 0.0) or below_ground(c)]
    return dict(us=1e6 * total / window, tunnel=tunnel, first=first, pose=pose, deepest=deepest)


def close(world):
    """Disconnect a world ``build`` made."""
    p.disconnect(world[0])
