"""Shared by the demo scripts: their options, stepping a scene with and without BoxCCD
while recording where the bodies go, a table, and the picture (matplotlib, headless):
plain pybullet and BoxCCD side by side, each body's box outline at every step
projected on a plane (top view x-y or side view x-z)."""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import dataclass, field

import numpy as np
import pybullet as p
from _plot import pyplot  # noqa: F401  (the demos import it from here)

from bullet_boxccd.cli import add_demo_options

# Colours: static geometry, and the moving bodies (plain pybullet and BoxCCD use the same).
WALL = "#8a8fa8"
BODY = ("#d1495b", "#2e86ab", "#edae49", "#66a182", "#8d6a9f", "#00798c")

# A plane to project on: which world axes go right and up, and their labels.
VIEWS = {
    "top": ((0, 1), "x (m)", "y (m)"),
    "side": ((0, 2), "x (m)", "z (m)"),
}


def demo_setup(doc: str, argv, options: dict):
    """Parse a demo's ``options`` (``name: (default, help)``, typed by the default) and
    ``--out``, check that matplotlib is there, and connect a headless pybullet.
    Returns (args, physics client id)."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_demo_options(ap, options)
    args = ap.parse_args(argv)
    pyplot()  # before any work: the picture is the last thing a demo does
    return args, p.connect(p.DIRECT)


def print_table(title: str, header, rows) -> None:
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
    print(f"\n{title}")
    print("| " + " | ".join(str(h).ljust(w) for h, w in zip(header, widths)) + " |")
    print("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for r in rows:
        print("| " + " | ".join(str(x).ljust(w) for x, w in zip(r, widths)) + " |")


class Timer:
    def __init__(self):
        self.seconds = 0.0
        self.steps = 0

    def step(self, fn):
        t = time.perf_counter()
        out = fn()
        self.seconds += time.perf_counter() - t
        self.steps += 1
        return out

    @property
    def us_per_step(self) -> float:
        return 1e6 * self.seconds / max(self.steps, 1)


# ----------------------------------------------------------------------------- geometry
def _matrix(quat) -> np.ndarray:
    return np.reshape(p.getMatrixFromQuaternion(quat), (3, 3))


def box_shapes(cid, body) -> list:
    """The boxes of a body's base as (half extents, position, rotation) in the base's frame."""
    out = []
    for s in p.getCollisionShapeData(body, -1, physicsClientId=cid):
        if s[2] == p.GEOM_BOX:
            out.append((np.array(s[3]) / 2, np.array(s[5]), _matrix(s[6])))
    return out


def world_boxes(shapes, pose) -> list:
    """``shapes`` (from box_shapes) placed at a base ``pose`` (x, y, z, quaternion):
    a list of (8, 3) corner arrays."""
    R, t = _matrix(pose[3:]), np.asarray(pose[:3])
    signs = np.array([(i, j, k) for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
    return [t + (pos + (signs * half) @ Rl.T) @ R.T for half, pos, Rl in shapes]


def static_boxes(cid, bodies) -> list:
    """Corner arrays of every box of these (static) bodies, where they are now."""
    out = []
    for b in bodies:
        pos, orn = p.getBasePositionAndOrientation(b, physicsClientId=cid)
        out += world_boxes(box_shapes(cid, b), [*pos, *orn])
    return out


def outline(corners, axes) -> np.ndarray:
    """The outline (convex hull, counter-clockwise) of a box's corners projected on ``axes``."""
    pts = sorted(set(map(tuple, np.round(corners[:, list(axes)], 12))))
    if len(pts) < 3:
        return np.array(pts)

    def turn(o, a, b):  # > 0: o, a, b turn left
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def half(points):
        hull = []
        for q in points:
            while len(hull) >= 2 and turn(hull[-2], hull[-1], q) <= 0:
                hull.pop()
            hull.append(q)
        return hull[:-1]

    return np.array(half(pts) + half(pts[::-1]))


# ----------------------------------------------------------------------------- stepping
@dataclass
class Track:
    """Where bodies went: their box shapes and base poses (x, y, z, quaternion) before
    the first step and after each, plus the static boxes' corners."""

    shapes: list = field(default_factory=list)  # per body, from box_shapes
    poses: np.ndarray = None  # (steps + 1, bodies, 7)
    static: list = field(default_factory=list)  # corner arrays

    def boxes(self, step: int, body: int) -> list:
        return world_boxes(self.shapes[body], self.poses[step, body])


def _poses(cid, bodies) -> list:
    return [[*pos, *orn] for pos, orn in (p.getBasePositionAndOrientation(b, physicsClientId=cid) for b in bodies)]


def simulate(cid, ccd, steps, track=(), static=()):
    """Step ``steps`` times (with ``ccd.step`` if given, else plain pybullet), recording
    the poses of the bodies in ``track`` (outside the timed calls). Returns (CCD
    contacts, Timer, Track)."""
    timer, contacts = Timer(), 0
    path = [_poses(cid, track)]
    rec = Track([box_shapes(cid, b) for b in track], None, static_boxes(cid, static))
    for _ in range(steps):
        events = timer.step(ccd.step if ccd else lambda: p.stepSimulation(physicsClientId=cid))
        contacts += len(events or [])
        path.append(_poses(cid, track))
    rec.poses = np.array(path, dtype=float).reshape(steps + 1, len(track), 7)
    return contacts, timer, rec


