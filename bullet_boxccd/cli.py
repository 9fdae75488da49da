"""The ``boxccd`` console command (also ``python -m bullet_boxccd``).

    boxccd demo wall|plank|bullets|rain|solver [demo options]   run a headless demo
    boxccd demo --list                                            list the demos
    boxccd toi case.json                                          solve one case from JSON
    boxccd validate [--queries N] [--families F ...] [--seed S] [--workers W] [--address A] [--report FILE]
                                                                  randomized queries, independently checked
    boxccd sweep [--boxes N ...] [--trials T] [--workers W] [--address A] [--report FILE]
                                                                  the plugin's trade-off grid (benchmarks/tradeoff.py)

A case file holds ``lo_a``, ``hi_a``, ``coeffs_a``, ``lo_b``, ``hi_b``, ``coeffs_b``
(nested lists, as for ``time_of_impact``) and optionally ``t_range``; ``validate``
writes its failures in that format (with what it found, which ``toi`` ignores).
``validate`` and ``sweep`` run on Ray (``pip install ".[scale]"``): a local Ray on this
machine's cores, or the cluster at ``--address``; ``--workers 0`` runs in this process.
"""

from __future__ import annotations

import argparse
import json
import runpy
import sys
from pathlib import Path

DEMOS = {
    "wall": ("thin_wall.py", "a fast cube against a thin static wall"),
    "plank": ("spinning_plank.py", "a plank spinning at 200 rad/s next to a cube"),
    "bullets": ("two_bullets.py", "two fast cubes head-on and crossing"),
    "rain": ("box_rain.py", "pybullet_data lego/jenga pieces thrown fast in a tray"),
    "solver": ("solver_contact.py", "the solver on a seed-style example"),
}


def demo_dir() -> Path:
    """Installed demos (the wheel carries them) or, in a source checkout, ../demos."""
    here = Path(__file__).resolve().parent
    for d in (here / "demos", here.parent / "demos"):
        if (d / "thin_wall.py").exists():
            return d
    raise FileNotFoundError("the demo scripts are not installed next to bullet_boxccd")


def run_demo(name: str, args) -> None:
    script = demo_dir() / DEMOS[name][0]
    saved, sys.argv = sys.argv, [str(script), *args]
    try:
        runpy.run_path(str(script), run_name="__main__")
    finally:
        sys.argv = saved


def solve_case(path: str) -> None:
    from . import Box, QuadraticMotion, time_of_impact

    case = json.loads(Path(path).read_text())
    c = time_of_impact(Box(case["lo_a"], case["hi_a"]), QuadraticMotion(case["coeffs_a"]),
                       Box(case["lo_b"], case["hi_b"]), QuadraticMotion(case["coeffs_b"]),
                       tuple(case.get("t_range", (0.0, 1.0))))
    if c is None:
        print(json.dumps({"hit": False}))
    else:
        print(json.dumps({"hit": True, "t": c.t, "initial": c.initial, "point": c.point.tolist(),
                          "normal": c.normal.tolist(), "feature": c.feature._asdict()}, indent=2))


def _count(text: str) -> int:
    """An integer, also written as 1e7."""
    v = float(text)
    if not v.is_integer():
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text}")
    return int(v)


def _at_least(low: int):
    def parse(text: str) -> int:
        v = _count(text)
        if v < low:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {low}, got {text}")
        return v

    return parse


def _families(values) -> list:
    from .validate.families import FAMILIES

    names = [f for v in values for f in v.split(",") if f]
    bad = [f for f in names if f not in FAMILIES]
    if bad:
        raise SystemExit(f"boxccd validate: unknown families {bad}; expected some of: {', '.join(FAMILIES)}")
    return names


