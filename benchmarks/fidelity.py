"""Fidelity of BoxCCD against pybullet's converged physics, and what it costs.

The claim measured: a world stepped with ``BoxCCD(cid).step()`` at a coarse step ends like
*pybullet's converged physics*, the same seeded scene in plain pybullet at a step so fine
that halving it again changes the figures by less than their tolerance.

Per family (the scenes: ``benchmarks/_fidelity_scenes.py``, one ``build``/``observe``/
``measure`` each) and seed, the same scene is run by every method:

* ``plain``: ``p.stepSimulation()`` at the family's step dt,
* ``boxccd``: ``BoxCCD(cid).step()`` (defaults); ``--knob k=v`` adds a method ``boxccd k=v``
  with those keyword arguments (``--knob a=1,b=2`` for several at once),
* ``sub2`` .. ``sub16``: ``setPhysicsEngineParameter(numSubSteps=k)``, fixedTimeStep dt,
* ``native``: pybullet's own CCD: the scene made with ``useMaximalCoordinates=True`` and
  ``changeDynamics(ccdSweptSphereRadius=0.5 * smallest half extent,
  contactProcessingThreshold=0)`` on every dynamic body (not for the jointed robots:
  maximal coordinates have no joints),
* ``ref`` / ``ref2``: plain pybullet at dt/K and dt/(2K) (K per family, printed). Where a
  figure compares seeds one by one (head-on, pusher) the reference is the mean over
  ``phases`` offsets of its step grid (a first step of j/phases of a fine step): pybullet's
  rebound depends on where in its step a touch falls (the contact's position correction
  adds up to about 7 % of the impact speed, linearly in that phase, at every step size), so a
  single fine run does not converge seed by seed, while the phase mean does.

Controls (the pusher's velocity) are applied before every solver step of a method (each
fine step of a reference; once per step of dt for the others, as a user would). Figures are
read after every step of dt (the references: every K fine steps, so at the same times).
Cost: the mean wall time of a step of dt over the run (controls included, observation not),
the fastest of ``--repeats`` runs of the seed (default 3; the references: one run), then
the mean over seeds; ``x plain`` is its ratio to ``plain`` on the same family in the
same run (runs go to ``--jobs`` worker processes in one shuffled queue, so load from
elsewhere hits every method alike). Non-BoxCCD methods call pybullet's own stepSimulation
(not the journaling wrapper that importing bullet_boxccd installs).

Outputs: ``benchmarks/results/fidelity.csv`` (one row per family x variant x figure x
method, with the reference's value at dt/K and dt/2K, their difference and the tolerance),
``docs/fidelity.png`` (error against the reference versus cost relative to plain, one panel
per family), a markdown table on stdout (``--quick``: ``fidelity_quick.csv`` and ``.png``).
Every family has one scalar error for the plot,
named in the CSV (``figure`` column, rows whose ref is 0 by definition).

The families (seeds by default; ``--quick``): 1 ``head_on`` (9 variants: restitution 1, 0.5,
0 x straight, tilted, spinning; 4 each; 1), 2 ``spinning`` (16; 6), 3 ``table`` (12; 4),
4 ``planks`` (6; 2), 5 ``rain`` (48 boxes, 4 seeds; 1; and 100 and 1000 boxes for cost only,
one seed; 100 only with --quick), 6a ``arm`` (8; 2), 6b ``biped`` (8; 2), 7 ``pusher`` (8; 2),
8 ``stack`` (12; 3), 9 ``glancing`` (16; 6). ``--study K1,K2,..`` prints the references' figures at each dt/K instead
(how K was chosen). ``--maximal`` builds every body in maximal coordinates
(``useMaximalCoordinates=True``) for every method, into ``fidelity_maximal.csv`` and ``.png``.

Run
---
    python benchmarks/fidelity.py                   # all families, ~2 min on 2 cores
    python benchmarks/fidelity.py --quick           # ~1 min: fewer seeds and methods
    python benchmarks/fidelity.py --families head_on,table --seeds 4 --knob max_partial_steps=4

This is a benchmark, not a test: it asserts nothing (tests/test_fidelity.py does, on the
deterministic head-on cases and the glancing family).
"""

from __future__ import annotations

import argparse
import math
import multiprocessing as mp
import os
import platform
import random
import sys
import time
from collections import defaultdict

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pybullet as p  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _fidelity_scenes import FAMILIES, G, World  # noqa: E402
from _report import code_version, knobs, write_csv  # noqa: E402

