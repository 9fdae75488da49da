"""Two 0.1 m cubes fired at each other at 200 m/s, head-on and crossing at an angle,
over 24 start phases at 240 Hz (restitution 1, no gravity).

Plain pybullet lets them pass through each other; with BoxCCD they collide, and
their total momentum is conserved.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pybullet as p

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import box_body, demo_setup, print_table, simulate  # noqa: E402

from bullet_boxccd import BoxCCD  # noqa: E402

SPEED = 200.0


def run(cid, use_ccd, phase, angle, picture=None):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(1 / 240, physicsClientId=cid)
    d = np.array([np.cos(angle), np.sin(angle), 0.0])
    gap = 1.0 + phase * 2 * SPEED / 240
    a = box_body(cid, [0.05] * 3, [-gap / 2, 0, 0], restitution=1.0)
    b = box_body(cid, [0.05] * 3, (gap / 2 * d).tolist(), restitution=1.0, color=(0.2, 0.4, 0.8, 1), mass=2.0)
    p.resetBaseVelocity(a, [SPEED, 0, 0], [0, 0, 0], physicsClientId=cid)
    p.resetBaseVelocity(b, (-SPEED * d).tolist(), [0, 0, 0], physicsClientId=cid)
    momentum0 = 1.0 * np.array([SPEED, 0, 0]) + 2.0 * (-SPEED * d)
    ccd = BoxCCD(cid) if use_ccd else None
    contacts, timer = simulate(cid, ccd, int(gap / SPEED * 240) + 10, picture, ([0, 0, 0], 0.8, 0, -60))
    va = np.array(p.getBaseVelocity(a, physicsClientId=cid)[0])
    vb = np.array(p.getBaseVelocity(b, physicsClientId=cid)[0])
    momentum = 1.0 * va + 2.0 * vb
    through = np.allclose(va, [SPEED, 0, 0]) and np.allclose(vb, -SPEED * d)  # never interacted
    return through, contacts, timer, np.linalg.norm(momentum - momentum0) / np.linalg.norm([SPEED, 0, 0])


def main(argv=None):
    args, cid = demo_setup(__doc__, argv, phases=24)
    rows, result = [], {}
    for angle in (0.0, np.radians(30)):
        for use in (False, True):
            out = [run(cid, use, k / args.phases, angle,
                       os.path.join(args.out, "two_bullets.png") if use and k == 0 and angle == 0 else None)
                   for k in range(args.phases)]
            result[(angle, use)] = (sum(o[0] for o in out), max(o[3] for o in out))
            rows.append((f"{np.degrees(angle):.0f} deg", "BoxCCD" if use else "plain pybullet",
                         f"{result[(angle, use)][0]}/{args.phases}", sum(o[1] for o in out),
                         f"{100 * result[(angle, use)][1]:.2f}%", f"{np.median([o[2].us_per_step for o in out]):.0f}"))
    print_table("two bullets: 0.1 m cubes at 200 m/s each, 240 Hz", (
        "approach", "run", "passed through", "CCD contacts", "momentum error (max)", "us/step (median)"), rows)
    for angle in (0.0, np.radians(30)):
        assert result[(angle, True)][0] == 0, "BoxCCD let the cubes pass through each other"
        assert result[(angle, True)][1] < 0.01, "momentum not conserved to 1%"
    assert result[(0.0, False)][0] > 0, "plain pybullet never tunneled"
    p.disconnect(cid)


if __name__ == "__main__":
    main()
