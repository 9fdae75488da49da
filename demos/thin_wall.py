"""A 0.1 m cube at 100 m/s against a 1 cm static wall at 240 Hz, over many start phases.

Plain pybullet lets it through in most phases; with BoxCCD it never ends on the
far side. Prints a table, asserts the outcome and saves thin_wall.png: the same
run without and with BoxCCD, seen from above, the cube's outline at every step.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pybullet as p

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _common as demo  # noqa: E402

from bullet_boxccd import BoxCCD  # noqa: E402

OPTIONS = {
    "phases": (24, "runs: the cube's start distance to the wall spread over one step's travel"),
    "speed": (100.0, "the cube's speed towards the wall (m/s)"),
    "thickness": (0.01, "the wall's thickness (m)"),
}


def scene(cid, phase, speed, thickness, spin):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(1 / 240, physicsClientId=cid)
    wall = demo.box_body(cid, [thickness / 2, 0.5, 0.5], [0, 0, 0], mass=0.0, color=(0.6, 0.6, 0.7, 1))
    cube = demo.box_body(cid, [0.05] * 3, [-0.3 - phase * speed / 240, 0.1, 0.05])
    p.resetBaseVelocity(cube, [speed, 0, 0], spin, physicsClientId=cid)
    return wall, cube


def run(cid, use_ccd, phase, speed, thickness, spin):
    wall, cube = scene(cid, phase, speed, thickness, spin)
    ccd = BoxCCD(cid) if use_ccd else None
    contacts, timer, track = demo.simulate(cid, ccd, int(240 / speed) + 30, track=[cube], static=[wall])
    return p.getBasePositionAndOrientation(cube, physicsClientId=cid)[0][0] > 0.0, contacts, timer, track


def picture(path, args, runs, tunneled):
    """One phase (the first that plain pybullet lets through), without and with BoxCCD, from above."""
    k = demo.pick(runs[False], lambda r: r[0])
    step = args.speed / 240
    fig, axes = demo.figure(f"{args.speed:g} m/s cube (0.1 m) against a {args.thickness * 1000:g} mm wall at 240 Hz "
                       f"({step * 100:.0f} cm per step)\ntop view of run {k + 1} of {args.phases}, "
                       "the cube's outline after every step", 1, 2, size=(13.0, 6.0))
    for ax, use in zip(axes[0], (False, True)):
        name = "BoxCCD" if use else "plain pybullet"
        track = runs[use][k][3]
        xy = demo.panel(ax, f"{name}: {tunneled[use]}/{args.phases} tunneled", "top",
                        (-0.5 - 2.2 * step, 0.3 + 1.7 * step), (-1.2, 0.6), bad=tunneled[use] > 0)
        demo.draw_static(ax, track.static, xy, f"wall ({args.thickness * 1000:g} mm thick, static)")
        demo.draw_path(ax, track, 0, xy, demo.BODY[0], "cube after each step, numbered (dashed: start)", spacing=0.1,
                  number_offset=(0, 14))
        demo.off_panel_note(ax, track, 0, xy, demo.BODY[0], "the cube")
    demo.legend(fig, axes)
    return demo.save(fig, path)


def main(argv=None):
    args, cid = demo.demo_setup(__doc__, argv, OPTIONS)
    rows, results, runs = [], {}, {}
    for use in (False, True):
        rng = np.random.default_rng(0)  # the same phases and spins for both runs
        tunneled, contacts, us, runs[use] = 0, 0, [], []
        for k in range(args.phases):
            spin = rng.uniform(-20, 20, 3)
            out = run(cid, use, k / args.phases, args.speed, args.thickness, spin)
            runs[use].append(out)
            tunneled += out[0]
            contacts += out[1]
            us.append(out[2].us_per_step)
        results[use] = tunneled
        rows.append(("BoxCCD" if use else "plain pybullet", f"{tunneled}/{args.phases}", contacts,
                     f"{np.median(us):.0f}"))
    demo.print_table(f"thin wall: 0.1 m cube at {args.speed:g} m/s, wall {args.thickness * 1000:g} mm, 240 Hz",
                ("run", "tunneled", "CCD contacts", "us/step (median)"), rows)
    assert results[True] == 0, "BoxCCD let the cube through"
    assert results[False] > 0, "plain pybullet did not tunnel: the scene shows nothing"
    print(f"picture: {picture(os.path.join(args.out, 'thin_wall.png'), args, runs, results)}")
    p.disconnect(cid)


if __name__ == "__main__":
    main()
