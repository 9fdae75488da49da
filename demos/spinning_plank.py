"""A 1 x 0.02 x 0.2 m plank spinning at 200 rad/s about its centre, next to a static
0.1 m cube at radius 0.3 m and 0.45 m, over 40 start phases at 240 Hz.

The plank turns 0.83 rad a step, so plain pybullet sees it on one side of the
cube and then on the other; pybullet's own CCD sweeps a sphere at the start
orientation and never sees the rotation. With BoxCCD the plank always strikes
the cube. A pass-through: the plank's spin is unchanged after it has swept past.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pybullet as p

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import box_body, demo_setup, print_table, simulate  # noqa: E402

from bullet_boxccd import BoxCCD  # noqa: E402


def run(cid, use_ccd, phase, radius, picture=None):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(1 / 240, physicsClientId=cid)
    box_body(cid, [0.05] * 3, [radius, 0, 0], mass=0.0, color=(0.6, 0.6, 0.7, 1))
    yaw = np.pi / 2 + phase * 0.83  # the plank starts across the cube's direction
    plank = box_body(cid, [0.5, 0.01, 0.1], [0, 0, 0], orn=p.getQuaternionFromEuler([0, 0, yaw]))
    p.resetBaseVelocity(plank, [0, 0, 0], [0, 0, -200.0], physicsClientId=cid)
    ccd = BoxCCD(cid) if use_ccd else None
    contacts, timer = simulate(cid, ccd, 8, picture, ([radius / 2, 0, 0], 1.4, 20, -60))  # about one turn
    spin = p.getBaseVelocity(plank, physicsClientId=cid)[1][2]
    return abs(spin + 200.0) < 1e-6, contacts, timer


def main(argv=None):
    args, cid = demo_setup(__doc__, argv, phases=40)
    rows, passed = [], {}
    for radius in (0.3, 0.45):
        for use in (False, True):
            out = [run(cid, use, k / args.phases, radius,
                       os.path.join(args.out, "spinning_plank.png") if use and k == 0 and radius == 0.3 else None)
                   for k in range(args.phases)]
            passed[(radius, use)] = sum(o[0] for o in out)
            rows.append((f"{radius} m", "BoxCCD" if use else "plain pybullet", f"{passed[(radius, use)]}/{args.phases}",
                         sum(o[1] for o in out), f"{np.median([o[2].us_per_step for o in out]):.0f}"))
    print_table("spinning plank: 200 rad/s, 240 Hz", ("cube at", "run", "passed through", "CCD contacts",
                                                       "us/step (median)"), rows)
    assert passed[(0.3, True)] == 0 and passed[(0.45, True)] == 0, "BoxCCD let the plank through"
    assert passed[(0.3, False)] + passed[(0.45, False)] > 0, "plain pybullet never passed through"
    p.disconnect(cid)


if __name__ == "__main__":
    main()