# Imported before any world is built: it wraps pybullet's world-changing calls (its journal
# of user moves), which BoxCCD needs to have seen.
from bullet_boxccd import BoxCCD  # noqa: E402
from bullet_boxccd.validate.tables import markdown  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
METHODS = ["plain", "boxccd", "sub2", "sub4", "sub8", "sub16", "native", "ref", "ref2"]
QUICK_METHODS = ["plain", "boxccd", "sub4", "native", "ref", "ref2"]
QUICK_VARIANTS = {"rain": ["48", "100"]}  # --quick: no 1000-box rain

_CLIENT = [None]


# --------------------------------------------------------------------- one run
def _client():
    if _CLIENT[0] is None:
        _CLIENT[0] = p.connect(p.DIRECT)
    return _CLIENT[0]


def _raw_step():
    return getattr(p, "_bullet_boxccd_originals", {}).get("stepSimulation", p.stepSimulation)


def parse_method(method):
    """(kind, numSubSteps, BoxCCD keyword arguments)."""
    if method.startswith("boxccd"):
        return "boxccd", 0, knobs(method[len("boxccd"):])
    if method.startswith("sub"):
        return "sub", int(method[3:]), {}
    return method, 0, {}


def run_one(fam_key, variant, seed, method, phase=0.0, cid=None):
    """One seed of one family variant by one method: (the measure's dict, us per step of dt).
    ``phase``: the references' grid offset, in fine steps. ``ref@K``: plain at dt/K."""
    fam = FAMILIES[fam_key]
    kind, sub, knobs = parse_method(method)
    K = {"ref": fam.K, "ref2": 2 * fam.K}.get(kind, 1)
    if kind.startswith("ref@"):
        K = int(kind[4:])
    cid = _client() if cid is None else cid
    p.resetSimulation(physicsClientId=cid)
    h = fam.dt / K
    p.setPhysicsEngineParameter(fixedTimeStep=h, numSubSteps=sub, physicsClientId=cid)
    p.setGravity(0, 0, -G, physicsClientId=cid)
    w = World(cid, fam.dt, h, maximal=kind == "native" or MAXIMAL[0])
    rng = np.random.default_rng([list(FAMILIES).index(fam_key), fam.variants.index(variant), seed])
    s = fam.build(w, rng, variant)
    if kind == "native":
        for b, link, half in w.dynamic:
            p.changeDynamics(b, link, ccdSweptSphereRadius=0.5 * half, contactProcessingThreshold=0.0,
                             physicsClientId=cid)
    raw = _raw_step()
    if kind == "boxccd":
        step = BoxCCD(cid, **knobs).step
    else:
        def step():
            raw(physicsClientId=cid)
    control = getattr(s, "control", None)
    t0 = 0.0
    if phase:  # a first, shorter step shifts the reference's grid
        p.setPhysicsEngineParameter(fixedTimeStep=phase * h, physicsClientId=cid)
        if control:
            control(w, s, 0.0, phase * h)
        raw(physicsClientId=cid)
        p.setPhysicsEngineParameter(fixedTimeStep=h, physicsClientId=cid)
        t0 = phase * h
    hc = h if K > 1 else fam.dt  # a control's time span: a solver step, or the user's step
    clock, total = time.perf_counter, 0.0
    for k in range(s.steps):
        c0 = clock()
        for j in range(K):
            if control:
                control(w, s, t0 + k * fam.dt + j * hc, hc)
            step()
        total += clock() - c0
        w.t = t0 + (k + 1) * fam.dt
        fam.observe(w, s, k)
    return fam.measure(w, s), 1e6 * total / s.steps


TIMING_REPEATS = [3]  # runs of a timed method's job: the fastest is its cost (load from elsewhere only adds)
MAXIMAL = [False]  # --maximal: every body in maximal coordinates


def _job(args):
    fam_key, variant, seed, method, phase = args
    try:
        out, us = run_one(fam_key, variant, seed, method, phase)
        for _ in range(0 if method.startswith("ref") else TIMING_REPEATS[0] - 1):
            us = min(us, run_one(fam_key, variant, seed, method, phase)[1])
    except NotImplementedError:
        return args, None, math.nan
    return args, out, us


