"""The ``boxccd`` console command (also ``python -m bullet_boxccd``).

    boxccd demo wall|plank|bullets|rain|solver [demo options]   run a headless demo (boxccd demo NAME --help)
    boxccd demo --list                                            list the demos
    boxccd toi case.json                                          solve one case from JSON (boxccd toi --help)
    boxccd validate [--queries N] [--families F ...] [--seed S] [--workers W] [--address A] [--report FILE]
                                                                  randomized queries, independently checked
    boxccd sweep [--boxes N ...] [--trials T] [--workers W] [--address A] [--report FILE]
                                                                  the plugin's trade-off grid (benchmarks/tradeoff.py)
    boxccd --version

A case file holds ``lo_a``, ``hi_a``, ``coeffs_a``, ``lo_b``, ``hi_b``, ``coeffs_b``
(nested lists, as for ``time_of_impact``) and optionally ``t_range``; ``validate``
writes its failures in that format (with what it found, which ``toi`` ignores).
``validate`` and ``sweep`` run on Ray (``pip install ".[scale]"`` from the checkout): a
local Ray on the local machine's cores, or the cluster at ``--address``; ``--workers 0`` runs
in this process. They check for their extras before any work.

Each demo declares its options in a module-level ``OPTIONS`` dict literal
(``name: (default, help)``), read here without running the script, so that
``boxccd demo NAME --help`` lists them.
"""

from __future__ import annotations

import argparse
import ast
import importlib.util
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

# validate and sweep need these (the scale extra); the package is not on an index.
SCALE_INSTALL = 'pip install ".[scale]"'


def _fail(command: str, message: str) -> None:
    """A usage error in one line on stderr, exit status 2 (as argparse's own)."""
    print(f"boxccd {command}: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("bullet_boxccd")
    except PackageNotFoundError:
        return "unknown (not installed)"


def demo_dir() -> Path:
    """Installed demos (the wheel carries them) or, in a source checkout, ../demos."""
    here = Path(__file__).resolve().parent
    for d in (here / "demos", here.parent / "demos"):
        if (d / "thin_wall.py").exists():
            return d
    raise FileNotFoundError("the demo scripts are not installed next to bullet_boxccd")


def demo_spec(name: str) -> tuple:
    """A demo's docstring and ``OPTIONS`` (``{name: (default, help)}``), read from its
    source without running it (no pybullet, no matplotlib: ``boxccd --help`` stays fast)."""
    try:
        tree = ast.parse((demo_dir() / DEMOS[name][0]).read_text())
    except FileNotFoundError:  # no demos here: the other commands still work, `boxccd demo` says why
        return DEMOS[name][1], {}
    options = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "OPTIONS" for t in node.targets):
            options = ast.literal_eval(node.value)
    return ast.get_docstring(tree) or DEMOS[name][1], options


def _positive(kind):
    def parse(text: str):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {'a whole' if kind is int else 'a'} number, got {text!r}") \
                from None
        if not 0 < v < float("inf"):
            raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
        return v

    parse.__name__ = kind.__name__  # argparse names the type in its messages
    return parse


def add_demo_options(parser, options: dict) -> None:
    """A demo's options (``{name: (default, help)}``, each a positive int or float typed
    by its default) and ``--out``, on ``parser``: shared by ``boxccd demo NAME`` and the
    scripts themselves (``python demos/thin_wall.py --help``)."""
    for name, (default, text) in options.items():
        parser.add_argument(f"--{name}", type=_positive(type(default)), default=default, metavar=name.upper(),
                            help=f"{text} (default: {default:g})")
    parser.add_argument("--out", default="demo_output", metavar="DIR",
                        help="directory the demo's PNG is written to (default: demo_output)")


def run_demo(name: str, args) -> None:
    script = demo_dir() / DEMOS[name][0]
    saved, sys.argv = sys.argv, [str(script), *args]
    try:
        runpy.run_path(str(script), run_name="__main__")
    finally:
        sys.argv = saved


CASE_FORMAT = """\
A case file is one JSON object (the format boxccd validate writes its failures in):

  "lo_a", "hi_a"  box A's corners in its own frame: [x, y, z] each, lo < hi
  "coeffs_a"      A's motion, 3 x 4 x 4 numbers [C0, C1, C2]: at time t its pose is
                  the 4 x 4 matrix C0 + C1 t + C2 t^2 (rotation and translation;
                  a static box at its own frame: C0 = identity, C1 = C2 = zeros)
  "lo_b", "hi_b", "coeffs_b"  the same for box B
  "t_range"       optional [t0, t1], default [0, 1]

Other keys (solver_t, verdict, ... written by validate) are ignored. Prints JSON:
{"hit": false}, or the first contact's t, initial, point, normal (from A towards B)
and feature. A file that cannot be read or does not hold such a case: exit status 2."""

_CASE_SHAPES = {"lo_a": (3,), "hi_a": (3,), "coeffs_a": (3, 4, 4), "lo_b": (3,), "hi_b": (3,), "coeffs_b": (3, 4, 4)}


