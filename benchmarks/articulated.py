"""Articulated bodies: what the plugin prevents, and what it costs per step.

1. Pass-through. A fixed-base arm with one revolute joint (axis z, motor off, no
   damping) carries a 0.6 m bar, ``--thickness`` thick along its sweep (default 1 cm);
   a static plate ``--plate`` thick (default 2 mm) stands across its path, 0.35 to
   0.55 m from the axis. Per seed the joint starts 90 to 73 degrees before the plate
   at omega rad/s; a run passes through when the joint goes beyond the plate within
   60 steps of 1/240 s. Plain ``p.stepSimulation()`` against ``BoxCCD.step()``.

2. Cost. A 7-link box arm (revolute joints about z and y in turn, 0.15 m links of
   3 cm, velocity motors at ``--omega`` rad/s) swings on a fixed base through
   clutter: 60 free 2 cm cubes floating (no gravity) in its reach. Per step: CPU
   time of plain pybullet, of ``BoxCCD.step()``, and of plain pybullet with
   ``numSubSteps`` = 2, 4, 8, 16 (the usual remedy), each as a ratio to plain in the
   same run; and how many cubes the arm struck (moved by more than 1 cm: a cube a
   link passes through stays where it was). CPU time (process_time), the minimum
   of ``--repeats`` runs.

3. Resting. pybullet_data's r2d2 (15 links, 5 of them boxes) settled on plane.urdf:
   CPU time per step with and without the plugin, and what one state read of the
   robot costs right after a step (pybullet brings the whole body's state up to
   date for the first query: a cost any reader of the robot pays).

Run
---
    python benchmarks/articulated.py            # ~4 min
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pybullet as p
import pybullet_data

from bullet_boxccd import BoxCCD

DT = 1 / 240


def swing(cid: int, use_ccd: bool, omega: float, thickness: float, plate: float, seed: int) -> bool:
    """Whether the bar passed through the plate."""
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(DT, physicsClientId=cid)
    p.setGravity(0, 0, 0, physicsClientId=cid)
    base = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid)
    bar = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.3, thickness / 2, 0.02],
                                 collisionFramePosition=[0.3, 0, 0], physicsClientId=cid)
    arm = p.createMultiBody(0, base, linkMasses=[1.0], linkCollisionShapeIndices=[bar],
                            linkVisualShapeIndices=[-1], linkPositions=[[0, 0, 0]],
                            linkOrientations=[[0, 0, 0, 1]], linkInertialFramePositions=[[0.3, 0, 0]],
                            linkInertialFrameOrientations=[[0, 0, 0, 1]], linkParentIndices=[0],
                            linkJointTypes=[p.JOINT_REVOLUTE], linkJointAxis=[[0, 0, 1]], physicsClientId=cid)
    p.changeDynamics(arm, 0, linearDamping=0, angularDamping=0, maxJointVelocity=1000, physicsClientId=cid)
    p.setJointMotorControl2(arm, 0, p.VELOCITY_CONTROL, force=0, physicsClientId=cid)
    wall = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.1, plate / 2, 0.2], physicsClientId=cid)
    p.createMultiBody(0, wall, basePosition=[0.45, 0, 0], physicsClientId=cid)
    rng = np.random.default_rng(seed)
    p.resetJointState(arm, 0, -np.pi / 2 + rng.uniform(0, 0.3), omega, physicsClientId=cid)
    ccd = BoxCCD(cid) if use_ccd else None
    for _ in range(60):
        ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
        if p.getJointState(arm, 0, physicsClientId=cid)[0] > 0.3:
            return True
    return False


def clutter_world(cid: int, omega: float, seed: int, substeps: int = 0):
    """The 7-link arm and its clutter; returns the cubes."""
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(DT, physicsClientId=cid)
    p.setPhysicsEngineParameter(numSubSteps=substeps, physicsClientId=cid)
    p.setGravity(0, 0, 0, physicsClientId=cid)
    base = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05, 0.05, 0.1], physicsClientId=cid)
    link = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.075, 0.015, 0.015], collisionFramePosition=[0.075, 0, 0],
                                  physicsClientId=cid)
    n = 7
    arm = p.createMultiBody(0, base, basePosition=[0, 0, 0.1], linkMasses=[0.5] * n,
                            linkCollisionShapeIndices=[link] * n, linkVisualShapeIndices=[-1] * n,
                            linkPositions=[[0, 0, 0.1]] + [[0.15, 0, 0]] * (n - 1),
                            linkOrientations=[[0, 0, 0, 1]] * n, linkInertialFramePositions=[[0.075, 0, 0]] * n,
                            linkInertialFrameOrientations=[[0, 0, 0, 1]] * n, linkParentIndices=list(range(n)),
                            linkJointTypes=[p.JOINT_REVOLUTE] * n,
                            linkJointAxis=[[0, 0, 1] if k % 2 == 0 else [0, 1, 0] for k in range(n)],
                            physicsClientId=cid)
    rng = np.random.default_rng(seed)
    for k in range(n):
        p.changeDynamics(arm, k, maxJointVelocity=1000, physicsClientId=cid)
        w = omega if k == 0 else rng.uniform(-0.3, 0.3) * omega
        p.setJointMotorControl2(arm, k, p.VELOCITY_CONTROL, targetVelocity=w, force=500, physicsClientId=cid)
    cube = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.01] * 3, physicsClientId=cid)
    cubes = []
    for _ in range(60):
        r, a = rng.uniform(0.3, 1.0), rng.uniform(0, 2 * np.pi)
        cubes.append(p.createMultiBody(0.05, cube, basePosition=[r * np.cos(a), r * np.sin(a), rng.uniform(0, 0.4)],
                                       physicsClientId=cid))
        # pybullet clamps a multibody's speeds to 100 by default: a struck cube spinning
        # at that clamp cannot get out of a link's way.
        p.changeDynamics(cubes[-1], -1, maxJointVelocity=10000, physicsClientId=cid)
    return cubes


def _positions(cid, cubes):
    return np.array([p.getBasePositionAndOrientation(c, physicsClientId=cid)[0] for c in cubes])


def cost(cid: int, method, omega: float, steps: int, seed: int):
    """(CPU seconds per step, cubes struck) of one run."""
    substeps = method if isinstance(method, int) else 0
    cubes = clutter_world(cid, omega, seed, substeps)
    start = _positions(cid, cubes)
    ccd = BoxCCD(cid) if method == "plugin" else None
    t0 = time.process_time()
    for _ in range(steps):
        ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
    seconds = (time.process_time() - t0) / steps
    return seconds, int((np.linalg.norm(_positions(cid, cubes) - start, axis=1) > 0.01).sum())


def resting(cid: int, steps: int, repeats: int):
    """(plain, plugin, plain plus one base read) CPU seconds per step, resting r2d2."""
    def world():
        p.resetSimulation(physicsClientId=cid)
        p.setAdditionalSearchPath(pybullet_data.getDataPath())
        p.setGravity(0, 0, -9.8, physicsClientId=cid)
        p.setTimeStep(DT, physicsClientId=cid)
        p.loadURDF("plane.urdf", physicsClientId=cid)
        robot = p.loadURDF("r2d2.urdf", [0, 0, 0.5], physicsClientId=cid)
        for _ in range(240):
            p.stepSimulation(physicsClientId=cid)
        return robot

    def plain_read(robot):
        p.stepSimulation(physicsClientId=cid)
        p.getBasePositionAndOrientation(robot, physicsClientId=cid)

    best = [np.inf] * 3
    for _ in range(repeats):
        for k in range(3):
            robot = world()
            ccd = BoxCCD(cid) if k == 1 else None
            step = ccd.step if ccd else (lambda: p.stepSimulation(physicsClientId=cid)) if k == 0 else (
                lambda: plain_read(robot))
            t0 = time.process_time()
            for _ in range(steps):
                step()
            best[k] = min(best[k], (time.process_time() - t0) / steps)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--thickness", type=float, default=0.01, help="bar thickness along its sweep (m)")
    ap.add_argument("--plate", type=float, default=0.002, help="plate thickness (m)")
    ap.add_argument("--omega", type=float, default=40.0, help="the 7-link arm's first joint speed (rad/s)")
    ap.add_argument("--steps", type=int, default=240)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    cid = p.connect(p.DIRECT)
    print(f"1. bar {args.thickness * 100:g} cm thick, static plate {args.plate * 1000:g} mm, {args.seeds} seeds")
    print("| omega (rad/s) | bar speed at the plate (m/s) | plain: passed through | BoxCCD: passed through |")
    print("|---|---|---|---|")
    for omega in (5.0, 10.0, 20.0, 50.0):
        plain = sum(swing(cid, False, omega, args.thickness, args.plate, s) for s in range(args.seeds))
        ccd = sum(swing(cid, True, omega, args.thickness, args.plate, s) for s in range(args.seeds))
        print(f"| {omega:g} | {0.35 * omega:.1f} to {0.55 * omega:.1f} | {plain}/{args.seeds} | {ccd}/{args.seeds} |")
    print(f"\n2. 7-link box arm at {args.omega:g} rad/s through 60 cubes, {args.steps} steps, "
          f"min of {args.repeats} runs (CPU time)")
    print(f"| method | per step vs plain | cubes struck (seeds 0..{args.repeats - 1}) |")
    print("|---|---|---|")
    methods = ["plain", "plugin", 2, 4, 8, 16]
    best = {m: np.inf for m in methods}
    losses = {m: [] for m in methods}
    for r in range(args.repeats):
        for m in methods:  # interleaved: the machine's drift hits every method alike
            t, struck = cost(cid, m, args.omega, args.steps, seed=r)
            best[m] = min(best[m], t)
            losses[m].append(struck)
    for m in methods:
        name = m if isinstance(m, str) else f"plain, numSubSteps {m}"
        print(f"| {name} | {best[m] / best['plain']:.2f}x | {losses[m]} |")
    print(f"(plain: {1e6 * best['plain']:.0f} us a step here)")
    plain, plugin, read = resting(cid, 4 * args.steps, args.repeats)
    print(f"\n3. r2d2 resting on plane.urdf, {4 * args.steps} steps, min of {args.repeats} runs (CPU time)")
    print("| plugin, x plain | plain + one read of the robot, x plain | plugin's own share of a plain step |")
    print("|---|---|---|")
    print(f"| {plugin / plain:.2f} | {read / plain:.2f} | {(plugin - read) / plain:.2f} |")
    p.disconnect(cid)


if __name__ == "__main__":
    main()
