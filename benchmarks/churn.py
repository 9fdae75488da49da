"""Bodies made and removed between steps: what a world change costs.

What it measures
----------------
60 cubes resting on plane.urdf; before every step a cube is made (even steps) or one
removed (odd steps), as an RL task spawns and drops its projectiles (pybullet reuses the
removed ids). Nothing moves fast, so BoxCCD's work is reading the change: the body made
is read, and its tables are rebuilt. Mean time of a step (the body calls excluded), for
plain pybullet (its own stepSimulation, not the journaling one importing bullet_boxccd
installs) and for ``BoxCCD.step()``, each in its own client, over 2 runs of 1000
steps; the ratio is from the same run.

Run
---
    python benchmarks/churn.py      # about 10 s
"""

from __future__ import annotations

import random
import time

import pybullet as p
import pybullet_data

from bullet_boxccd import BoxCCD

STEPS = 1000
RESTING = 60


def run(use_boxccd):
    """Mean us a step of a world where a cube is made or removed before every step."""
    cid = p.connect(p.DIRECT)
    try:
        p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=cid)
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        p.loadURDF("plane.urdf", physicsClientId=cid)
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid)
        bodies = [p.createMultiBody(1, shape, basePosition=[i % 10 * 0.3, i // 10 * 0.3, 0.05],
                                    physicsClientId=cid) for i in range(RESTING)]
        raw = getattr(p, "_bullet_boxccd_originals", {}).get("stepSimulation", p.stepSimulation)  # (unjournaled)
        step = BoxCCD(cid).step if use_boxccd else (lambda: raw(physicsClientId=cid))
        rng, spent = random.Random(3), 0.0
        for k in range(STEPS):
            if k % 2 == 0:
                bodies.append(p.createMultiBody(1, shape, basePosition=[rng.uniform(-3, 0), rng.uniform(-3, 0), 0.05],
                                                physicsClientId=cid))
            else:
                p.removeBody(bodies.pop(rng.randrange(len(bodies))), physicsClientId=cid)
            t = time.perf_counter()
            step()
            spent += time.perf_counter() - t
        return 1e6 * spent / STEPS
    finally:
        p.disconnect(cid)


def main():
    print(f"{RESTING} resting cubes, a cube made or removed before every step; us a step")
    print("| run | plain pybullet | BoxCCD | ratio |\n|---|---|---|---|")
    for k in range(2):
        plain, boxccd = run(False), run(True)
        print(f"| {k + 1} | {plain:.0f} | {boxccd:.0f} | {boxccd / plain:.2f} |")


if __name__ == "__main__":
    main()