def _distributed(p) -> None:
    p.add_argument("--workers", type=_at_least(0), default=None,
                   help="tasks at a time (default: every CPU of the local Ray or of the cluster); 0: in this "
                        "process, without Ray")
    p.add_argument("--address", default=None,
                   help='join this Ray cluster ("auto", "HOST:6379", or "ray://HOST:10001"); default: a local Ray')
    p.add_argument("--report", default=None, help="JSON-lines report: appended as work finishes, resumed from")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def run_validate(args) -> int:
    from .validate.shards import last_line, summary_table, validate

    summary, run = validate(args.queries, _families(args.families) if args.families else None, args.seed,
                            args.workers, args.address, args.report, args.cases, args.shard_size,
                            show_progress=not args.no_progress)
    print(summary_table(summary))
    t = summary["total"]
    if run["queries_run"]:
        where = "in this process" if args.workers == 0 and not args.address else "on Ray"
        print(f"\n{run['queries_run']:,} queries run now in {run['seconds']:.1f} s "
              f"({run['queries_run'] / run['seconds']:,.0f} queries/s, {where})")
    if t["queries"] > run["queries_run"]:
        print(f"{t['queries'] - run['queries_run']:,} queries taken from {args.report}")
    if (summary.failures or t["unresolved"] or t["early"]) and Path(run["cases_dir"]).is_dir():
        print(f"case files of the failures (and of up to 20 unresolved and 20 early answers per shard and family): "
              f"{run['cases_dir']}/ (boxccd toi FILE)")
    print(last_line(summary))
    return 1 if summary.failures else 0


def run_sweep(args) -> int:
    from .validate.sweep import summary_text, sweep, write_outputs

    rows, tunnels, meta = sweep(args.boxes, args.seed, args.trials, args.window, args.quick, args.workers,
                                args.address, args.report, show_progress=not args.no_progress)
    print(summary_text(rows, tunnels, meta))
    written = write_outputs(rows, args.csv, args.png, args.boxes)
    where = "in this process" if args.workers == 0 and not args.address else "on Ray"
    n_cfg = len(rows) // len(args.boxes)
    print(f"\nwritten: {', '.join(written)}")
    print(f"swept {n_cfg} configurations x {len(args.boxes)} scenes x {meta['trials']} seeds: {meta['tasks_run']} "
          f"trials run now in {meta['seconds']:.0f} s ({where})")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="boxccd", description="Exact box CCD for pybullet.")
    sub = ap.add_subparsers(dest="command", required=True)
    d = sub.add_parser("demo", help="run a headless demo (it asserts its outcome and saves a PNG)")
    d.add_argument("name", nargs="?", choices=sorted(DEMOS))
    d.add_argument("--list", action="store_true", help="list the demos")
    t = sub.add_parser("toi", help="time of impact of one case from a JSON file")
    t.add_argument("case")
    v = sub.add_parser("validate", help="seeded randomized queries, solved and checked by an independent checker; "
                                        "exit status 1 if any fails")
    v.add_argument("--queries", type=_at_least(1), default=100_000, help="how many (default 1e5)")
    from .validate.families import FAMILIES

    v.add_argument("--families", nargs="+", default=None,
                   help=f"query families, space or comma separated (default: all): {', '.join(FAMILIES)}")
    v.add_argument("--seed", type=int, default=0)
    v.add_argument("--shard-size", type=_at_least(1), default=10_000, help="queries per task (default 1e4)")
    v.add_argument("--cases", default=None, help="directory for failing cases (default: next to the report, "
                                                 "else ./boxccd_cases)")
    _distributed(v)
    w = sub.add_parser("sweep", help="the plugin's trade-off grid (benchmarks/tradeoff.py): every (configuration, "
                                     "scene, seed) a task in its own pybullet client; CSV and Pareto plot")
    w.add_argument("--boxes", type=_at_least(5), nargs="+", default=[100],
                   help="scenes: dynamic boxes in each, 4 of them projectiles (default 100)")
    w.add_argument("--seed", type=int, default=2024, help="first seed (trials use seed, seed + 1, ...)")
    w.add_argument("--trials", type=_at_least(1), default=None, help="seeds per scene (default 10; 2 with --quick)")
    w.add_argument("--window", type=_at_least(1), default=None, help="steps per trial (default 120; 72 with --quick)")
    w.add_argument("--quick", action="store_true", help="fewer configurations, 2 trials of 72 steps")
    w.add_argument("--csv", default="tradeoff.csv")
    w.add_argument("--png", default="tradeoff.png", help="the Pareto plot (one per scene: _<boxes> before the "
                                                          "suffix when there are several)")
    _distributed(w)
    args, rest = ap.parse_known_args(argv)
    if args.command == "demo":
        if args.list or not args.name:
            for k, (f, what) in DEMOS.items():
                print(f"{k:8s} {what}  ({f})")
            return 0
        run_demo(args.name, rest)
    if args.command != "demo" and rest:
        ap.error(f"unrecognized arguments: {' '.join(rest)}")
    if args.command == "toi":
        solve_case(args.case)
    elif args.command == "validate":
        return run_validate(args)
    elif args.command == "sweep":
        return run_sweep(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
