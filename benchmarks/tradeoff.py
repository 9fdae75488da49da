"""Cost / accuracy trade-off of the BoxCCD plugin's knobs, beside substepping and native CCD.

What it measures
----------------
The scene and the shots are those of ``benchmarks/plugin.py`` (both import them from
``bullet_boxccd.pybullet_ccd.tradeoff.scenes``): ``--boxes`` dynamic 0.1 m cubes (default 100: a
settled pile of 96 plus 4 projectiles) over a static ground (top face z = 0) and a static 1 cm wall (plane
x = 0); per seeded trial 2 projectiles are fired at the wall and 2 down at the
ground at 50..150 m/s with a random spin (``scenes.shots(seed)``), and a window of
``--window`` steps of 1/240 s (default 120) is run. Every trial is a task
of its own: the scene is built and settled in a new pybullet client, then the seeded
shots are fired, so every configuration sees the same settled pile and the same shots;
tasks run seeds outer, configurations inner (a burst of load from elsewhere hits all).
The grid, the task and the outputs live in ``bullet_boxccd.pybullet_ccd.tradeoff.grid``: this program
runs them in this process; ``boxccd sweep`` runs the same tasks on Ray (or in-process with
``--workers 0``) and writes the same CSV and plot from the same seeds (all but the
timing columns are equal; ``tests/test_sweep.py`` checks it).

Configurations (one knob at a time around the default):

* ``BoxCCD default`` (sweep_threshold 0.25, sweep_distance 0.01 m, fit_tolerance 0.05,
  penetration 1e-5 m, impact_depth 1e-3 m, depth_tolerance 1e-3 m, max_partial_steps 8),
* ``sweep_threshold`` 0.05, 0.5, 1, 2, 4, 8 (a box is swept when its fastest point
  moves more than this fraction of its smallest extent per step; the projectiles
  move 2..6.3 extents per step, so 4 sweeps only the faster shots and 8 none),
* ``fit_tolerance`` 0.005, 0.5 (rotation fit split into 2, 4, .. pieces until its
  error is below this fraction of the smallest half extent),
* ``penetration`` (the overlap by which a touching pair presses in or parts) 1e-6, 1e-4 m,
* ``impact_depth`` (the overlap an impact is resolved at, at most a quarter of the thinner
  box) 1e-5, 1e-4 m,
* ``depth_tolerance`` 1e-4, 1e-2 m (a contact met inside a step that ends shallower is
  pybullet's),
* ``max_partial_steps`` 0, 2 (0: the bodies of such a contact go back to it on their own
  and the step ends; pybullet resolves the impact at the next step),
* ``reference`` = BoxCCD with fit_tolerance 1e-4 (the fine reference of the
  contact times; itself in the table),
* pybullet ``plain``, ``substeps`` 2, 4, 8, 16, 32 (``numSubSteps``), and, on the same
  scene built with maximal coordinates, ``plain (maximal)`` and ``native CCD
  (maximal)`` (``ccdSweptSphereRadius`` 0.025, ``contactProcessingThreshold`` 0, as
  in plugin.py).

Metrics per configuration:

* ``us/step``: per trial the mean wall time of a step over the window (only the
  step: the checks below are untimed), then the median over trials,
* ``tunneled/shots``: plugin.py's test (centre below the ground, or through the
  wall's face and beyond it, at the end of the window),
* contact-time error (BoxCCD only): for each projectile its first CCD event against
  the ground or the wall that begins inside the step (``not ev.initial``), at time
  step index * dt + ``ev.time``, against the same projectile's first such event in
  the reference run of the same seed; median and max |dt| in seconds over the
  projectiles both runs report within one step (1/240 s) of each other, and
  ``matched/ref`` (a configuration that does not sweep a shot reports no event for
  it, or only a later contact, which is not matched),
* rewind pose error (``max_partial_steps`` 0 only, where a step ends at its
  contacts): right after each ``ccd.step()`` returning a rewound first-touch event of
  a projectile against the ground or wall, ``p.getClosestPoints(body_a, body_b, 0.01,
  link_a, link_b)`` minimum distance; the worst (largest |d|) is reported, and how
  many fall outside the expected band [-0.001 - 1e-6, 0.001 + 1e-6] m (at most the
  impact depth deep, at most the collision margin 0.001 apart),
* end-of-step penetration (all configurations): after every step, the minimum
  ``p.getClosestPoints(projectile, ground or wall, 0)`` distance over the
  projectiles; the deepest (most negative) value over all steps and trials. For
  substeps / native CCD this is their "pose error"; a tunneling configuration can
  show little here, since a box that is already through is no longer inside.
* ``pieces/pair``: the plugin's ``solver_rows / candidate_pairs`` (how many fit pieces
  the rotation tolerance asked for), summed over the trials' BoxCCD instances.

Reading it: the reported contact time comes from a refit of Bullet's exact path
over the window the conservative fit found, so ``fit_tolerance`` changes the cost
and how many pieces are solved, not the answer. A contact that ends a step shallower
than ``depth_tolerance`` is pybullet's, which bounds what the end-of-step penetration
of BoxCCD can show.

Outputs: a markdown table (stdout), ``benchmarks/results/tradeoff.csv`` and
``docs/tradeoff.png`` (Pareto plots, x = us/step, log: left the tunneling rate,
middle the deepest end-of-step penetration, right the max contact-time error of
the BoxCCD configurations; the grey staircase is the Pareto front; the default is
the star; points carry the configuration's number, listed beside the plots).
Every BoxCCD tunneled projectile is printed with its seed and configuration, and
its launch reach (|v| dt / extent, what ``sweep_threshold`` is compared with).

Run
---
    python benchmarks/tradeoff.py            # < 8 min (210 trials, each builds its scene)
    python benchmarks/tradeoff.py --quick    # < 1 min

Options: ``--seed`` (default 2024), ``--trials`` (default 10; 2 with --quick),
``--window`` (default 120; 72 with --quick: the impacts come by step 61),
``--boxes`` (default 100), ``--csv``, ``--png``. The machine may carry other load:
read the medians. This is a benchmark, not a test: it asserts nothing about timings.
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _report import code_version  # noqa: E402  (the commit measured)

from bullet_boxccd.pybullet_ccd.tradeoff.grid import summary_text, sweep, write_outputs  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help="2 trials of 72 steps; sweep_threshold 0.05, 1, 4, 8 only; substeps 2, 8, 32 only")
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--trials", type=int, default=None)
    ap.add_argument("--window", type=int, default=None)
    ap.add_argument("--boxes", type=int, default=100)
    ap.add_argument("--csv", default=os.path.join(HERE, "results", "tradeoff.csv"))
    ap.add_argument("--png", default=os.path.join(ROOT, "docs", "tradeoff.png"))
    args = ap.parse_args(argv)
    print(f"code: {code_version()}")
    rows, tunnels, meta = sweep([args.boxes], args.seed, args.trials, args.window, args.quick, workers=0)
    print(f"{args.boxes} boxes, {meta['trials']} trials (seeds {meta['seeds'][0]}..{meta['seeds'][-1]}), window "
          f"{meta['window']} steps of 1/240 s, 4 projectiles per trial")
    print(summary_text(rows, tunnels, meta))
    written = write_outputs(rows, args.csv, args.png, [args.boxes])
    print(f"\nwritten: {', '.join(written)} (runs took {meta['seconds']:.0f} s)")


if __name__ == "__main__":
    main()