def box_body(cid, half, pos, mass=1.0, orn=(0, 0, 0, 1), color=(0.8, 0.3, 0.2, 1), **dynamics):
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid)
    vis = p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=color, physicsClientId=cid)
    b = p.createMultiBody(mass, col, vis, basePosition=pos, baseOrientation=orn, physicsClientId=cid)
    dyn = dict(linearDamping=0.0, angularDamping=0.0, maxJointVelocity=10000.0)
    dyn.update(dynamics)
    p.changeDynamics(b, -1, physicsClientId=cid, **dyn)
    return b


# ----------------------------------------------------------------------------- drawing
def figure(title: str, nrows: int, ncols: int, size=(12.0, 5.6), **gridspec):
    plt = pyplot()
    fig, axes = plt.subplots(nrows, ncols, figsize=size, squeeze=False, layout="constrained", gridspec_kw=gridspec)
    fig.suptitle(title, fontsize=12)
    return fig, axes


def panel(ax, title: str, view: str, xlim, ylim, bad: bool) -> tuple:
    """Set up an axes for a projection: limits, equal scale, labels, a title in red
    when the run lost something (``bad``), green when not. Returns the view's axes."""
    axes, xlabel, ylabel = VIEWS[view]
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.set_aspect("equal")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, color="#b3001b" if bad else "#1b7f3b", fontweight="bold", fontsize=11)
    ax.grid(alpha=0.25)
    return axes


def draw_static(ax, corners_list, axes, label: str, color=WALL, alpha=0.9, fill=True):
    """Static boxes, filled (or, with ``fill=False``, dashed outlines)."""
    from matplotlib.patches import Polygon

    for i, corners in enumerate(corners_list):
        ax.add_patch(Polygon(outline(corners, axes), closed=True, facecolor=color if fill else "none",
                             edgecolor="#4a4e69", lw=0.8 if fill else 1.3, ls="-" if fill else "--",
                             alpha=alpha if fill else 1.0, zorder=1, label=label if i == 0 else None))


def draw_path(ax, track: Track, body: int, axes, color, label: str, steps=None, numbers=True, spacing=0.05,
              number_offset=(0.0, 0.0), anchor=None, line=True):
    """The filmstrip of one body: its outline at every recorded step (faint at the start,
    solid at the end; the start dashed), a thin line through its centres, and the
    step numbers (at the centre, or at the body-frame point ``anchor``) where
    consecutive labels are at least ``spacing`` apart."""
    from matplotlib.patches import Polygon

    n = len(track.poses) if steps is None else min(steps + 1, len(track.poses))
    centres = track.poses[:n, body, list(axes)]
    if line:
        ax.plot(centres[:, 0], centres[:, 1], color=color, lw=0.8, alpha=0.6, zorder=2)
    if anchor is not None:
        centres = np.array([(track.poses[i, body, :3] + _matrix(track.poses[i, body, 3:]) @ anchor)[list(axes)]
                            for i in range(n)])
    last = None
    for i in range(n):
        start = i == 0
        for corners in track.boxes(i, body):
            ax.add_patch(Polygon(outline(corners, axes), closed=True, fill=False, edgecolor=color,
                                 lw=1.4 if start or i == n - 1 else 1.0, ls="--" if start else "-",
                                 alpha=0.35 + 0.65 * i / max(n - 1, 1), zorder=3))
        if numbers and (last is None or np.linalg.norm(centres[i] - last) >= spacing):
            ax.annotate(str(i), centres[i], xytext=number_offset, textcoords="offset points", fontsize=7,
                        color=color, ha="center", va="center", zorder=4, clip_on=True)
            last = centres[i]
    ax.plot([], [], color=color, lw=1.2, label=label)  # the legend's entry


def off_panel_note(ax, track: Track, body: int, axes, color, what: str):
    """Say where a body went if it ended outside the panel."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    end = track.poses[-1, body, list(axes)]
    if x0 <= end[0] <= x1 and y0 <= end[1] <= y1:
        return
    names = "xyz"
    at = ", ".join(f"{names[a]} = {v:.1f} m" for a, v in zip(axes, end))
    ax.annotate(f"{what} ends off this view: {at}", xy=(0.98, 0.03), xycoords="axes fraction", ha="right",
                va="bottom", fontsize=8, color=color, bbox=dict(boxstyle="round", fc="white", ec=color, alpha=0.9))


def legend(fig, axes, ncol=3):
    """One legend for the figure, below the panels: every label of every panel, once."""
    seen = {}
    for ax in np.ravel(axes):
        for h, label in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(label, h)
    fig.legend(list(seen.values()), list(seen), loc="outside lower center", ncol=ncol, fontsize=9, frameon=False)


def save(fig, path: str) -> str:
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    pyplot().close(fig)
    return path


def pick(results, want):
    """The index of the first run for which ``want(result)`` holds (0 if none)."""
    return next((k for k, r in enumerate(results) if want(r)), 0)
