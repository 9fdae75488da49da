"""A 1 x 0.02 x 0.2 m plank spinning at 200 rad/s about its centre, next to a static
0.1 m cube at radius 0.3 m and 0.45 m, over 40 start phases at 240 Hz.

The plank turns 0.83 rad a step, so plain pybullet sees it on one side of the
cube and then on the other; pybullet's own CCD sweeps a sphere at the start
orientation and never sees the rotation. With BoxCCD the plank always strikes
the cube. A pass-through: the plank's spin is unchanged after it has swept past.
Saves spinning_plank.png: the same run without and with BoxCCD, seen from above,
the plank's outline at every step.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pybullet as p

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _common as demo  # noqa: E402

from bullet_boxccd import BoxCCD  # noqa: E402

OPTIONS = {"phases": (40, "runs per cube position: the plank's start angle spread over one step's turn")}


def run(cid, use_ccd, phase, radius):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(1 / 240, physicsClientId=cid)
    cube = demo.box_body(cid, [0.05] * 3, [radius, 0, 0], mass=0.0, color=(0.6, 0.6, 0.7, 1))
    yaw = np.pi / 2 + phase * 0.83  # the plank starts across the cube's direction
    plank = demo.box_body(cid, [0.5, 0.01, 0.1], [0, 0, 0], orn=p.getQuaternionFromEuler([0, 0, yaw]))
    p.resetBaseVelocity(plank, [0, 0, 0], [0, 0, -200.0], physicsClientId=cid)
    ccd = BoxCCD(cid) if use_ccd else None
    contacts, timer, track = demo.simulate(cid, ccd, 8, track=[plank], static=[cube])  # about one turn
    spin = p.getBaseVelocity(plank, physicsClientId=cid)[1][2]
    return abs(spin + 200.0) < 1e-6, contacts, timer, track


def picture(path, args, runs, passed):
    """One run (the first that plain pybullet lets through), without and with BoxCCD, from above."""
    from matplotlib.patches import Circle

    radius = next((r for r in (0.3, 0.45) if passed[(r, False)]), 0.3)
    k = demo.pick(runs[(radius, False)], lambda r: r[0])
    fig, axes = demo.figure(f"1 m plank spinning at 200 rad/s (0.83 rad per step at 240 Hz) by a static 0.1 m cube at "
                       f"{radius} m\ntop view of run {k + 1} of {args.phases}, the plank after every step",
                       1, 2, size=(12.0, 7.0))
    for ax, use in zip(axes[0], (False, True)):
        name = "BoxCCD" if use else "plain pybullet"
        n = passed[(0.3, use)] + passed[(0.45, use)]
        track = runs[(radius, use)][k][3]
        xy = demo.panel(ax, f"{name}: {n}/{2 * args.phases} passed through", "top", (-0.8, 0.8), (-0.8, 0.8),
                   bad=n > 0)
        ax.add_patch(Circle((0, 0), 0.5, fill=False, ls=":", color="0.5", label="circle swept by the plank's ends"))
        demo.draw_static(ax, track.static, xy, "cube (static)")
        demo.draw_path(ax, track, 0, xy, demo.BODY[1], "plank after each step, numbered at one end (dashed: start)",
                  anchor=(0.56, 0.0, 0.0), spacing=0.02, line=False)
    demo.legend(fig, axes)
    return demo.save(fig, path)


def main(argv=None):
    args, cid = demo.demo_setup(__doc__, argv, OPTIONS)
    rows, passed, runs = [], {}, {}
    for radius in (0.3, 0.45):
        for use in (False, True):
            out = runs[(radius, use)] = [run(cid, use, k / args.phases, radius) for k in range(args.phases)]
            passed[(radius, use)] = sum(o[0] for o in out)
            rows.append((f"{radius} m", "BoxCCD" if use else "plain pybullet", f"{passed[(radius, use)]}/{args.phases}",
                         sum(o[1] for o in out), f"{np.median([o[2].us_per_step for o in out]):.0f}"))
    demo.print_table("spinning plank: 200 rad/s, 240 Hz", ("cube at", "run", "passed through", "CCD contacts",
                                                       "us/step (median)"), rows)
    assert passed[(0.3, True)] == 0 and passed[(0.45, True)] == 0, "BoxCCD let the plank through"
    assert passed[(0.3, False)] + passed[(0.45, False)] > 0, "plain pybullet never passed through"
    print(f"picture: {picture(os.path.join(args.out, 'spinning_plank.png'), args, runs, passed)}")
    p.disconnect(cid)


if __name__ == "__main__":
    main()
