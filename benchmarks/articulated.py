"""A known limit, measured: an articulated link swung through a thin static plate.

What it measures
----------------
A fixed-base arm with one revolute joint (axis z, its velocity motor switched off,
no damping) carries a box link: a 0.6 m bar, ``--thickness`` thick in the direction
it sweeps (default 1 cm) and 4 cm tall. A static plate ``--plate`` thick (default
2 mm, 0.2 m wide, 0.4 m tall) stands across its path, 0.35 to 0.55 m from the axis.
Per seed the joint starts 90 to 73 degrees before the plate at ``omega`` rad/s; a
run counts as passed through when the joint angle goes beyond the plate within 60
steps of 1/240 s.

The same runs with plain ``p.stepSimulation()`` and with ``BoxCCD.step()``, plus the
CCD events the plugin reported. BoxCCD sweeps articulated links and reports their
contacts, but rewinds only free single-body boxes: a link that meets a static body
is not stopped (README, Known limits). This script is the evidence for that limit;
it asserts nothing.

Run
---
    cd /work/main && PYTHONPATH=/work/main python3 benchmarks/articulated.py    # ~5 s
"""

from __future__ import annotations

import argparse

import numpy as np
import pybullet as p

from bullet_boxccd import BoxCCD

DT = 1 / 240


def run(cid: int, use_ccd: bool, omega: float, thickness: float, plate: float, seed: int):
    """(passed through, CCD events reported) for one swing."""
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
    events = 0
    for _ in range(60):
        if ccd:
            events += len(ccd.step())
        else:
            p.stepSimulation(physicsClientId=cid)
        if p.getJointState(arm, 0, physicsClientId=cid)[0] > 0.3:
            return True, events
    return False, events


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--thickness", type=float, default=0.01, help="bar thickness along its sweep (m)")
    ap.add_argument("--plate", type=float, default=0.002, help="plate thickness (m)")
    args = ap.parse_args()
    cid = p.connect(p.DIRECT)
    print(f"bar {args.thickness * 100:g} cm thick, static plate {args.plate * 1000:g} mm, {args.seeds} seeds")
    print("| omega (rad/s) | bar speed at the plate (m/s) | plain: passed through | BoxCCD: passed through "
          "| BoxCCD events |")
    print("|---|---|---|---|---|")
    for omega in (5.0, 10.0, 20.0, 50.0):
        plain = ccd = events = 0
        for seed in range(args.seeds):
            plain += run(cid, False, omega, args.thickness, args.plate, seed)[0]
            through, n = run(cid, True, omega, args.thickness, args.plate, seed)
            ccd += through
            events += n
        print(f"| {omega:g} | {0.35 * omega:.1f} to {0.55 * omega:.1f} | {plain}/{args.seeds} | {ccd}/{args.seeds} "
              f"| {events} |")
    p.disconnect(cid)


if __name__ == "__main__":
    main()
