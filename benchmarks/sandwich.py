"""A thin light plate struck while resting just in front of a heavy cube.

What it measures
----------------
A 10 kg, 0.2 m cube at V m/s along +x strikes a 10 g plate (0.4 m square, 1 or 2 mm
thick) resting 0.5 mm in front of a second 10 kg cube; restitution 0, no gravity, no
damping. Only the three bodies' contacts act on them, so their momentum along x stays
10 V kg m/s, and the impact being inelastic, their kinetic energy can only fall. After
12 steps of 1/240 s: the total momentum and kinetic energy, and each body's velocity
along x, for plain pybullet, BoxCCD, and pybullet at steps 64 and 256 times finer (the
converged engine).

A light body pressed between two heavy ones is where a partial step's impulses are most
tightly coupled: the plate's impact with the first cube and its push on the second are
one solve, and the world going back within it must keep that solve's impulses alike on
every body it pushed (``contacts._Solve``), or the three leave with momentum no force
gave them.

Run
---
    python benchmarks/sandwich.py        # about 2 s
"""

from __future__ import annotations

import pybullet as p

from bullet_boxccd import BoxCCD

DT = 1 / 240
STEPS = 12


def run(method, speed, half_thickness, K=1):
    """(momentum along x, kinetic energy, [each body's velocity along x]) after STEPS steps of DT."""
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, 0, physicsClientId=cid)
        p.setTimeStep(DT / K, physicsClientId=cid)

        def body(mass, half, x):
            shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid)
            b = p.createMultiBody(mass, shape, basePosition=[x, 0, 1], physicsClientId=cid)
            p.changeDynamics(b, -1, restitution=0.0, maxJointVelocity=10000, linearDamping=0, angularDamping=0,
                             physicsClientId=cid)
            return b, mass

        bodies = [body(10.0, [0.1] * 3, -0.6), body(0.01, [half_thickness, 0.2, 0.2], 0.0),
                  body(10.0, [0.1] * 3, 0.1 + half_thickness + 0.0005)]
        p.resetBaseVelocity(bodies[0][0], [speed, 0, 0], physicsClientId=cid)
        step = BoxCCD(cid).step if method == "boxccd" else lambda: p.stepSimulation(physicsClientId=cid)
        for _ in range(STEPS * K):
            step()
        vx = [p.getBaseVelocity(b, physicsClientId=cid)[0] for b, _ in bodies]
        momentum = sum(m * v[0] for (_, m), v in zip(bodies, vx))
        energy = sum(0.5 * m * sum(c * c for c in v) for (_, m), v in zip(bodies, vx))
        return momentum, energy, [v[0] for v in vx]
    finally:
        p.disconnect(cid)


def main():
    print(f"10 kg cube -> 10 g plate 0.5 mm in front of a 10 kg cube; restitution 0; {STEPS} steps of 1/240 s\n")
    print("| speed, plate | method | momentum / initial | kinetic energy / initial | vx: cube, plate, cube (m/s) |")
    print("|---|---|---|---|---|")
    for speed, half in ((50.0, 0.001), (100.0, 0.0005), (300.0, 0.0005)):
        for name, method, K in (("plain", "plain", 1), ("BoxCCD", "boxccd", 1), ("plain, dt/64", "plain", 64),
                                ("plain, dt/256", "plain", 256)):
            momentum, energy, vx = run(method, speed, half, K)
            print(f"| {speed:.0f} m/s, {2000 * half:.0f} mm | {name} | {momentum / (10 * speed):.2f} | "
                  f"{energy / (5 * speed * speed):.2f} | {', '.join(f'{v:.1f}' for v in vx)} |")


if __name__ == "__main__":
    main()
