"""The solver on a seed-style example: a static box S and a box M that flies at it
while turning, under a quadratic motion. Prints the route division (octant
switches), the BMS planes at the contact, and the contact itself, then checks
the contact against the boxes' vertices. Saves solver_contact.png: the route's
sections over t with the gap between the boxes and the contact time, and the
two boxes at the contact (M's path before it in outlines).
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _plot import pyplot  # noqa: E402

from bullet_boxccd import Box, QuadraticMotion, bms_planes, sections, time_of_impact  # noqa: E402
from bullet_boxccd.cli import add_demo_options  # noqa: E402
from bullet_boxccd.motion import rotation_matrix  # noqa: E402

OPTIONS = {}  # --out only
# A box's faces as indices into Box.vertices() (ordered by sign triples (-,-,-), (-,-,+), ...).
FACES = ((0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5))


def corners(box, motion, t):
    X = motion.at(t)
    return box.vertices() @ X[:3, :3].T + X[:3, 3]


def gap(S, m_S, M, m_M, t):
    """The largest separation over the 30 BMS planes at t (> 0: apart; 0: touching; < 0: overlapping)."""
    return -min(plane.offset for plane in bms_planes(S, m_S, M, m_M, t))


def picture(path, S, m_S, M, m_M, cuts, c):
    plt = pyplot()
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = plt.figure(figsize=(14.5, 6.4), layout="constrained")
    fig.get_layout_engine().set(wspace=0.06)
    fig.suptitle(f"time_of_impact on a static box S and a box M flying at it while turning: first contact at "
                 f"t = {c.t:.6f}\nthe solver's route: {len(cuts) - 1} sections of constant BMS topology (between "
                 "octant switches), searched in order", fontsize=12)
    grid = fig.add_gridspec(1, 2, width_ratios=(1.0, 1.35))

    # Left: the boxes at the contact, and M's path up to it.
    ax = fig.add_subplot(grid[0], projection="3d")
    for box, m, color, label in ((S, m_S, "#8a8fa8", "S (static)"), (M, m_M, "#d1495b", "M at the contact")):
        v = corners(box, m, c.t)
        ax.add_collection3d(Poly3DCollection([v[list(f)] for f in FACES], facecolor=color, edgecolor="0.2",
                                             alpha=0.45, lw=0.6, label=label))
    for i, t in enumerate(np.linspace(0.0, c.t, 6)[:-1]):
        v = corners(M, m_M, t)
        for f in FACES:
            loop = v[list(f) + [f[0]]]
            ax.plot(*loop.T, color="#d1495b", lw=0.7, alpha=0.3 + 0.1 * i, ls="--" if i == 0 else "-",
                    label="M before the contact, t = 0 (dashed) to t_c" if (i, f) == (0, FACES[0]) else None)
    ax.scatter(*c.point, color="black", s=30, depthshade=False, label="contact point", zorder=5)
    ax.quiver(*c.point, *(0.8 * c.normal), color="black", lw=1.5, arrow_length_ratio=0.25,
              label="contact normal (S towards M)")
    centre = np.array([corners(M, m_M, t).mean(axis=0) for t in np.linspace(0.0, c.t, 40)])
    ax.plot(*centre.T, color="#d1495b", lw=1.2, ls=":", label="M's centre")
    pts = np.vstack([corners(S, m_S, 0.0)] + [corners(M, m_M, t) for t in np.linspace(0.0, c.t, 6)])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(hi - lo)
    ax.view_init(elev=30, azim=70)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title(f"the boxes at t = {c.t:.6f}: {c.feature.kind} contact, edge {c.feature.a} of S against "
                 f"edge {c.feature.b} of M" if c.feature.kind == "EE" else
                 f"the boxes at t = {c.t:.6f}: {c.feature.kind} contact ({c.feature.a or '-'} of S, "
                 f"{c.feature.b or '-'} of M)", fontsize=10)
    ax.legend(loc="upper left", fontsize=8)

    # Right: the route over t.
    ax = fig.add_subplot(grid[1])
    ts = np.unique(np.concatenate([np.linspace(0.0, 1.0, 801), cuts, [c.t]]))
    g = np.array([gap(S, m_S, M, m_M, t) for t in ts])
    k = int(np.searchsorted(cuts, c.t, side="right"))  # the contact's section, 1-based
    shade = 0
    for i, (a, b) in enumerate(zip(cuts[:-1], cuts[1:])):
        if b - a > 1e-3:  # narrower ones (two switches at about the same t) are only their boundaries
            ax.axvspan(a, b, color=("#e8eef7", "#f7f1e3")[shade % 2], zorder=0)
            shade += 1
        if b - a > 0.03:
            ax.text((a + b) / 2, 1.01, str(i + 1), transform=ax.get_xaxis_transform(), ha="center", va="bottom",
                    fontsize=8, color="#1b7f3b" if i + 1 == k else "0.35", fontweight="bold" if i + 1 == k else None)
    for i, t in enumerate(cuts[1:-1]):
        ax.axvline(t, color="0.45", lw=0.8, ls="--", zorder=1, label="section boundary (octant switch)" if i == 0
                   else None)
    ax.axhline(0.0, color="0.2", lw=0.8, zorder=1)
    ax.plot(ts, g, color="#2e86ab", lw=1.8, zorder=2,
            label="gap: the largest separation over the 30 BMS planes (< 0: the boxes overlap)")
    ax.axvline(c.t, color="#d1495b", lw=1.8, zorder=3, label=f"first contact, t = {c.t:.6f} (section {k})")
    ax.plot([c.t], [0.0], "o", color="#d1495b", zorder=4)
    ax.set_xlim(0.0, 1.0)
    ax.set_xlabel("t (the motion's parameter; M(t) = C0 + C1 t + C2 t^2)")
    ax.set_ylabel("gap (m)")
    ax.set_title("the route over t: sections numbered above (the narrow ones unnumbered), shaded in turn",
                 fontsize=10, pad=16)
    ax.grid(alpha=0.25)
    ax.legend(loc="upper right", fontsize=8, framealpha=0.95)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_demo_options(ap, OPTIONS)
    args = ap.parse_args(argv)
    pyplot()  # before any work
    S = Box(lo=(-1.0, -0.5, -0.25), hi=(1.0, 0.5, 0.25))  # the BMS algorithm's (X, Y, Z) and (X', Y', Z')
    M = Box(lo=(0.0, 0.0, 0.0), hi=(0.4, 0.3, 0.2))  # an off-centre box in its own frame
    start = np.eye(4)
    start[:3, :3] = rotation_matrix((1, 2, 3), 0.7)
    start[:3, 3] = (3.0, 1.0, 0.8)
    m_S = QuadraticMotion.static()
    m_M = QuadraticMotion.screw(start, velocity=(-4.0, -1.2, -0.9), angular_velocity=(0.0, 1.5, 2.5))
    print("S:", S, "static")
    print("M:", M, "turning at (0, 1.5, 2.5) rad per unit t while flying at (-4, -1.2, -0.9)")

    cuts = sections(S, m_S, M, m_M)
    print(f"\nroute division: {len(cuts) - 1} sections, boundaries (octant switches) at t =",
          np.array2string(cuts, precision=6))

    c = time_of_impact(S, m_S, M, m_M)
    assert c is not None, "expected a contact"
    print(f"\nfirst contact: t = {c.t:.15f}")
    print(f"  {c.feature.kind} plane: {c.feature.a or '-'} of S against {c.feature.b or '-'} of M")
    print("  point  =", np.array2string(c.point, precision=9))
    print("  normal =", np.array2string(c.normal, precision=9), "(from S towards M)")

    print("\nBMS planes at the contact (the origin lies on the touching one):")
    for plane in bms_planes(S, m_S, M, m_M, c.t):
        mark = " <- touching" if plane.feature == c.feature and abs(plane.offset) < 1e-9 else ""
        print(f"  {plane.feature.kind}  {plane.feature.a:>6} | {plane.feature.b:<6} offset {plane.offset:+.3e}{mark}")

    # Check: at t the boxes touch (the point is on both), and just before they are apart.
    for box, m in ((S, m_S), (M, m_M)):
        X = m.at(c.t)
        local = np.linalg.solve(X[:3, :3], c.point - X[:3, 3])
        assert np.all(local >= box.lo - 1e-9) and np.all(local <= box.hi + 1e-9), "contact point off a box"
    assert time_of_impact(S, m_S, M, m_M, (0.0, c.t - 1e-6)) is None, "a contact before the reported one"
    print("\nchecked: the point lies on both boxes, and they are apart until t.")
    print(f"picture: {picture(os.path.join(args.out, 'solver_contact.png'), S, m_S, M, m_M, cuts, c)}")


if __name__ == "__main__":
    main()
