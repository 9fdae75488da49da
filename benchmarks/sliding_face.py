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
does not: the face then strikes with one edge first, and from that tipped start
pybullet's answer does not converge as its step is refined. BoxCCD resolves the strike
from the impact depth (1 mm here), where Bullet's box-box detector sees the whole tipped
face, and the cube comes straight back as in the scene stepped finely from the start.

A second table: the same at 50 m/s after longer slides (10.5 and 30.5 steps), with
friction 1 (every body), and at 60 Hz: the longer the slide and the higher the friction,
the more pybullet's coarse step tips the cube; a face tipped by more than the impact depth
across strikes on its near edge (README, known limits).

Run
---
    python benchmarks/sliding_face.py      # about 6 s
"""

from __future__ import annotations

import math

import numpy as np
import pybullet as p

from bullet_boxccd import BoxCCD

DT = 1.0 / 240.0
HIT = 3.5  # steps until the front reaches the wall
AFTER = 0.05  # s run after the impact


def _box(cid, half, pos, mass, restitution, friction):
    shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid)
    body = p.createMultiBody(mass, shape, basePosition=pos, physicsClientId=cid)
    p.changeDynamics(body, -1, restitution=restitution, lateralFriction=friction, linearDamping=0, angularDamping=0,
                     maxJointVelocity=1e4, physicsClientId=cid)
    return body


def run(speed, method, K=1, hit=HIT, friction=0.5, dt=DT):
    """(vx, vz, spin, pitch before the impact step) of the cube, its front reaching the wall
    ``hit`` steps of dt in."""
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        p.setTimeStep(dt, physicsClientId=cid)
        _box(cid, (100, 2, 0.05), (0, 0, -0.05), 0.0, 0.0, friction)
        _box(cid, (0.005, 1.0, 0.15), (0.005, 0, 0.15), 0.0, 1.0, friction)
        cube = _box(cid, (0.05,) * 3, (-0.05 - speed * hit * dt, 0, 0.05), 1.0, 0.6, friction)
        p.resetBaseVelocity(cube, (speed, 0, 0), (0, 0, 0), physicsClientId=cid)
        before = int(hit)  # coarse steps before the impact step
        steps = before + int(math.ceil(AFTER / dt)) + 1
        ccd = BoxCCD(cid) if method == "BoxCCD" else None
        if method == "fine":
            p.setTimeStep(dt / K, physicsClientId=cid)
        pitch = 0.0
        for k in range(steps):
            if k == before:
                pitch = p.getEulerFromQuaternion(p.getBasePositionAndOrientation(cube, physicsClientId=cid)[1])[1]
                if method == "tipped":
                    p.setTimeStep(dt / K, physicsClientId=cid)
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
    print("\nthe same at 50 m/s after longer slides: (vx, vz) m/s and spin rad/s 0.05 s after the impact; "
          "pitch before the impact step (mrad)")
    head = ["step", "friction", "steps sliding", "plain", "BoxCCD", "fine x128", "fine x256"]
    print("| " + " | ".join(head) + " |\n|" + "|".join("---" for _ in head) + "|")
    for dt, friction, hit in ((DT, 0.5, 3.5), (DT, 0.5, 10.5), (DT, 0.5, 30.5), (DT, 1.0, 10.5), (4 * DT, 0.5, 10.5),
                              (4 * DT, 0.5, 30.5)):
        row = [f"1/{round(1 / dt)} s", f"{friction:g}", f"{hit:g}"]
        for method, K in (("plain", 1), ("BoxCCD", 1), ("fine", 128), ("fine", 256)):
            vx, vz, spin, pitch = run(50.0, method, K, hit, friction, dt)
            row.append(f"({vx:+.1f}, {vz:+.1f}), {spin:.0f}; {1e3 * pitch:+.2f}")
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
