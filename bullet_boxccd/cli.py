"""The ``boxccd`` console command (also ``python -m bullet_boxccd``).

    boxccd demo wall|plank|bullets|rain|solver [demo options]   run a headless demo
    boxccd demo --list                                            list the demos
    boxccd toi case.json                                          solve one case from JSON

A case file holds ``lo_a``, ``hi_a``, ``coeffs_a``, ``lo_b``, ``hi_b``, ``coeffs_b``
(nested lists, as for ``time_of_impact``) and optionally ``t_range``.
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="boxccd", description="Exact box CCD for pybullet.")
    sub = ap.add_subparsers(dest="command", required=True)
    d = sub.add_parser("demo", help="run a headless demo (it asserts its outcome and saves a PNG)")
    d.add_argument("name", nargs="?", choices=sorted(DEMOS))
    d.add_argument("--list", action="store_true", help="list the demos")
    t = sub.add_parser("toi", help="time of impact of one case from a JSON file")
    t.add_argument("case")
    args, rest = ap.parse_known_args(argv)
    if args.command == "demo":
        if args.list or not args.name:
            for k, (f, what) in DEMOS.items():
                print(f"{k:8s} {what}  ({f})")
            return 0
        run_demo(args.name, rest)
    elif args.command == "toi":
        if rest:
            ap.error(f"unrecognized arguments: {' '.join(rest)}")
        solve_case(args.case)
    return 0


if __name__ == "__main__":
    sys.exit(main())
