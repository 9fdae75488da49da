"""Shared by the demo scripts: timing a scene with and without BoxCCD, a table, a PNG."""

from __future__ import annotations

import argparse
import os
import struct
import time
import zlib

import numpy as np
import pybullet as p


def demo_setup(doc: str, argv, **options):
    """Parse a demo's options (``name=default``, typed by the default) and ``--out``,
    and connect a headless pybullet. Returns (args, physics client id)."""
    ap = argparse.ArgumentParser(description=doc)
    for name, default in options.items():
        ap.add_argument(f"--{name}", type=type(default), default=default)
    ap.add_argument("--out", default="demo_output")
    return ap.parse_args(argv), p.connect(p.DIRECT)


def write_png(path: str, rgb: np.ndarray) -> None:
    """Write an (H, W, 3) uint8 image as PNG (no imaging library needed)."""
    h, w, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[i].tobytes() for i in range(h))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def snapshot(cid: int, path: str, target, distance: float, yaw: float = 30.0, pitch: float = -25.0,
             size=(480, 360)) -> str:
    """Render the world with pybullet's TinyRenderer and save it as PNG."""
    view = p.computeViewMatrixFromYawPitchRoll(target, distance, yaw, pitch, 0, 2, physicsClientId=cid)
    proj = p.computeProjectionMatrixFOV(50, size[0] / size[1], 0.01, 100, physicsClientId=cid)
    img = p.getCameraImage(size[0], size[1], view, proj, renderer=p.ER_TINY_RENDERER, physicsClientId=cid)
    rgb = np.reshape(np.asarray(img[2], dtype=np.uint8), (size[1], size[0], 4))[:, :, :3]
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    write_png(path, np.ascontiguousarray(rgb))
    return path


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


def simulate(cid, ccd, steps, picture=None, camera=None, picture_at=None):
    """Step ``steps`` times (with ``ccd.step`` if given, else plain pybullet); save a
    picture (``camera``: snapshot's target, distance, yaw, pitch) at the first step
    with a CCD contact, or at step ``picture_at``. Returns (CCD contacts, Timer)."""
    timer, contacts = Timer(), 0
    for _ in range(steps):
        events = timer.step(ccd.step if ccd else lambda: p.stepSimulation(physicsClientId=cid))
        contacts += len(events or [])
        if picture and (timer.steps == picture_at if picture_at else events):
            target, distance, yaw, pitch = camera
            snapshot(cid, picture, target, distance, yaw=yaw, pitch=pitch)
            picture = None
    return contacts, timer


def box_body(cid, half, pos, mass=1.0, orn=(0, 0, 0, 1), color=(0.8, 0.3, 0.2, 1), **dynamics):
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid)
    vis = p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=color, physicsClientId=cid)
    b = p.createMultiBody(mass, col, vis, basePosition=pos, baseOrientation=orn, physicsClientId=cid)
    dyn = dict(linearDamping=0.0, angularDamping=0.0, maxJointVelocity=10000.0)
    dyn.update(dynamics)
    p.changeDynamics(b, -1, physicsClientId=cid, **dyn)
    return b
