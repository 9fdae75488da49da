"""Two 0.1 m cubes fired at each other at 200 m/s, head-on and crossing at an angle,
over 24 start phases at 240 Hz (restitution 1, no gravity).

Plain pybullet lets them pass through each other; with BoxCCD they collide, and
their total momentum is conserved. Saves two_bullets.png: the same runs without and
with BoxCCD, head-on as position against time, crossing seen from above.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pybullet as p

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _common as demo  # noqa: E402

from bullet_boxccd import BoxCCD  # noqa: E402

SPEED = 200.0
OPTIONS = {"phases": (24, "runs per approach: the cubes' start gap spread over one step's travel")}


def run(cid, use_ccd, phase, angle):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(1 / 240, physicsClientId=cid)
    d = np.array([np.cos(angle), np.sin(angle), 0.0])
    gap = 1.0 + phase * 2 * SPEED / 240
    a = demo.box_body(cid, [0.05] * 3, [-gap / 2, 0, 0], restitution=1.0)
    b = demo.box_body(cid, [0.05] * 3, (gap / 2 * d).tolist(), restitution=1.0, color=(0.2, 0.4, 0.8, 1), mass=2.0)
    p.resetBaseVelocity(a, [SPEED, 0, 0], [0, 0, 0], physicsClientId=cid)
    p.resetBaseVelocity(b, (-SPEED * d).tolist(), [0, 0, 0], physicsClientId=cid)
    momentum0 = 1.0 * np.array([SPEED, 0, 0]) + 2.0 * (-SPEED * d)
    ccd = BoxCCD(cid) if use_ccd else None
    contacts, timer, track = demo.simulate(cid, ccd, int(gap / SPEED * 240) + 10, track=[a, b])
    va = np.array(p.getBaseVelocity(a, physicsClientId=cid)[0])
    vb = np.array(p.getBaseVelocity(b, physicsClientId=cid)[0])
    momentum = 1.0 * va + 2.0 * vb
    through = np.allclose(va, [SPEED, 0, 0]) and np.allclose(vb, -SPEED * d)  # never interacted
    return through, contacts, timer, np.linalg.norm(momentum - momentum0) / np.linalg.norm([SPEED, 0, 0]), track


CUBES = ("cube A (1 kg)", "cube B (2 kg)")


def spacetime(ax, track, title, bad, through):
    """Head-on: each cube's extent along x (its outline projected on the x axis) at every step, against time."""
    from matplotlib.patches import Rectangle

    ms = 1000 * np.arange(len(track.poses)) / 240
    for body in (0, 1):
        x = track.poses[:, body, 0]
        ax.plot(x, ms, color=demo.BODY[body], lw=0.8, alpha=0.6)
        for i, (xi, ti) in enumerate(zip(x, ms)):
            ax.add_patch(Rectangle((xi - 0.05, ti - 0.6), 0.1, 1.2, facecolor=demo.BODY[body],
                                   edgecolor=demo.BODY[body], alpha=0.35 + 0.65 * i / (len(ms) - 1),
                                   ls="--" if i == 0 else "-"))
        ax.plot([], [], color=demo.BODY[body], lw=6, alpha=0.7, label=f"{CUBES[body]} after each step (dashed: start)")
    ax.set_xlim(-2.6, 2.6)
    ax.set_ylim(-2, min(ms[-1], 26) + 2)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("time (ms), one step = 4.2 ms")
    ax.set_title(title, color="#b3001b" if bad else "#1b7f3b", fontweight="bold", fontsize=11)
    ax.grid(alpha=0.25)
    ax.text(0.02, 0.97, "the paths cross: the cubes went through each other" if through else
            "the paths meet and turn back: the cubes collided", transform=ax.transAxes, ha="left", va="top",
            fontsize=9, bbox=dict(boxstyle="round", fc="white", ec="0.6"))


def picture(path, args, runs, result):
    """For each approach one run (the first that plain pybullet lets through), without and with BoxCCD."""
    fig, axes = demo.figure(f"two 0.1 m cubes at {SPEED:g} m/s each (83 cm per step at 240 Hz), restitution 1\n"
                       "top: head-on, x against time; bottom: crossing at 30 degrees, top view, the cubes after "
                       "every step", 2, 2, size=(12.0, 9.0))
    for row, angle in enumerate((0.0, np.radians(30))):
        k = demo.pick(runs[(angle, False)], lambda r: r[0])
        for ax, use in zip(axes[row], (False, True)):
            n = result[(angle, use)][0]
            title = (f"{'head-on' if angle == 0 else '30 degrees'}, {'BoxCCD' if use else 'plain pybullet'}: "
                     f"{n}/{args.phases} passed through (run {k + 1} shown)")
            track = runs[(angle, use)][k][4]
            if angle == 0:
                spacetime(ax, track, title, n > 0, runs[(angle, use)][k][0])
                continue
            xy = demo.panel(ax, title, "top", (-1.8, 1.8), (-1.1, 0.6), bad=n > 0)
            for body in (0, 1):
                demo.draw_path(ax, track, body, xy, demo.BODY[body], f"{CUBES[body]} after each step (dashed: start)",
                          spacing=0.2, number_offset=(0, 11))
    demo.legend(fig, axes, ncol=2)
    return demo.save(fig, path)


def main(argv=None):
    args, cid = demo.demo_setup(__doc__, argv, OPTIONS)
    rows, result, runs = [], {}, {}
    for angle in (0.0, np.radians(30)):
        for use in (False, True):
            out = runs[(angle, use)] = [run(cid, use, k / args.phases, angle) for k in range(args.phases)]
            result[(angle, use)] = (sum(o[0] for o in out), max(o[3] for o in out))
            rows.append((f"{np.degrees(angle):.0f} deg", "BoxCCD" if use else "plain pybullet",
                         f"{result[(angle, use)][0]}/{args.phases}", sum(o[1] for o in out),
                         f"{100 * result[(angle, use)][1]:.2f}%", f"{np.median([o[2].us_per_step for o in out]):.0f}"))
    demo.print_table("two bullets: 0.1 m cubes at 200 m/s each, 240 Hz", (
        "approach", "run", "passed through", "CCD contacts", "momentum error (max)", "us/step (median)"), rows)
    for angle in (0.0, np.radians(30)):
        assert result[(angle, True)][0] == 0, "BoxCCD let the cubes pass through each other"
        assert result[(angle, True)][1] < 0.01, "momentum not conserved to 1%"
    assert result[(0.0, False)][0] > 0, "plain pybullet never tunneled"
    print(f"picture: {picture(os.path.join(args.out, 'two_bullets.png'), args, runs, result)}")
    p.disconnect(cid)


if __name__ == "__main__":
    main()
