"""Lego and Jenga pieces from pybullet_data thrown fast inside tray/traybox.urdf
(five boxes on one link, 2 cm walls, URDFs unchanged) under a static 2 cm lid, at 240 Hz.

The tray and lid close the pieces in, so a piece found outside went through a
wall, the floor or the lid. Plain pybullet loses most of them; with BoxCCD none.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pybullet as p
import pybullet_data

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import box_body, demo_setup, print_table, simulate  # noqa: E402

from bullet_boxccd import BoxCCD  # noqa: E402

PIECES = ("lego/lego.urdf", "jenga/jenga.urdf")


def run(cid, use_ccd, n, seed, picture=None):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(1 / 240, physicsClientId=cid)
    p.setGravity(0, 0, -9.81, physicsClientId=cid)
    data = pybullet_data.getDataPath()
    p.loadURDF(os.path.join(data, "tray/traybox.urdf"), physicsClientId=cid)
    box_body(cid, [0.36, 0.36, 0.01], [0, 0, 0.13], mass=0.0, color=(0.6, 0.6, 0.7, 0.4))  # the lid
    rng = np.random.default_rng(seed)
    pieces = []
    side = int(np.ceil(np.sqrt(n)))
    for k in range(n):
        pos = [-0.15 + 0.3 * (k % side) / max(side - 1, 1), -0.15 + 0.3 * (k // side) / max(side - 1, 1), 0.07]
        b = p.loadURDF(os.path.join(data, PIECES[k % 2]), pos, p.getQuaternionFromEuler([0, 0, rng.uniform(0, 6)]),
                       physicsClientId=cid)
        p.changeDynamics(b, -1, maxJointVelocity=10000, physicsClientId=cid)
        v = [rng.uniform(-40, 40), rng.uniform(-40, 40), rng.uniform(-80, 80)]
        p.resetBaseVelocity(b, v, rng.uniform(-30, 30, 3).tolist(), physicsClientId=cid)
        pieces.append(b)
    ccd = BoxCCD(cid) if use_ccd else None
    contacts, timer = simulate(cid, ccd, 240, picture, ([0, 0, 0.05], 1.1, 30, -50), picture_at=30)
    escaped = 0
    for b in pieces:
        x, y, z = p.getBasePositionAndOrientation(b, physicsClientId=cid)[0]
        escaped += not (abs(x) < 0.36 and abs(y) < 0.36 and -0.01 < z < 0.14)
    return escaped, contacts, timer


def main(argv=None):
    args, cid = demo_setup(__doc__, argv, pieces=16, runs=3)
    rows, escaped = [], {}
    for use in (False, True):
        out = [run(cid, use, args.pieces, seed, os.path.join(args.out, "box_rain.png") if use and seed == 0 else None)
               for seed in range(args.runs)]
        escaped[use] = sum(o[0] for o in out)
        rows.append(("BoxCCD" if use else "plain pybullet", f"{escaped[use]}/{args.pieces * args.runs}",
                     sum(o[1] for o in out), f"{np.median([o[2].us_per_step for o in out]):.0f}"))
    print_table(f"box rain: {args.pieces} lego/jenga pieces at up to 100 m/s in tray/traybox.urdf, 240 Hz",
                ("run", "left the tray", "CCD contacts", "us/step (median)"), rows)
    assert escaped[True] == 0, "a piece left the tray with BoxCCD"
    assert escaped[False] > 0, "no piece left the tray without BoxCCD: the scene shows nothing"
    p.disconnect(cid)


if __name__ == "__main__":
    main()
