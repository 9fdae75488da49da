"""A 0.1 m cube at 100 m/s against a 1 cm static wall at 240 Hz, over many start phases.

Plain pybullet lets it through in most phases; with BoxCCD it never ends on the
far side. Prints a table, asserts the outcome and saves a picture of an impact.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pybullet as p

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import box_body, demo_setup, print_table, simulate  # noqa: E402

from bullet_boxccd import BoxCCD  # noqa: E402


def scene(cid, phase, speed, thickness, spin):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(1 / 240, physicsClientId=cid)
    box_body(cid, [thickness / 2, 0.5, 0.5], [0, 0, 0], mass=0.0, color=(0.6, 0.6, 0.7, 1))
    cube = box_body(cid, [0.05] * 3, [-0.3 - phase * speed / 240, 0.1, 0.05])
    p.resetBaseVelocity(cube, [speed, 0, 0], spin, physicsClientId=cid)
    return cube


def run(cid, use_ccd, phase, speed, thickness, spin, picture=None):
    cube = scene(cid, phase, speed, thickness, spin)
    ccd = BoxCCD(cid) if use_ccd else None
    contacts, timer = simulate(cid, ccd, int(240 / speed) + 30, picture, ([-0.05, 0.1, 0.05], 0.9, -50, -20))
    return p.getBasePositionAndOrientation(cube, physicsClientId=cid)[0][0] > 0.0, contacts, timer


def main(argv=None):
    args, cid = demo_setup(__doc__, argv, phases=24, speed=100.0, thickness=0.01)
    rows, results = [], {}
    for use in (False, True):
        rng = np.random.default_rng(0)  # the same phases and spins for both runs
        tunneled, contacts, us = 0, 0, []
        for k in range(args.phases):
            spin = rng.uniform(-20, 20, 3)
            pic = os.path.join(args.out, "thin_wall.png") if use and k == 0 else None
            through, n, timer = run(cid, use, k / args.phases, args.speed, args.thickness, spin, pic)
            tunneled += through
            contacts += n
            us.append(timer.us_per_step)
        results[use] = tunneled
        rows.append(("BoxCCD" if use else "plain pybullet", f"{tunneled}/{args.phases}", contacts,
                     f"{np.median(us):.0f}"))
    print_table(f"thin wall: 0.1 m cube at {args.speed:g} m/s, wall {args.thickness * 1000:g} mm, 240 Hz",
                ("run", "tunneled", "CCD contacts", "us/step (median)"), rows)
    assert results[True] == 0, "BoxCCD let the cube through"
    assert results[False] > 0, "plain pybullet did not tunnel: the scene shows nothing"
    print(f"picture: {os.path.join(args.out, 'thin_wall.png')}")
    p.disconnect(cid)


if __name__ == "__main__":
    main()
