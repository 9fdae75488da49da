"""Lego and Jenga pieces from pybullet_data thrown fast inside tray/traybox.urdf
(five boxes on one link, 2 cm walls, URDFs unchanged) under a static 2 cm lid, at 240 Hz.

The tray and lid close the pieces in, so a piece found outside went through a
wall, the floor or the lid. Plain pybullet loses most of them; with BoxCCD none.
Saves box_rain.png: the first run without and with BoxCCD, the tray cut in half
from the side and seen from above, each piece's path and its outline at every step.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pybullet as p
import pybullet_data

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _common as demo  # noqa: E402

from bullet_boxccd import BoxCCD  # noqa: E402

PIECES = ("lego/lego.urdf", "jenga/jenga.urdf")
OPTIONS = {
    "pieces": (16, "pieces thrown in the tray per run (lego and jenga in turn)"),
    "runs": (3, "runs (seeds), each with and without BoxCCD"),
}
INSIDE = dict(x=0.36, y=0.36, z=(-0.01, 0.14))  # a piece outside this went through the tray or the lid


def inside(pos) -> bool:
    x, y, z = pos
    return abs(x) < INSIDE["x"] and abs(y) < INSIDE["y"] and INSIDE["z"][0] < z < INSIDE["z"][1]


def run(cid, use_ccd, n, seed):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(1 / 240, physicsClientId=cid)
    p.setGravity(0, 0, -9.81, physicsClientId=cid)
    data = pybullet_data.getDataPath()
    tray = p.loadURDF(os.path.join(data, "tray/traybox.urdf"), physicsClientId=cid)
    lid = demo.box_body(cid, [0.36, 0.36, 0.01], [0, 0, 0.13], mass=0.0, color=(0.6, 0.6, 0.7, 0.4))
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
    contacts, timer, track = demo.simulate(cid, ccd, 240, track=pieces, static=[tray, lid])
    escaped = sum(not inside(p.getBasePositionAndOrientation(b, physicsClientId=cid)[0]) for b in pieces)
    return escaped, contacts, timer, track


def draw_pieces(ax, track, axes, steps):
    """Each piece: its centre's path (grey inside, red from where it left the tray), its
    outline at each of the first ``steps`` steps, a cross where an escaped one was last seen."""
    from matplotlib.patches import Polygon

    for body in range(track.poses.shape[1]):
        path = track.poses[:, body, :3]
        out = next((i for i, q in enumerate(path) if not inside(q)), None)
        end = len(path) if out is None else out + 1
        xy = path[:, list(axes)]
        ax.plot(xy[:end, 0], xy[:end, 1], color="#2e86ab", lw=0.7, alpha=0.5, zorder=2,
                label="a piece's centre, every step (1/240 s) for 1 s")
        for i in range(min(steps + 1, end)):
            for corners in track.boxes(i, body):
                ax.add_patch(Polygon(demo.outline(corners, axes), closed=True, fill=False, edgecolor="#2e86ab", lw=0.8,
                                     alpha=0.3 + 0.5 * i / steps, ls="--" if i == 0 else "-", zorder=3))
        if out is not None:
            ax.plot(xy[out - 1:, 0], xy[out - 1:, 1], color="#d1495b", lw=1.4, zorder=4,
                    label="path of a piece that left the tray")
            ax.plot(*xy[out - 1], "x", color="#d1495b", ms=7, mew=2, zorder=5, label="last step inside")
    ax.plot([], [], color="#2e86ab", lw=0.8, label=f"piece outlines, the first {steps} steps (dashed: start)")


def picture(path, args, first, escaped):
    """Run 1 without and with BoxCCD: the tray cut at y = 0 from the side, and from above."""
    n = args.pieces * args.runs
    fig, axes = demo.figure(f"{args.pieces} lego and jenga pieces thrown at up to 100 m/s into tray/traybox.urdf under "
                       f"a 2 cm lid, 240 Hz, gravity, 1 s\nrun 1 of {args.runs}: side view (tray and lid cut at y = 0) "
                       "and top view", 2, 2, size=(12.0, 9.6), height_ratios=(0.6, 1.2))
    for col, use in enumerate((False, True)):
        track = first[use][3]
        title = f"{'BoxCCD' if use else 'plain pybullet'}: {escaped[use]}/{n} left the tray"
        xz = demo.panel(axes[0, col], title + " (side)", "side", (-0.6, 0.6), (-0.25, 0.35), bad=escaped[use] > 0)
        section = [c for c in track.static if c[:, 1].min() < 0 < c[:, 1].max()]
        demo.draw_static(axes[0, col], section, xz, "tray and lid (static)", alpha=0.7)
        draw_pieces(axes[0, col], track, xz, 6)
        xy = demo.panel(axes[1, col], title + " (top)", "top", (-0.6, 0.6), (-0.6, 0.6), bad=escaped[use] > 0)
        demo.draw_static(axes[1, col], track.static[:5], xy, "tray and lid (static)", alpha=0.35)  # the tray's 5 boxes
        demo.draw_static(axes[1, col], track.static[5:], xy, "the lid's edge in the top view", fill=False)
        draw_pieces(axes[1, col], track, xy, 6)
    demo.legend(fig, axes, ncol=3)
    return demo.save(fig, path)


def main(argv=None):
    args, cid = demo.demo_setup(__doc__, argv, OPTIONS)
    rows, escaped, first = [], {}, {}
    for use in (False, True):
        out = [run(cid, use, args.pieces, seed) for seed in range(args.runs)]
        escaped[use] = sum(o[0] for o in out)
        first[use] = out[0]
        rows.append(("BoxCCD" if use else "plain pybullet", f"{escaped[use]}/{args.pieces * args.runs}",
                     sum(o[1] for o in out), f"{np.median([o[2].us_per_step for o in out]):.0f}"))
    demo.print_table(f"box rain: {args.pieces} lego/jenga pieces at up to 100 m/s in tray/traybox.urdf, 240 Hz",
                ("run", "left the tray", "CCD contacts", "us/step (median)"), rows)
    assert escaped[True] == 0, "a piece left the tray with BoxCCD"
    assert escaped[False] > 0, "no piece left the tray without BoxCCD: the scene shows nothing"
    print(f"picture: {picture(os.path.join(args.out, 'box_rain.png'), args, first, escaped)}")
    p.disconnect(cid)


if __name__ == "__main__":
    main()
