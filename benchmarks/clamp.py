"""A fast box driven into a box held at pybullet's default velocity clamp.

What it measures
----------------
A 1 kg, 0.1 m cube (its clamp lifted) at 200 m/s along +x strikes pybullet_data's
jenga block (50 g, 5 cm thick along x), which keeps pybullet's default clamp of
100 m/s: no solve can send the block away faster than the cube, so the contact is
one pybullet's solver cannot resolve in a step. For plain pybullet at 1/240 s and at
steps 256 and 2,048 times finer (the converged engine), and for BoxCCD at 1/240 s:
the cube's and the block's speed after 0.05 s, and the first step (of 1/240 s) at
which the cube's back face is past the block's front face (through).

It is the README's known limit on the velocity clamp: BoxCCD holds the pair at its
contact, and its few solves a step (each kept: the clamp cut it) slow the cube over
steps, where the converged engine's thousands slow it within a step.

Run
---
    python benchmarks/clamp.py        # about 2 s
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import pybullet as p
import pybullet_data

from bullet_boxccd import BoxCCD
from bullet_boxccd.pybullet_ccd import BoxCCDWarning

DT = 1 / 240
STEPS = 120


def run(method, K=1):
    """(cube speed, block speed) after 12 steps of DT, and the first step the cube is through (None)."""
    cid = p.connect(p.DIRECT)
    try:
        p.setTimeStep(DT / K, physicsClientId=cid)
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid)
        cube = p.createMultiBody(1.0, shape, basePosition=[-1, 0, 0.5], physicsClientId=cid)
        p.changeDynamics(cube, -1, maxJointVelocity=1000, linearDamping=0, angularDamping=0, physicsClientId=cid)
        p.resetBaseVelocity(cube, [200, 0, 0], physicsClientId=cid)
        block = p.loadURDF(os.path.join(pybullet_data.getDataPath(), "jenga/jenga.urdf"), [0, 0, 0.5],
                           p.getQuaternionFromEuler([0, 0, np.pi / 2]), physicsClientId=cid)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", BoxCCDWarning)  # the block at the clamp is named: known here
            step = BoxCCD(cid).step if method == "boxccd" else lambda: p.stepSimulation(physicsClientId=cid)
            speeds, through = None, None
            for k in range(STEPS):
                for _ in range(K):
                    step()
                xc = p.getBasePositionAndOrientation(cube, physicsClientId=cid)[0][0]
                xb = p.getBasePositionAndOrientation(block, physicsClientId=cid)[0][0]
                if through is None and xc - 0.05 > xb + 0.025:
                    through = k + 1
                if k == 11:
                    speeds = (p.getBaseVelocity(cube, physicsClientId=cid)[0][0],
                              p.getBaseVelocity(block, physicsClientId=cid)[0][0])
        return speeds, through
    finally:
        p.disconnect(cid)


def main():
    print(f"1 kg cube at 200 m/s into a 50 g jenga block at pybullet's 100 m/s clamp; {STEPS} steps of 1/240 s\n")
    print("| method | cube m/s after 0.05 s | block m/s | through at step |")
    print("|---|---|---|---|")
    for name, method, K in (("plain, 1/240 s", "plain", 1), ("plain, 1/61,440 s", "plain", 256),
                            ("plain, 1/491,520 s", "plain", 2048), ("BoxCCD, 1/240 s", "boxccd", 1)):
        (vc, vb), through = run(method, K)
        print(f"| {name} | {vc:.1f} | {vb:.1f} | {through if through else 'never'} |")


if __name__ == "__main__":
    main()
