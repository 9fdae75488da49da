"""Where a BoxCCD step's time goes: pybullet's calls, the core's, and the plugin's Python.

For each family of ``benchmarks/fidelity.py`` named (its scenes and seeds), every step of
``BoxCCD(cid).step()`` is timed and sorted by what it did:

* ``first``: the first step, which reads the world (bodies, shapes, filters),
* ``not fast``: no box could move its sweep reach (pybullet's step and the velocity reads),
* ``swept``: a sweep of the fast boxes that found nothing to take the world back to,
* ``back xN``: the world went back to contacts, N partial steps in all.

A second run of the same seeds times, inside those steps, every call to a pybullet
function and to the core (module functions and ``Sweeper`` methods), wrapped for the run:
``pybullet`` and ``core`` are their shares of that run's time (less what the wrappers
themselves add, measured on a wrapped no-op), ``python`` the rest, the plugin's own Python
(its bookkeeping, numpy on small arrays).
``floor`` is the step's time times the pybullet and core shares: what a step of that kind
would cost if the plugin's Python took no time, the floor of this design over pybullet's
per-body API. ``plain`` and ``sub16`` are pybullet's own step and ``numSubSteps=16`` on
the same scenes in the same run (each step's time: the fastest of three runs per seed, as
in ``fidelity.py``).

Run
---
    python benchmarks/step_cost.py                           # head_on, spinning, rain 48 and 1000
    python benchmarks/step_cost.py --families "head_on:e=0.5 tilt10,pusher" --seeds 4

This is a benchmark, not a test: it asserts nothing and writes nothing.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import defaultdict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pybullet as p  # noqa: E402
from fidelity import FAMILIES, G, World, _client, run_one  # noqa: E402

from bullet_boxccd import BoxCCD, _core  # noqa: E402
from bullet_boxccd.pybullet_ccd import _hooks  # noqa: E402

_SWEEPER_METHODS = ("put_twists", "put_poses", "fast", "velocities_at", "rows", "touches", "at_speed")


class _Clock:
    """Wraps pybullet's functions (as the plugin calls them) and the core's, summing the
    time spent in each group while ``on``."""

    def __init__(self):
        self.on, self.spent, self.calls = False, defaultdict(int), defaultdict(int)
        self._undo = []
        self.overhead = self._calibrate()
        for name, fn in vars(_hooks.raw).items():
            self._wrap(_hooks.raw, name, fn, "pybullet")
        for name in dir(_core):
            fn = getattr(_core, name)
            if callable(fn) and not isinstance(fn, type) and not name.startswith("_"):
                self._wrap(_core, name, fn, "core")
        for name in _SWEEPER_METHODS:
            self._wrap(_core.Sweeper, name, getattr(_core.Sweeper, name), "core")

    def _wrap(self, owner, name, fn, group):
        clock = time.perf_counter_ns

        def timed(*args, **kwargs):
            if not self.on:
                return fn(*args, **kwargs)
            t0 = clock()
            try:
                return fn(*args, **kwargs)
            finally:
                self.spent[group] += clock() - t0
                self.calls[group] += 1

        setattr(owner, name, timed)
        self._undo.append((owner, name, fn))

    def _calibrate(self, n=20000):
        """ns a wrapped call costs outside its timed part (what the run adds to ``python``)."""
        holder = type("Holder", (), {"noop": staticmethod(len)})
        self._wrap(holder, "noop", len, "calibration")
        args, clock = ((),), time.perf_counter_ns
        self.on = True
        best = []
        for fn in (len, holder.noop):
            t0 = clock()
            for _ in range(n):
                fn(*args)
            best.append(clock() - t0)
        self.on = False
        self._undo.pop()
        inside = self.spent.pop("calibration") / n
        self.calls.pop("calibration")
        return max((best[1] - best[0]) / n - inside, 0.0)

    def restore(self):
        for owner, name, fn in self._undo:
            setattr(owner, name, fn)


def _build(fam_key, variant, seed, cid):
    fam = FAMILIES[fam_key]
    p.resetSimulation(physicsClientId=cid)
    p.setPhysicsEngineParameter(fixedTimeStep=fam.dt, numSubSteps=0, physicsClientId=cid)
    p.setGravity(0, 0, -G, physicsClientId=cid)
    w = World(cid, fam.dt, fam.dt)
    rng = np.random.default_rng([list(FAMILIES).index(fam_key), fam.variants.index(variant), seed])
    return fam, w, fam.build(w, rng, variant)


def _kind(k, stats, before):
    partial = stats.partial_steps - before[0]
    if k == 0:
        return "first"
    if partial:
        return f"back x{partial}" if partial < 4 else "back x4+"
    return "swept" if stats.swept_boxes > before[1] else "not fast"


def run_seed(fam_key, variant, seed, cid, clock=None):
    """{kind: [(microseconds of the step, of its pybullet calls, of its core calls), ...]} over the
    seed's steps."""
    fam, w, s = _build(fam_key, variant, seed, cid)
    control = getattr(s, "control", None)
    ccd = BoxCCD(cid)
    out = defaultdict(list)
    for k in range(s.steps):
        if control:
            control(w, s, k * fam.dt, fam.dt)
        before = (ccd.stats.partial_steps, ccd.stats.swept_boxes)
        if clock is not None:
            clock.spent.clear()
            clock.calls.clear()
            clock.on = True
        t0 = time.perf_counter_ns()
        ccd.step()
        us = (time.perf_counter_ns() - t0) / 1e3
        if clock is not None:
            clock.on = False
        spent = clock.spent if clock is not None else {}
        wrappers = sum(clock.calls.values()) * clock.overhead if clock is not None else 0.0
        out[_kind(k, ccd.stats, before)].append((us - wrappers / 1e3, spent.get("pybullet", 0) / 1e3,
                                                 spent.get("core", 0) / 1e3))
        w.t = (k + 1) * fam.dt
        fam.observe(w, s, k)
    return out