# ------------------------------------------------------------------ schedule
def jobs_for(fams, methods, seeds_of, quick):
    jobs = []
    for fk in fams:
        fam = FAMILIES[fk]
        for variant in fam.variants:
            cost_only = variant in fam.cost_only
            if quick and cost_only and variant not in QUICK_VARIANTS.get(fk, fam.variants):
                continue
            n = 1 if cost_only else seeds_of(fam)
            for m in methods:
                if m.startswith("ref") and cost_only:
                    continue
                if m == "native" and not fam.native:
                    continue
                phases = fam.phases if m.startswith("ref") else 1
                for seed in range(n):
                    for j in range(phases):
                        jobs.append((fk, variant, seed, m, j / phases))
    return jobs


def _mean_dict(ds):
    return {k: np.mean([np.asarray(d[k], dtype=float) for d in ds], axis=0) for k in ds[0]}


def run_all(jobs, n_jobs):
    """{(family, variant, method): [per-seed dict]} and {(family, variant, method): [us per step]}."""
    random.Random(0).shuffle(jobs)  # the methods interleaved: outside load hits all alike
    jobs.sort(key=lambda j: 0 if j[3] == "ref2" else 1 if j[3] == "ref" else 2)  # the longest first
    raw = defaultdict(dict)
    cost = defaultdict(list)
    try:
        from tqdm import tqdm
    except ImportError:  # the bar is optional
        def tqdm(it, **kw):
            return it
    bar = dict(total=len(jobs), desc="runs", unit="run", disable=not sys.stderr.isatty())
    if n_jobs > 1:
        with mp.get_context("fork").Pool(n_jobs) as pool:
            done = list(tqdm(pool.imap_unordered(_job, jobs, chunksize=1), **bar))
    else:
        done = [_job(j) for j in tqdm(jobs, **bar)]
    for (fk, variant, seed, m, _), out, us in done:
        if out is None:
            continue
        raw[(fk, variant, m)].setdefault(seed, []).append(out)
        cost[(fk, variant, m)].append(us)
    results = {key: [_mean_dict(by_seed[s]) for s in sorted(by_seed)] for key, by_seed in raw.items()}
    return results, cost


# ------------------------------------------------------------------ figures
def table_rows(results, cost, fams, methods):
    """The CSV rows: per family, variant, figure and method."""
    rows = []
    for fk in fams:
        fam = FAMILIES[fk]
        for variant in fam.variants + (["all"] if len(fam.variants) > 1 and not fam.cost_only else []):
            vs = [v for v in fam.variants if v not in fam.cost_only] if variant == "all" else [variant]

            def res(m):
                out = []
                for v in vs:
                    out += results.get((fk, v, m), [])
                return out

            def us(m):
                c = [x for v in vs for x in cost.get((fk, v, m), [])]
                return float(np.mean(c)) if c else math.nan

            plain_us = us("plain")
            ref, ref2 = res("ref"), res("ref2")
            figs = ([] if variant == "all" else fam.figures) + [fam.error]
            for fig in figs:
                if fig.paired and not ref:
                    continue
                if fig.paired:
                    r_val, r2_val = 0.0, fig.fn(ref2, ref) if ref2 else math.nan
                else:
                    r_val = fig.fn(ref) if ref else math.nan
                    r2_val = fig.fn(ref2) if ref2 else math.nan
                diff = abs(r_val - r2_val)
                for m in methods:
                    rs = res(m)
                    if not rs:
                        continue
                    val = (fig.fn(rs, ref) if fig.paired else fig.fn(rs))
                    rows.append(dict(
                        family=fk, variant=variant, figure=fig.name, is_error=int(fig is fam.error),
                        kind="error vs ref" if fig.paired else "figure", method=m, value=val, ref=r_val, ref2=r2_val,
                        ref_diff=diff, tol=fig.tol, converged=int(diff <= fig.tol) if not math.isnan(diff) else "",
                        K=fam.K, phases=fam.phases, dt=fam.dt, seeds=len(rs), us_per_step=us(m),
                        x_plain=us(m) / plain_us if plain_us else math.nan))
    return rows


def fmt(x, nd=3):
    if isinstance(x, str):
        return x
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    if x == int(x) and abs(x) < 1e6:
        return str(int(x))
    a = abs(x)
    if a >= 100:
        return f"{x:.0f}"
    if a >= 1:
        return f"{x:.2f}"
    return f"{x:.{nd}f}" if a >= 1e-3 else f"{x:.1e}"