def read_case(path: str) -> dict:
    """The case file's geometry as float arrays, or a one-line usage error."""
    import numpy as np

    try:
        text = Path(path).read_text()
    except (OSError, UnicodeDecodeError) as e:
        _fail("toi", f"cannot read {path}: {getattr(e, 'strerror', None) or e}")
    try:
        case = json.loads(text)
    except json.JSONDecodeError as e:
        _fail("toi", f"{path} is not JSON: {e}")
    if not isinstance(case, dict):
        _fail("toi", f"{path}: expected a JSON object with {', '.join(_CASE_SHAPES)}, got a {type(case).__name__}")
    missing = [k for k in _CASE_SHAPES if k not in case]
    if missing:
        _fail("toi", f"{path}: no {', '.join(missing)} (a case holds {', '.join(_CASE_SHAPES)}; see boxccd toi --help)")
    out = {}
    for k, shape in {**_CASE_SHAPES, "t_range": (2,)}.items():
        try:
            a = np.asarray(case.get(k, (0.0, 1.0)), dtype=float)
        except (TypeError, ValueError):
            _fail("toi", f"{path}: {k} must hold numbers, expected shape {shape}")
        if a.shape != shape:
            _fail("toi", f"{path}: {k} has shape {a.shape}, expected {shape}")
        out[k] = a
    return out


def solve_case(path: str) -> None:
    from . import Box, InvalidInputError, QuadraticMotion, time_of_impact

    case = read_case(path)
    try:
        c = time_of_impact(Box(case["lo_a"], case["hi_a"]), QuadraticMotion(case["coeffs_a"]),
                           Box(case["lo_b"], case["hi_b"]), QuadraticMotion(case["coeffs_b"]),
                           tuple(case["t_range"]))
    except InvalidInputError as e:
        _fail("toi", f"{path}: {e}")
    if c is None:
        print(json.dumps({"hit": False}))
    else:
        print(json.dumps({"hit": True, "t": c.t, "initial": c.initial, "point": c.point.tolist(),
                          "normal": c.normal.tolist(), "feature": c.feature._asdict()}, indent=2))


def _installed(module: str) -> bool:
    if module in sys.modules:
        return sys.modules[module] is not None  # None: imports of it fail
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def check_extras(command: str, args) -> None:
    """Before any work: the modules this run will import (Ray unless it runs in this
    process, mpmath for validate's checker, matplotlib for sweep's plot); a missing one
    is a one-line error naming the install command. Without tqdm there is no progress
    bar: a one-line note."""
    need = ["ray"] if args.workers != 0 or args.address else []
    need += ["mpmath"] if command == "validate" else ["matplotlib"]
    missing = [m for m in need if not _installed(m)]
    if missing:
        hint = " (or --workers 0 to run in this process without Ray)" if missing == ["ray"] else ""
        _fail(command, f"needs {' and '.join(missing)}, not installed: {SCALE_INSTALL} in the bullet_boxccd "
                       f"checkout{hint}")
    if not args.no_progress and not _installed("tqdm"):
        print(f"boxccd {command}: no progress bar, tqdm is not installed ({SCALE_INSTALL} in the checkout)",
              file=sys.stderr)


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
        _fail("validate", f"unknown families {bad}; expected some of: {', '.join(FAMILIES)}")
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

    summary, run = validate(args.queries, args.families, args.seed,
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
    from .pybullet_ccd.tradeoff.grid import summary_text, sweep, write_outputs

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
    ap.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = ap.add_subparsers(dest="command", required=True)
    d = sub.add_parser("demo", help="run a headless demo (it asserts its outcome and saves a PNG)",
                       description="Run a headless demo: it prints a table, asserts its outcome and saves a PNG "
                                   "(plain pybullet and BoxCCD side by side). boxccd demo NAME --help: its options.")
    d.add_argument("--list", action="store_true", help="list the demos")
    names = d.add_subparsers(dest="name", metavar="NAME", title="demos")
    for name, (_, what) in DEMOS.items():
        doc, options = demo_spec(name)
        n = names.add_parser(name, help=what, description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
        add_demo_options(n, options)
        n.set_defaults(demo_options=[*options, "out"])
    t = sub.add_parser("toi", help="time of impact of one case from a JSON file (boxccd toi --help: the format)",
                       description="Solve one case: the first contact of two boxes under quadratic motions.",
                       epilog=CASE_FORMAT, formatter_class=argparse.RawDescriptionHelpFormatter)
    t.add_argument("case", help="the case file (JSON)")
    v = sub.add_parser("validate", help="seeded randomized queries, solved and checked by an independent checker; "
                                        "exit status 1 if any fails",
                       epilog=f"Needs the scale extra ({SCALE_INSTALL} in the checkout; Ray only without --workers 0).")
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
                                     "scene, seed) a task in its own pybullet client; CSV and Pareto plot",
                       epilog=f"Needs the scale extra ({SCALE_INSTALL} in the checkout; Ray only without --workers 0).")
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
    args = ap.parse_args(argv)
    if args.command == "demo":
        if args.list or not args.name:
            for k, (f, what) in DEMOS.items():
                print(f"{k:8s} {what}  ({f})")
            return 0
        # The script parses its options again (it also runs on its own): hand them on as parsed.
        run_demo(args.name, [x for k in args.demo_options for x in (f"--{k}", str(getattr(args, k)))])
    elif args.command == "toi":
        solve_case(args.case)
    elif args.command == "validate":
        args.families = _families(args.families) if args.families else None
        check_extras("validate", args)
        return run_validate(args)
    elif args.command == "sweep":
        check_extras("sweep", args)
        return run_sweep(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
