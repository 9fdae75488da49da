"""A cube sliding fast along a floor into a wall: a face striking nearly flat, and how
much its tilt before the impact decides the rebound.

What it measures
----------------
A 0.1 m cube (1 kg, restitution 0.6, friction 0.5) resting on a static box floor
(restitution 0, friction 0.5) slides along +x at 30 to 150 m/s into a static wall 1 cm
thick (restitution 1, friction 0.5), gravity on, no damping, velocity clamp lifted to
1e4, at 240 Hz; its front reaches the wall
3.5 steps in. Per speed, the cube's velocity (vx, vz) and spin 0.05 s after the impact,
and its pitch (rad) just before the impact step:

* ``plain``: ``p.stepSimulation()`` at 240 Hz (the cube passes through);
* ``BoxCCD``: ``BoxCCD(cid).step()`` at 240 Hz;
* ``fine xK``: plain pybullet at a step K times finer from the start;
* ``tipped, fine xK``: plain pybullet at 240 Hz up to the impact step (the state plain
  pybullet and BoxCCD both reach: BoxCCD leaves the slide to pybullet), then K times finer.

At 240 Hz pybullet's floor contact tips the sliding cube by about 2 mrad, a fine step
does not: the face then strikes with one edge first. BoxCCD resolves that impact as
pybullet at a fine step does from the same tipped start (spinning, thrown up), not as
the scene stepped fine from the beginning (straight back) (README, known limits).

Run
---
    python benchmarks/sliding_face.py      # about 10 s
"""

from __future__ import annotations

import math

import numpy as np
import pybullet as p

from bullet_boxccd import BoxCCD

DT = 1.0 / 240.0
HIT = 3.5  # steps until the front reaches the wall
AFTER = 0.05  # s run after the impact


def _box(cid, half, pos, mass, restitution):
    shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid)
    body = p.createMultiBody(mass, shape, basePosition=pos, physicsClientId=cid)
    p.changeDynamics(body, -1, restitution=restitution, lateralFriction=0.5, linearDamping=0, angularDamping=0,
                     maxJointVelocity=1e4, physicsClientId=cid)
    return body


def run(speed, method, K=1):
    """(vx, vz, spin, pitch before the impact step) of the cube."""
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        p.setTimeStep(DT, physicsClientId=cid)
        _box(cid, (20, 2, 0.05), (0, 0, -0.05), 0.0, 0.0)
        _box(cid, (0.005, 1.0, 0.15), (0.005, 0, 0.15), 0.0, 1.0)
        cube = _box(cid, (0.05,) * 3, (-0.05 - speed * HIT * DT, 0, 0.05), 1.0, 0.6)
        p.resetBaseVelocity(cube, (speed, 0, 0), (0, 0, 0), physicsClientId=cid)
        before = int(HIT)  # coarse steps before the impact step
        steps = before + int(math.ceil(AFTER / DT)) + 1
        ccd = BoxCCD(cid) if method == "BoxCCD" else None
        if method == "fine":
            p.setTimeStep(DT / K, physicsClientId=cid)
        pitch = 0.0
        for k in range(steps):
            if k == before:
                pitch = p.getEulerFromQuaternion(p.getBasePositionAndOrientation(cube, physicsClientId=cid)[1])[1]
                if method == "tipped":
                    p.setTimeStep(DT / K, physicsClientId=cid)
            if ccd is not None:
                ccd.step()
            else:
                for _ in range(K if method == "fine" or (method == "tipped" and k >= before) else 1):
                    p.stepSimulation(physicsClientId=cid)
        v, w = p.getBaseVelocity(cube, physicsClientId=cid)
        return v[0], v[2], float(np.linalg.norm(w)), pitch
    finally:
        p.disconnect(cid)


def main():
    methods = [("plain", "plain", 1), ("BoxCCD", "BoxCCD", 1), ("fine x128", "fine", 128),
               ("fine x1024", "fine", 1024), ("tipped, fine x128", "tipped", 128),
               ("tipped, fine x1024", "tipped", 1024), ("tipped, fine x8192", "tipped", 8192)]
    head = ["speed (m/s)"] + [name for name, _, _ in methods]
    print("cube's (vx, vz) m/s and spin rad/s 0.05 s after the impact; its pitch before the impact step (mrad)")
    print("| " + " | ".join(head) + " |\n|" + "|".join("---" for _ in head) + "|")
    for speed in (30.0, 50.0, 100.0, 150.0):
        row = [f"{speed:g}"]
        for _, method, K in methods:
            vx, vz, spin, pitch = run(speed, method, K)
            row.append(f"({vx:+.1f}, {vz:+.1f}), {spin:.0f}; {1e3 * pitch:+.2f}")
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