def print_tables(rows, fams, methods):
    def table(title, header, body):
        print(f"\n{title}\n\n{markdown(header, body)}")

    for fk in fams:
        fam = FAMILIES[fk]
        for variant in dict.fromkeys(r["variant"] for r in rows if r["family"] == fk):
            rr = [r for r in rows if r["family"] == fk and r["variant"] == variant]
            figs = list(dict.fromkeys(r["figure"] for r in rr))
            ms = [m for m in methods if any(r["method"] == m for r in rr)]
            get = {(r["figure"], r["method"]): r for r in rr}
            body = []
            for m in ms:
                any_r = next(r for r in rr if r["method"] == m)
                body.append([m, fmt(any_r["us_per_step"], 1), fmt(any_r["x_plain"], 2)]
                            + [fmt(get[(f, m)]["value"]) if (f, m) in get else "" for f in figs])
            first = {f: next(r for r in rr if r["figure"] == f) for f in figs}
            if any(m == "ref" for m in ms):
                body.append(["|ref - ref2| / tol", "", ""] + [
                    f"{fmt(first[f]['ref_diff'])} / {fmt(first[f]['tol'])} "
                    f"{'ok' if first[f]['converged'] == 1 else 'NOT conv.'}" for f in figs])
            ref_note = (f"ref: dt/{fam.K}, ref2: dt/{2 * fam.K}" + (f", each the mean over {fam.phases} grid phases"
                                                                 if fam.phases > 1 else ""))
            table(f"{fam.label} [{fk}, variant {variant}] (dt = {fam.dt:.4g} s, {ref_note}; "
                  f"{first[figs[0]]['seeds']} seeds)", ["method", "us/step", "x plain"] + figs, body)


