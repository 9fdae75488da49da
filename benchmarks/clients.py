"""Real clients: pybullet's own gym envs and example scripts, run unedited with every
``stepSimulation`` routed through ``BoxCCD.step()``, against plain pybullet.

For each client and seed, three fresh interpreters (benchmarks/_clients_run.py), one
after the other:

* ``bare``: pybullet alone (bullet_boxccd never imported): the reference trajectory,
* ``plain``: bullet_boxccd imported, its hooks installed; each stepSimulation timed
  around pybullet's own function. Its trajectory must equal bare's bit for bit (the
  hooks change nothing, and the client is deterministic with these seeds),
* ``ccd``: each stepSimulation of client c after the env's first reset (a script: from
  its first step) goes to the ``BoxCCD(c).step()`` made for c; timed around that call.

Same seeds (``random``, ``np.random``, ``env.seed``), same actions
(``np.random.default_rng(seed)``). Reported per client: steps (env steps; stepSimulation
calls in brackets where more), the largest |difference| between the bare and BoxCCD
observations (envs) and of all bodies' base poses and link frames (both), with the
first step that differs; BoxCCD's rewinds, partial steps, contacts and swept boxes; every
BoxCCDWarning; the median wall time per stepSimulation call, plain and BoxCCD, and
their ratio (median over the seeds of each seeded run's ratio of medians), and the same ratio
over the steps where BoxCCD swept no box (nothing fast); for envs, the median env.step
with pybullet alone (bare) and with BoxCCD (hooks and BoxCCD steps: what an RL loop
pays); BoxCCD's own breakdown (``ccd.stats.seconds`` per step).

    python benchmarks/clients.py            # 1000 env steps (fewer where noted), 3 seeds
    python benchmarks/clients.py --quick    # the short horizons of CLIENTS, 1 seed
    python benchmarks/clients.py --clients KukaBulletEnv-v0 snake.py --seeds 1 --steps 100
    python benchmarks/clients.py --profile-dir /tmp/prof --clients CartPoleBulletEnv-v1
    python benchmarks/clients.py --where --clients MinitaurBulletEnv-v0 --steps 300   # BoxCCD's callees

Writes benchmarks/results/clients.csv (--quick: clients_quick.csv).
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402
from _clients_run import CLIENTS, Env, compare, run_subprocess  # noqa: E402

PHASES = ("step", "state", "broad_phase", "solve", "rewind")


def run_client(name, steps, seeds, timeout, profile_dir=None, workdir=None, log=print):
    """The three variants of one client for each seed, compared; one row."""
    spec = CLIENTS[name]
    row = {"client": name, "kind": "env" if isinstance(spec, Env) else "script", "seeds": len(seeds),
           "steps": steps, "errors": [], "warnings": {}, "first_diff": "", "plain_vs_bare": 0.0}
    ratios, plain_med, ccd_med, sim_steps, ccd_ns = [], [], [], [], []
    env_bare, env_ccd, env_ratios = [], [], []
    quiet_ratios, quiet_share, quiet_plain, quiet_ccd = [], [], [], []
    totals = {k: 0 for k in ("rewinds", "partial_steps", "contacts", "swept_boxes", "tracked_boxes", "steps",
                             "candidate_pairs", "pushes", "rediscoveries")}
    seconds = dict.fromkeys(PHASES, 0.0)
    obs_diff = pose_diff = 0.0
    construct = []
    for seed in seeds:
        recs = {}
        for variant in ("bare", "plain", "ccd"):
            prof = os.path.join(profile_dir, f"{name}.{seed}.prof") if profile_dir and variant == "ccd" else None
            t0 = time.perf_counter()
            recs[variant] = r = run_subprocess(name, variant, steps, seed, timeout, prof, workdir)
            log(f"  {name} seed {seed} {variant}: {time.perf_counter() - t0:.1f} s"
                + (f"  ERROR {r['error'].splitlines()[0]}" if r.get("error") else ""))
            if r.get("error"):
                row["errors"].append(f"{variant} seed {seed}: {r['error']}")
        bare, plain, ccd = recs["bare"], recs["plain"], recs["ccd"]
        if not bare.get("error") and not plain.get("error"):
            d = compare(bare, plain)
            row["plain_vs_bare"] = max(row["plain_vs_bare"], d["obs_diff"], d["pose_diff"])
        if bare.get("error") or ccd.get("error"):
            continue
        d = compare(bare, ccd)
        obs_diff, pose_diff = max(obs_diff, d["obs_diff"]), max(pose_diff, d["pose_diff"])
        firsts = [f for f in (d["obs_first"], d["pose_first"]) if f is not None]
        if firsts and not row["first_diff"]:
            row["first_diff"] = f"seed {seed} step {min(firsts)}"
        for msg, where in ccd.get("boxccd_warnings", []):
            row["warnings"].setdefault(msg, where)
        for s in ccd.get("stats", {}).values():
            for k in totals:
                totals[k] += s.get(k, 0) if k != "tracked_boxes" else 0
            totals["tracked_boxes"] = max(totals["tracked_boxes"], s.get("tracked_boxes", 0))
            for k in PHASES:
                seconds[k] += s["seconds"].get(k, 0.0)
        construct += list(ccd.get("construct_s", {}).values())
        if ccd.get("ccd_inner"):
            row["errors"].append(f"ccd seed {seed}: {ccd['ccd_inner']} router calls from inside BoxCCD.step")
        sim_steps.append(ccd.get("sim_steps", 0))
        row["env_steps"] = ccd.get("env_steps", 0)
        if plain.get("step_ns") and ccd.get("step_ns") and not plain.get("error"):
            pm, cm = statistics.median(plain["step_ns"]) / 1e3, statistics.median(ccd["step_ns"]) / 1e3
            plain_med.append(pm)
            ccd_med.append(cm)
            ratios.append(cm / pm)
        ccd_ns += ccd.get("step_ns", [])
        if bare.get("env_ns") and ccd.get("env_ns"):
            bm, cm = statistics.median(bare["env_ns"]) / 1e3, statistics.median(ccd["env_ns"]) / 1e3
            env_bare.append(bm)
            env_ccd.append(cm)
            env_ratios.append(cm / bm)
        q = _quiet(plain, ccd)
        if q is not None:
            quiet_share.append(q[0])
            if q[1] is not None:
                quiet_plain.append(q[1])
                quiet_ccd.append(q[2])
                quiet_ratios.append(q[2] / q[1])
    n = max(sum(sim_steps), 1)
    row.update(
        sim_steps=int(statistics.median(sim_steps)) if sim_steps else 0,
        obs_diff=obs_diff if row["kind"] == "env" else float("nan"), pose_diff=pose_diff,
        plain_us=statistics.median(plain_med) if plain_med else float("nan"),
        ccd_us=statistics.median(ccd_med) if ccd_med else float("nan"),
        ratio=statistics.median(ratios) if ratios else float("nan"),
        quiet_share=statistics.median(quiet_share) if quiet_share else float("nan"),
        quiet_plain_us=statistics.median(quiet_plain) if quiet_plain else float("nan"),
        quiet_ccd_us=statistics.median(quiet_ccd) if quiet_ccd else float("nan"),
        quiet_ratio=statistics.median(quiet_ratios) if quiet_ratios else float("nan"),
        ccd_mean_us=float(np.mean(ccd_ns)) / 1e3 if ccd_ns else float("nan"),
        env_bare_us=statistics.median(env_bare) if env_bare else float("nan"),
        env_ccd_us=statistics.median(env_ccd) if env_ccd else float("nan"),
        env_ratio=statistics.median(env_ratios) if env_ratios else float("nan"),
        construct_ms=1e3 * statistics.median(construct) if construct else float("nan"),
        **totals, **{f"{k}_us": 1e6 * v / n for k, v in seconds.items()})
    return row


def _quiet(plain, ccd):
    """(share of BoxCCD's steps that swept no box, plain's and BoxCCD's median us over those
    steps) — the steps where nothing is fast; the step indices of the two runs align when
    both took the same calls (None where they do not)."""
    swept, c = ccd.get("step_swept") or [], ccd.get("step_ns") or []
    if not swept or len(swept) != len(c):
        return None
    idle = [i for i, s in enumerate(swept) if s == 0]
    share = len(idle) / len(swept)
    p = plain.get("step_ns") or []
    if not idle or len(p) != len(c) or plain.get("error"):
        return share, None, None
    return share, statistics.median(p[i] for i in idle) / 1e3, statistics.median(c[i] for i in idle) / 1e3


def _fmt(x, digits=1):
    if isinstance(x, float):
        if np.isnan(x):
            return "-"
        if x == 0.0:
            return "0"
        if np.isinf(x):
            return "inf"
        return f"{x:.{digits}f}" if abs(x) >= 0.1 else f"{x:.2e}"
    return str(x)


def table(rows):
    head = ["client", "steps", "max abs obs diff", "max abs pose diff", "first diff", "rewinds", "partial",
            "contacts", "swept", "warnings", "plain us/step", "BoxCCD us/step", "ratio", "steps sweeping nothing",
            "ratio there", "env.step us: pybullet alone", "with BoxCCD", "ratio"]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for r in rows:
        steps = f"{r.get('env_steps', 0)}" + (f" ({r['sim_steps']})" if r["sim_steps"] != r.get("env_steps") else "")
        if r["errors"]:
            steps += " FAILED"
        lines.append("| " + " | ".join([
            r["client"], steps, _fmt(r["obs_diff"], 3), _fmt(r["pose_diff"], 3), r["first_diff"] or "-",
            str(r["rewinds"]), str(r["partial_steps"]), str(r["contacts"]), str(r["swept_boxes"]),
            str(len(r["warnings"])), _fmt(r["plain_us"]), _fmt(r["ccd_us"]), _fmt(r["ratio"], 2),
            f"{r['quiet_share']:.0%}" if r["quiet_share"] == r["quiet_share"] else "-",
            _fmt(r["quiet_ratio"], 2), _fmt(r["env_bare_us"]), _fmt(r["env_ccd_us"]), _fmt(r["env_ratio"], 2)])
            + " |")
    return "\n".join(lines)


def breakdown(rows):
    head = ["client", "tracked boxes", "BoxCCD() ms", "pybullet step", "state", "broad phase", "solve", "rewind",
            "sum", "BoxCCD mean us/step", "unaccounted"]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for r in rows:
        parts = [r[f"{k}_us"] for k in PHASES]
        lines.append("| " + " | ".join([r["client"], str(r["tracked_boxes"]), _fmt(r["construct_ms"])]
                                       + [_fmt(x) for x in parts]
                                       + [_fmt(sum(parts)), _fmt(r["ccd_mean_us"]),
                                          _fmt(r["ccd_mean_us"] - sum(parts)) if r["ccd_mean_us"] == r["ccd_mean_us"]
                                          else "-"])
                     + " |")
    return "\n".join(lines)


CSV_FIELDS = ["client", "kind", "seeds", "env_steps", "sim_steps", "obs_diff", "pose_diff", "first_diff",
              "plain_vs_bare", "rewinds", "partial_steps", "contacts", "swept_boxes", "tracked_boxes",
              "candidate_pairs", "pushes", "rediscoveries", "plain_us", "ccd_us", "ratio", "quiet_share",
              "quiet_plain_us", "quiet_ccd_us", "quiet_ratio", "ccd_mean_us", "env_bare_us", "env_ccd_us", "env_ratio",
              "construct_ms"] + \
             [f"{k}_us" for k in PHASES] + ["warnings", "errors"]


def where(names, steps_of, seed, timeout, workdir, top=12):
    """Where BoxCCD's time per stepSimulation call goes, per client: plain's and BoxCCD's
    mean and median, then BoxCCD's callees (pybullet functions, core functions) per call,
    and the rest (Python, and the core objects' C++ methods)."""
    out = []
    for name in names:
        plain = run_subprocess(name, "plain", steps_of(name), seed, timeout, None, workdir)
        ccd = run_subprocess(name, "ccd", steps_of(name), seed, timeout, None, workdir, categories=True)
        if plain.get("error") or ccd.get("error") or not ccd.get("step_ns"):
            out.append(f"### {name}: failed\n{plain.get('error') or ccd.get('error')}")
            continue
        n = len(ccd["step_ns"])
        pm, cm = np.mean(plain["step_ns"]) / 1e3, np.mean(ccd["step_ns"]) / 1e3
        lines = [f"### {name}: {n} stepSimulation calls",
                 f"plain: mean {pm:.1f} us, median {np.median(plain['step_ns']) / 1e3:.1f} us; BoxCCD: mean "
                 f"{cm:.1f} us, median {np.median(ccd['step_ns']) / 1e3:.1f} us (mean ratio {cm / pm:.2f})", "",
                 "| callee (means) | calls/step | us/step | share of BoxCCD |", "|---|---|---|---|"]
        g = np.asarray(ccd["step_groups"], dtype=np.float64) / 1e3
        if len(g):
            total, sim, reads, core = (np.median(g[:, k]) for k in range(4))
            py = np.median(g[:, 0] - g[:, 1:].sum(axis=1))
            lines[-3:-3] = [f"per step, medians: BoxCCD {total:.1f} us = pybullet's stepSimulation {sim:.1f} + other "
                            f"pybullet calls {reads:.1f} + core (C++) functions {core:.1f} + Python and core methods "
                            f"{py:.1f}; plain's stepSimulation {np.median(plain['step_ns']) / 1e3:.1f}"]
            swept = np.asarray(ccd.get("step_swept") or [], dtype=np.int64)
            pn = np.asarray(plain["step_ns"], dtype=np.float64) / 1e3
            if len(swept) == len(g) == len(pn):
                for label, sel in (("sweeping nothing", swept == 0), ("sweeping a box", swept > 0)):
                    if sel.any():
                        h = g[sel]
                        lines[-3:-3] = [
                            f"  steps {label} ({sel.mean():.0%}): BoxCCD {np.median(h[:, 0]):.1f} us = stepSimulation "
                            f"{np.median(h[:, 1]):.1f} + other pybullet {np.median(h[:, 2]):.1f} + core "
                            f"{np.median(h[:, 3]):.1f} + Python {np.median(h[:, 0] - h[:, 1:].sum(axis=1)):.1f}; "
                            f"plain {np.median(pn[sel]):.1f} (ratio {np.median(h[:, 0]) / np.median(pn[sel]):.2f})"]
            lines[-3:-3] = [""]
        cats = sorted(ccd["categories"].items(), key=lambda kv: -kv[1][1])
        accounted = 0.0
        for key, (calls, ns) in cats[:top]:
            us = ns / 1e3 / n
            accounted += us
            lines.append(f"| {key} | {calls / n:.2f} | {us:.1f} | {us / cm:.0%} |")
        rest = sum(ns for _, (_, ns) in cats[top:]) / 1e3 / n
        accounted += rest
        lines.append(f"| (other callees) | | {rest:.1f} | {rest / cm:.0%} |")
        lines.append(f"| Python and core methods | | {cm - accounted:.1f} | {(cm - accounted) / cm:.0%} |")
        s = ccd["stats"]
        if s:
            s = next(iter(s.values()))
            lines.append("")
            lines.append(f"stats: tracked {s['tracked_boxes']}, swept {s['swept_boxes'] / n:.2f}/step, candidate "
                         f"pairs {s['candidate_pairs'] / n:.2f}/step, contacts {s['contacts']}, rewinds "
                         f"{s['rewinds']}, partial steps {s['partial_steps']}")
        out.append("\n".join(lines))
    return "\n\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="short horizons (CLIENTS' quick), 1 seed")
    ap.add_argument("--clients", nargs="*", default=None, choices=sorted(CLIENTS), metavar="CLIENT")
    ap.add_argument("--seeds", type=int, default=None, help="seeds 0..n-1 (default 3; --quick: 1)")
    ap.add_argument("--steps", type=int, default=None, help="env steps (script: steps) for every client")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per variant run")
    ap.add_argument("--profile-dir", default=None, help="cProfile of the BoxCCD step calls, one file per run")
    ap.add_argument("--where", action="store_true",
                    help="instead of the table: where BoxCCD's time per step goes (1 seed, plain and ccd)")
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)
    names = a.clients or list(CLIENTS)
    seeds = list(range(a.seeds if a.seeds is not None else (1 if a.quick else 3)))
    out = a.out or os.path.join(HERE, "results", "clients_quick.csv" if a.quick else "clients.csv")
    if a.profile_dir:
        os.makedirs(a.profile_dir, exist_ok=True)
    rows = []

    def steps_of(name):
        spec = CLIENTS[name]
        return a.steps if a.steps is not None else (spec.quick if a.quick else spec.steps)

    if a.where:
        with tempfile.TemporaryDirectory() as work:
            print(where(names, steps_of, seeds[0], a.timeout, work))
        return 0
    with tempfile.TemporaryDirectory() as work:
        for name in names:
            steps = steps_of(name)
            print(f"{name}: {steps} steps x {len(seeds)} seeds", file=sys.stderr, flush=True)
            rows.append(run_client(name, steps, seeds, a.timeout, a.profile_dir, work,
                                   log=lambda m: print(m, file=sys.stderr, flush=True)))
    print(table(rows))
    print("\nsteps: env steps (script: steps), stepSimulation calls in brackets where more; rewinds, partial, "
          "contacts, swept (boxes swept): totals over the seeds; diffs: BoxCCD against pybullet alone, the largest "
          "over the seeds; us/step: median per stepSimulation call; ratio there: over the steps where BoxCCD swept "
          "no box (their share in the column before); env.step us: the median env.step, bullet_boxccd never imported "
          "against its hooks installed and every stepSimulation a BoxCCD step (what an RL loop pays)")
    print()
    print("BoxCCD's own time per stepSimulation call (us: ccd.stats.seconds / calls, and the mean wall time of "
          "BoxCCD.step; a step in a world where nothing changed is not timed by the stats until something in it is "
          "fast, so 'unaccounted' holds those steps' pybullet time and the Python around the phases):")
    print()
    print(breakdown(rows))
    notes = [(r["client"], m, w) for r in rows for m, w in r["warnings"].items()]
    if notes:
        print("\nBoxCCDWarnings:")
        for c, m, w in notes:
            print(f"- {c} ({w}): {m}")
    failed = [(r["client"], e) for r in rows for e in r["errors"]]
    nondet = [r["client"] for r in rows if r["plain_vs_bare"] != 0.0]
    if nondet:
        print(f"\nplain (hooks installed) differs from bare pybullet: {nondet}")
    if failed:
        print("\nFailures:")
        for c, e in failed:
            print(f"- {c}: {e}")
    os.makedirs(os.path.dirname(out), exist_ok=True)
    with open(out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({**r, "warnings": " || ".join(r["warnings"]), "errors": " || ".join(
                e.splitlines()[0] for e in r["errors"])})
    print(f"\nwrote {os.path.relpath(out)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