def report(fam_key, variant, seeds, cid, repeats):
    fam = FAMILIES[fam_key]
    bare = defaultdict(list)
    for seed in range(seeds):
        runs = [run_seed(fam_key, variant, seed, cid) for _ in range(repeats)]
        for kind in runs[0]:  # the same seed steps alike every run: the fastest of each step
            bare[kind] += [min(r[kind][i][0] for r in runs) for i in range(len(runs[0][kind]))]
    clock = _Clock()
    try:
        parts = defaultdict(list)
        for seed in range(seeds):
            for kind, rows in run_seed(fam_key, variant, seed, cid, clock).items():
                parts[kind] += rows
    finally:
        clock.restore()
    base = {m: np.mean([min(run_one(fam_key, variant, s, m, 0.0, cid)[1] for _ in range(repeats))
                        for s in range(seeds)]) for m in ("plain", "sub16")}
    total = sum(sum(v) for v in bare.values())
    n_steps = sum(len(v) for v in bare.values())
    print(f"\n{fam.label} ({variant}), {seeds} seeds, dt = {fam.dt:.4g} s: BoxCCD {total / n_steps:.1f} us a step "
          f"(x{total / n_steps / base['plain']:.1f} plain), plain {base['plain']:.1f}, "
          f"numSubSteps=16 {base['sub16']:.1f} (x{base['sub16'] / base['plain']:.1f})")
    print(f"  {'step':10s} {'steps':>6s} {'us':>9s} {'share':>6s} {'pybullet':>9s} {'core':>6s} {'python':>7s} "
          f"{'floor us':>9s}")
    order = ["first", "not fast", "swept", "back x1", "back x2", "back x3", "back x4+"]
    floor_total = 0.0
    for kind in sorted(bare, key=order.index):
        t, pb, core = np.array(parts[kind]).sum(axis=0)
        floor = np.sum(bare[kind]) * (pb + core) / t
        floor_total += floor
        print(f"  {kind:10s} {len(bare[kind]):6d} {np.mean(bare[kind]):9.1f} {np.sum(bare[kind]) / total:6.0%} "
              f"{pb / t:9.0%} {core / t:6.0%} {1 - (pb + core) / t:7.0%} {floor / len(bare[kind]):9.1f}")
    floor = floor_total / n_steps
    print(f"  floor, every step: {floor:.1f} us a step (x{floor / base['plain']:.1f} plain)")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--families", default="head_on:e=1 straight,head_on:e=1 spin20,spinning,rain:48,rain:1000",
                    help="family[:variant], comma-separated (variant: the family's first by default)")
    ap.add_argument("--seeds", type=int, default=4, help="seeds per family (rain 1000: one)")
    ap.add_argument("--repeats", type=int, default=3, help="untimed-inside runs per seed; each step's fastest counts")
    args = ap.parse_args(argv)
    cid = _client()
    for item in args.families.split(","):
        fam_key, _, variant = item.partition(":")
        variant = variant or FAMILIES[fam_key].variants[0]
        big = variant.isdigit() and int(variant) > 100
        report(fam_key, variant, 1 if big else args.seeds, cid, 1 if big else args.repeats)


if __name__ == "__main__":
    main()