def summary(rows, fams, methods):
    print("\n## summary: each family's error against the converged reference (and cost x plain)\n")
    ms = [m for m in methods if not m.startswith("ref")] + ["ref2"]
    head = ["family", "error (unit)", "K", "ref vs ref2"] + ms
    out = []
    for fk in fams:
        fam = FAMILIES[fk]
        rr = [r for r in rows if r["family"] == fk and r["is_error"] == 1
              and r["variant"] == ("all" if len(fam.variants) > 1 and not fam.cost_only else fam.variants[0])]
        if not rr:
            continue
        get = {r["method"]: r for r in rr}
        r0 = rr[0]
        conv = f"{fmt(r0['ref_diff'])} (tol {fmt(r0['tol'])})"
        out.append([fam.label, fam.error.name, fam.K, conv] + [
            f"{fmt(get[m]['value'])} (x{fmt(get[m]['x_plain'], 2)})" if m in get else "-" for m in ms])
    widths = [max(len(str(c)) for c in col) for col in zip(head, *out)]
    print("| " + " | ".join(str(h).ljust(w) for h, w in zip(head, widths)) + " |")
    print("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for r in out:
        print("| " + " | ".join(str(c).ljust(w) for c, w in zip(r, widths)) + " |")


def study(fams, Ks, seeds_of, n_jobs):
    """The references' convergence: each family's figures by plain pybullet at dt/K for each K
    (the paired errors against the finest), and the cost per step of dt."""
    methods = [f"ref@{K}" for K in Ks]
    jobs = []
    for fk in fams:
        fam = FAMILIES[fk]
        for variant in fam.variants:
            if variant in fam.cost_only:
                continue
            for m in methods:
                for seed in range(seeds_of(fam)):
                    jobs += [(fk, variant, seed, m, j / fam.phases) for j in range(fam.phases)]
    results, cost = run_all(jobs, n_jobs)
    for fk in fams:
        fam = FAMILIES[fk]
        finest = methods[-1]
        body = []
        for m in methods:
            rs = [r for v in fam.variants for r in results.get((fk, v, m), [])]
            fine = [r for v in fam.variants for r in results.get((fk, v, finest), [])]
            c = [x for v in fam.variants for x in cost.get((fk, v, m), [])]
            body.append([m, fmt(float(np.mean(c)), 0)] + [fmt(f.fn(rs, fine) if f.paired else f.fn(rs))
                                                          for f in fam.figures + [fam.error]])
        head = ["K", "us/step"] + [f.name + (f" (vs {finest})" if f.paired else "") + f" [tol {fmt(f.tol)}]"
                                   for f in fam.figures + [fam.error]]
        print(f"\n{fam.label}: all variants, {seeds_of(fam)} seeds, {fam.phases} phase(s)\n\n{markdown(head, body)}")


# ------------------------------------------------------------------ plot
STYLE = {"plain": dict(marker="o", color="black", s=60), "boxccd": dict(marker="*", color="tab:red", s=220),
         "native": dict(marker="D", color="tab:green", s=60), "ref2": dict(marker="s", color="0.55", s=55)}
SUB_COLORS = {"sub2": "#9ecae1", "sub4": "#6baed6", "sub8": "#3182bd", "sub16": "#08519c"}


def plot(rows, fams, methods, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    n = len(fams)
    cols = min(3, n)
    nrows = int(math.ceil(n / cols))
    fig, axes = plt.subplots(nrows, cols, figsize=(5.6 * cols, 4.3 * nrows + 1.0), squeeze=False)
    handles = {}
    for ax, fk in zip(axes.flat, fams):
        fam = FAMILIES[fk]
        variant = "all" if len(fam.variants) > 1 and not fam.cost_only else fam.variants[0]
        rr = {r["method"]: r for r in rows if r["family"] == fk and r["is_error"] == 1 and r["variant"] == variant}
        if not rr:
            ax.set_visible(False)
            continue
        tol = next(iter(rr.values()))["tol"]
        fails = defaultdict(float)  # the family's failure count (tunneled, ...) per method, over its variants
        for r in rows:
            if r["family"] == fk and r["figure"] == fam.failure and r["variant"] in fam.variants \
                    and r["variant"] not in fam.cost_only:
                fails[r["method"]] += r["value"]
                if r["method"] == "plain":
                    fails["ref"] += r["ref"]
        ref_fails = fails.get("ref", 0.0)
        floor = tol / 20.0
        ys = [max(abs(r["value"]), floor) for m, r in rr.items() if m != "ref" and not math.isnan(r["value"])]
        subs = [(rr[m]["x_plain"], max(abs(rr[m]["value"]), floor)) for m in methods if m in SUB_COLORS and m in rr]
        if subs:
            ax.plot(*zip(*subs), color="#3182bd", lw=1, alpha=0.6, zorder=1)
        for m in methods:
            if m not in rr or m == "ref":
                continue
            r = rr[m]
            x, y = r["x_plain"], max(abs(r["value"]), floor)
            if m in SUB_COLORS:
                st = dict(marker="v", color=SUB_COLORS[m], s=60)
                label = "numSubSteps 2/4/8/16 (light to dark)"
            elif m.startswith("boxccd") and m != "boxccd":
                st = dict(marker="P", color="tab:orange", s=80)
                label = "BoxCCD with a knob (annotated)"
                ax.annotate(m[len("boxccd"):].strip(), (x, y), xytext=(5, 4), textcoords="offset points",
                            fontsize=7, color="tab:orange")
            else:
                st = STYLE[m]
                label = {"plain": "plain pybullet", "boxccd": "BoxCCD (defaults)",
                         "native": "pybullet native CCD (maximal coords)",
                         "ref2": "reference at dt/2K vs dt/K (convergence)"}[m]
            hnd = ax.scatter([x], [y], zorder=3, **st)
            if label not in handles:  # a filled proxy for the legend
                handles[label] = Line2D([], [], ls="", marker=st["marker"], color=st["color"],
                                        markersize=math.sqrt(st["s"]))
            if fails.get(m, 0.0) > ref_fails:  # hollow: more went through than in the reference
                hnd.set_facecolor("none")
                hnd.set_edgecolor(st["color"])
                hnd.set_linewidth(1.5)
                ax.annotate(f"{fails[m]:g}", (x, y), xytext=(6, -9), textcoords="offset points",
                            fontsize=7, color=st["color"])
        ax.axhline(tol, color="0.4", ls=":", lw=1)
        ax.text(0.99, tol, " tolerance", transform=ax.get_yaxis_transform(), ha="right", va="bottom", fontsize=7,
                color="0.3")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(floor / 1.5, max(ys + [tol]) * 2.5)
        ax.set_title(f"{fam.label}\nref: dt/{fam.K}" + (f" x {fam.phases} phases" if fam.phases > 1 else "")
                     + f", dt = {fam.dt:.3g} s, {next(iter(rr.values()))['seeds']} seeds; "
                     + f"hollow: '{fam.failure}' > ref's ({ref_fails:g})", fontsize=8.5)
        ax.set_xlabel("cost per step relative to plain pybullet (log)", fontsize=8)
        ax.set_ylabel(fam.unit + f"\n(on the bottom edge: < {floor:.2g}, or 0)", fontsize=8)
        ax.grid(True, which="both", alpha=0.25)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center", ncol=3, fontsize=9, frameon=False)
    fig.suptitle("BoxCCD vs pybullet's converged physics: error against the fine-step reference (y, lower is better) "
                 "vs cost per step (x)\nhollow marker: more bodies tunneled (fell through, ...) than in the reference "
                 "(the count beside it); dotted: the tolerance the reference converged to", fontsize=11)
    fig.tight_layout(rect=(0, 0.05, 1, 0.95))
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ------------------------------------------------------------------ main
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="few seeds; plain, boxccd, sub4, native and the references")
    ap.add_argument("--families", default=",".join(FAMILIES), help=f"comma-separated, of {', '.join(FAMILIES)}")
    ap.add_argument("--seeds", type=int, default=None, help="seeds per family (variant) instead of its default")
    ap.add_argument("--knob", action="append", default=[], metavar="K=V[,K=V]",
                    help="another BoxCCD method with these keyword arguments (repeatable)")
    ap.add_argument("--methods", default=None, help="comma-separated subset of " + ",".join(METHODS))
    ap.add_argument("--repeats", type=int, default=3,
                    help="runs of each seed by a timed method (not the references); its cost is the fastest "
                    "(default 3)")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1), help="worker processes (default 2)")
    ap.add_argument("--out", default=None, help="directory for fidelity.csv and fidelity.png (default: "
                    "benchmarks/results/ and docs/)")
    ap.add_argument("--maximal", action="store_true",
                    help="every body in maximal coordinates, for every method (fidelity_maximal.csv, .png)")
    ap.add_argument("--study", default=None, metavar="K1,K2,..",
                    help="only the references' convergence: plain at dt/K for each K (the figures per K)")
    args = ap.parse_args(argv)
    fams = [f.strip() for f in args.families.split(",") if f.strip()]
    bad = [f for f in fams if f not in FAMILIES]
    if bad:
        ap.error(f"unknown families {bad}; expected some of {list(FAMILIES)}")
    methods = (args.methods.split(",") if args.methods else list(QUICK_METHODS if args.quick else METHODS))
    methods = methods[:2] + [f"boxccd {k.strip()}" for k in args.knob] + methods[2:]
    if "plain" not in methods:
        methods.insert(0, "plain")
    # a quick or maximal run never overwrites the full run's outputs
    name = ("fidelity_quick" if args.quick else "fidelity") + ("_maximal" if args.maximal else "")
    csv_path = os.path.join(args.out or os.path.join(ROOT, "benchmarks", "results"), name + ".csv")
    png_path = os.path.join(args.out or os.path.join(ROOT, "docs"), name + ".png")

    def seeds_of(fam):
        return args.seeds or (fam.quick_seeds if args.quick else fam.seeds)

    print(f"machine: {platform.platform()}, {os.cpu_count()} cpus, python {platform.python_version()}, "
          f"pybullet API {p.getAPIVersion()}, numpy {np.__version__}")
    import bullet_boxccd

    print(f"code: {code_version()}; bullet_boxccd imported from {os.path.dirname(bullet_boxccd.__file__)}")
    print(f"families: {', '.join(fams)}; methods: {', '.join(methods)}; jobs: {args.jobs}")
    TIMING_REPEATS[0] = max(1, args.repeats)
    MAXIMAL[0] = args.maximal
    t0 = time.perf_counter()
    if args.study:
        study(fams, [int(k) for k in args.study.split(",")], seeds_of, args.jobs)
        print(f"\n{time.perf_counter() - t0:.0f} s")
        return
    jobs = jobs_for(fams, methods, seeds_of, args.quick)
    results, cost = run_all(jobs, args.jobs)
    rows = table_rows(results, cost, fams, methods)
    print_tables(rows, fams, methods)
    summary(rows, fams, methods)
    write_csv(csv_path, rows)
    plot(rows, fams, methods, png_path)
    print(f"\n{len(jobs)} runs in {time.perf_counter() - t0:.0f} s; written: {csv_path}, {png_path}")


if __name__ == "__main__":
    main()
