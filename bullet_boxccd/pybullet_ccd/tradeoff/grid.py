"""The plugin's trade-off grid: knobs x scenes x seeds, each trial a task in its own pybullet client.

Shared by ``benchmarks/tradeoff.py`` (in this process) and ``boxccd sweep`` (on Ray, or in
this process with ``--workers 0``); both write the same CSV and Pareto plot from the same
seeds. A task is one (configuration, scene, seed): it builds the scene of
``tradeoff.scenes`` (``boxes`` dynamic cubes) in a new DIRECT client, fires the seeded
shots, runs ``window`` steps of 1/240 s and returns what ``benchmarks/tradeoff.py``
documents (its module docstring defines every metric):

* ``us``: the mean wall time of a step (only the step; the checks are untimed),
* ``tunnel``: the projectiles that ended through the wall or under the ground,
* ``first``: per projectile, the time of its first CCD event against the ground or wall
  that begins inside a step (BoxCCD configurations),
* ``pose``: ``getClosestPoints`` distance right after each rewound first touch (where
  the step ends there: ``max_partial_steps=0``),
* ``deepest``: the deepest end-of-step penetration of a projectile into the ground or wall,
* ``stats``: the BoxCCD counters the table uses (solver rows, candidate pairs, swept
  boxes, steps, rewinds).

Results go through JSON (the report) before they are used, so a resumed run and a fresh
one aggregate the same values. Timings depend on where a task ran (with 2 tasks on 2
cores they share the machine); every other column depends only on the seeds.
"""

from __future__ import annotations

import csv
import json
import math
import os
import statistics
import time

import numpy as np

from ...validate.report import Report
from ...validate.runner import progress, run_jobs
from ...validate.tables import markdown

__all__ = ["configs", "task", "sweep", "aggregate", "write_outputs", "summary_text"]

MARGIN = 0.001  # pybullet's collision margin for boxes
# Where an impact should put the pair: overlapping by at most its impact depth (the default
# 1 mm, at most a quarter of the thinner box's half extent), apart by
# at most the margin at a vertex or edge.
BAND = (-1e-3 - 1e-6, MARGIN + 1e-6)
REF_FIT = 1e-4  # fit_tolerance of the reference run (contact times are compared with it)
WORLD = {"ccd": "multibody", "ref": "multibody", "plain": "multibody", "maximal": "maximal", "native": "native"}


def configs(quick):
    """(name, kind, BoxCCD kwargs or substep count), one knob at a time around BoxCCD's defaults."""
    out = [("BoxCCD default", "ccd", {})]
    for s in ((0.05, 1.0, 4.0, 8.0) if quick else (0.05, 0.5, 1.0, 2.0, 4.0, 8.0)):
        out.append((f"sweep_threshold={s:g}", "ccd", dict(sweep_threshold=s)))
    for f in (0.005, 0.5):
        out.append((f"fit_tolerance={f:g}", "ccd", dict(fit_tolerance=f)))
    for d in (1e-6, 1e-4):
        out.append((f"penetration={d:g}", "ccd", dict(penetration=d)))
    for d in (1e-5, 1e-4):
        out.append((f"impact_depth={d:g}", "ccd", dict(impact_depth=d)))
    for d in (1e-4, 1e-2):
        out.append((f"depth_tolerance={d:g}", "ccd", dict(depth_tolerance=d)))
    for k in (0, 2):
        out.append((f"max_partial_steps={k}", "ccd", dict(max_partial_steps=k)))
    out.append((f"reference (fit_tolerance={REF_FIT:g})", "ref", dict(fit_tolerance=REF_FIT)))
    out.append(("plain", "plain", 0))
    for k in ((2, 8, 32) if quick else (2, 4, 8, 16, 32)):
        out.append((f"substeps {k}", "plain", k))
    out.append(("plain (maximal)", "maximal", 0))
    out.append(("native CCD (maximal)", "native", 0))
    return out


# ---------------------------------------------------------------- one task
def task(cfg, boxes, seed, window):
    """One (configuration, scene, seed) in its own pybullet client; a JSON-able result."""
    from .. import BoxCCD
    from . import scenes as S

    world = S.build(boxes, WORLD[cfg[1]] != "multibody")
    try:
        ccd = BoxCCD(world[0], **cfg[2]) if cfg[1] in ("ccd", "ref") else None
        r = S.run_trial(world, cfg, seed, window, ccd)
        if ccd is not None:
            st = ccd.stats
            r["stats"] = {k: getattr(st, k) for k in ("solver_rows", "candidate_pairs", "swept_boxes", "steps",
                                                      "rewinds")}
    finally:
        S.close(world)
    r["deepest"] = r["deepest"] if math.isfinite(r["deepest"]) else None
    return r


# ---------------------------------------------------------------- the grid
def _key(boxes, name, seed):
    return f"{boxes}|{name}|{seed}"


def sweep(boxes=(100,), seed=2024, trials=None, window=None, quick=False, workers=0, address=None, report=None,
          show_progress=True):
    """Run (or resume) the grid. Returns (rows, tunnel log, meta): rows as in the CSV (per scene, per
    configuration), the tunneled projectiles, and the run's parameters and wall time."""
    trials = trials or (2 if quick else 10)
    window = window or (72 if quick else 120)
    if min(boxes) < 5 or trials < 1 or window < 1:
        raise ValueError(f"expected scenes of >= 5 boxes (4 are projectiles), trials >= 1 and window >= 1; got "
                         f"boxes {list(boxes)}, trials {trials}, window {window}")
    cfgs = configs(quick)
    seeds = [seed + t for t in range(trials)]
    header = dict(command="boxccd sweep", format=1, boxes=list(boxes), seeds=seeds, window=window,
                  configs=[c[0] for c in cfgs])
    rep = Report(report, header)
    by_name = {c[0]: c for c in cfgs}
    # Seeds outer, configurations inner: in one process a burst of load hits every configuration.
    jobs = [(_key(n, c[0], s), (c, n, s, window)) for n in boxes for s in seeds for c in cfgs]
    todo = [j for j in jobs if j[0] not in rep.records]
    start = time.perf_counter()
    with progress(len(jobs), len(jobs) - len(todo), "sweep", " trials", show_progress) as bar:
        for key, r in run_jobs(task, todo, workers, address):
            rep.add(dict(json.loads(json.dumps(r)), key=key))
            bar.update(1)
    wall = time.perf_counter() - start
    rows, tunnels = [], []
    for n in boxes:
        res = {name: [(s, rep.records[_key(n, name, s)]) for s in seeds] for name in by_name}
        r, t = aggregate(cfgs, res, n, trials, window)
        rows += r
        tunnels += t
    return rows, tunnels, dict(boxes=list(boxes), trials=trials, window=window, seeds=seeds, seconds=wall,
                               tasks_run=len(todo))


def aggregate(cfgs, res, boxes, trials, window):
    """The CSV rows of one scene from {config name: [(seed, task result)]}, and its tunnel log."""
    from . import scenes as S

    ref_name = next(c[0] for c in cfgs if c[1] == "ref")
    ref_first = {(seed, int(i)): t for seed, r in res[ref_name] for i, t in r["first"].items()}
    rows, tunnel_log = [], []
    for name, kind, _ in cfgs:
        trs = res[name]
        us = [r["us"] for _, r in trs]
        nt = sum(len(r["tunnel"]) for _, r in trs)
        tunnel_log += [(boxes, name, seed, *t) for seed, r in trs for t in r["tunnel"]]
        row = dict(config=name, kind=kind, us_per_step_median=round(statistics.median(us), 1),
                   us_per_step_min=round(min(us), 1), tunneled=nt, shots=S.N_PROJ * len(trs),
                   tunnel_rate=nt / (S.N_PROJ * len(trs)))
        deep = [(r["deepest"], seed) for seed, r in trs if r["deepest"] is not None]
        deepest, d_seed = min(deep) if deep else (0.0, "")
        row["deepest_penetration_m"], row["deepest_seed"] = deepest, d_seed
        if kind in ("ccd", "ref"):
            errs = [abs(t - ref_first[(seed, int(i))]) for seed, r in trs for i, t in r["first"].items()
                    if (seed, int(i)) in ref_first]
            errs = [e for e in errs if e <= S.DT]  # farther: another contact (this one missed the first)
            row["time_matched"] = len(errs)
            row["time_ref_events"] = len(ref_first)
            row["time_err_median_s"] = statistics.median(errs) if errs else ""
            row["time_err_max_s"] = max(errs) if errs else ""
            pose = [d for _, r in trs for d in r["pose"]]
            row["pose_checks"] = len(pose)
            row["pose_err_worst_m"] = max(pose, key=abs) if pose else ""
            row["pose_out_of_band"] = sum(not (BAND[0] <= d <= BAND[1]) for d in pose)
            st = {k: sum(r["stats"][k] for _, r in trs) for k in trs[0][1]["stats"]}
            row["pieces_per_pair"] = round(st["solver_rows"] / st["candidate_pairs"], 3) if st["candidate_pairs"] \
                else ""
            row["swept_per_step"] = round(st["swept_boxes"] / max(st["steps"], 1), 3)
            row["rewinds"] = st["rewinds"]
        rows.append(dict(row, boxes=boxes, trials=trials, window_steps=window))
    return rows, tunnel_log


# ---------------------------------------------------------------- outputs
def _f(x, fmt):
    return "" if x in ("", None) else format(x, fmt)


def summary_text(rows, tunnels, meta) -> str:
    """The markdown tables and notes printed by both entry points."""
    from . import scenes as S

    out = []
    for n in meta["boxes"]:
        mine = [r for r in rows if r["boxes"] == n]
        ref = next(r["config"] for r in mine if r["kind"] == "ref")
        table = [(r["config"], f"{r['us_per_step_median']:.0f}", f"{r['tunneled']}/{r['shots']}",
                  _f(r.get("time_err_median_s"), ".1e"), _f(r.get("time_err_max_s"), ".1e"),
                  f"{r['time_matched']}/{r['time_ref_events']}" if "time_matched" in r else "",
                  _f(r.get("pose_err_worst_m"), ".2e"),
                  f"{r['pose_out_of_band']}/{r['pose_checks']}" if "pose_checks" in r else "",
                  f"{r['deepest_penetration_m']:.2e}", _f(r.get("pieces_per_pair"), ".2f")) for r in mine]
        out.append(f"\ntrade-off, {n} boxes, {meta['trials']} trials x {meta['window']} steps (us/step: median over "
                   f"trials of the mean step; errors against '{ref}')")
        out.append(markdown(("config", "us/step", "tunneled/shots", "|dt| median (s)", "|dt| max (s)", "matched/ref",
                             "rewind pose worst (m)", "pose outside band", "deepest end-of-step (m)", "pieces/pair"),
                            table))
    out.append(f"\nexpected rewind pose band: [{BAND[0]:g}, {BAND[1]:g}] m; 'deepest end-of-step' is the minimum "
               "getClosestPoints distance of a projectile to the ground or wall after any step (< 0: inside)")
    ccd_names = [r["config"] for r in rows if r["kind"] in ("ccd", "ref") and r["boxes"] == meta["boxes"][0]]
    shown = [t for t in tunnels if t[1] in ccd_names]
    out.append("\nBoxCCD configurations that tunneled: seed#projectile (aimed at, launch reach = |v| dt / extent, "
               f"the quantity sweep_threshold is compared with){'' if shown else ': none'}")
    for n in meta["boxes"]:
        for name in ccd_names:
            mine = [t for t in shown if t[0] == n and t[1] == name]
            if mine:
                items = [f"{seed}#{i} ({kind[0]}, {np.linalg.norm(S.shots(seed)[i][2]) * S.DT / (2 * S.HALF):.2f})"
                         for _, _, seed, i, kind, _ in mine]
                out.append(f"  {n} boxes, {name}: {len(mine)}: " + ", ".join(items))
    return "\n".join(out)


def write_csv(rows, path):
    """Rows (dicts) as a CSV file, the columns in the order they first appear (also
    ``benchmarks/plugin.py``'s)."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(path, "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=keys)
        wr.writeheader()
        wr.writerows(rows)


def write_outputs(rows, csv_path, png_path, boxes):
    """The CSV (every scene) and one Pareto plot per scene (``png_path``, or with ``_<boxes>``
    before the suffix when there are several scenes). Returns the paths written."""
    write_csv(rows, csv_path)
    written = [csv_path]
    for n in boxes:
        root, ext = os.path.splitext(png_path)
        path = png_path if len(boxes) == 1 else f"{root}_{n}{ext}"
        plot([r for r in rows if r["boxes"] == n], path)
        written.append(path)
    return written


def pareto(xs, ys):
    """Indices of the non-dominated points (lower x and lower y are better), by x."""
    pts = sorted(range(len(xs)), key=lambda i: (xs[i], ys[i]))
    front, best = [], math.inf
    for i in pts:
        if ys[i] < best:
            front.append(i)
            best = ys[i]
    return front


def plot(rows, path):
    """Pareto plots, x = us/step (log): tunneling rate, deepest end-of-step penetration, max
    contact-time error; the grey staircase is the front, the star the default."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import LogLocator, NullFormatter

    panels = [
        ("tunneled / shots", lambda r: r["tunnel_rate"], "linear", None, None),
        ("deepest end-of-step penetration (m)", lambda r: max(-r["deepest_penetration_m"], 0.0), "log", 1e-9,
         "0 drawn at 1e-9 m"),
        ("max contact-time error vs reference (s)", lambda r: r.get("time_err_max_s"), "log", 1e-12,
         "BoxCCD configurations only; 0 drawn at 1e-12 s"),
    ]
    colors = {"ccd": "tab:blue", "ref": "tab:cyan", "plain": "tab:red", "maximal": "tab:orange",
              "native": "tab:green"}
    number = {r["config"]: k + 1 for k, r in enumerate(rows)}
    fig, axes = plt.subplots(1, 3, figsize=(17, 6), gridspec_kw=dict(right=0.82))
    for ax, (label, get, scale, floor, note) in zip(axes, panels):
        _panel(ax, rows, get, scale, floor, colors, number)
        ax.set_xscale("log")
        ax.set_yscale(scale)
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
        ax.set_xlabel("time per step (us, median over trials)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
        if note:
            ax.set_title(note, fontsize=8)
    handles = [plt.Line2D([], [], marker="o", ls="", color=c, label=k) for k, c in
               (("BoxCCD", colors["ccd"]), ("BoxCCD reference", colors["ref"]),
                ("pybullet plain / substeps", colors["plain"]), ("plain (maximal)", colors["maximal"]),
                ("native CCD (maximal)", colors["native"]))]
    handles.append(plt.Line2D([], [], marker="*", ls="", color=colors["ccd"], markersize=12, label="BoxCCD default"))
    handles.append(plt.Line2D([], [], color="grey", alpha=0.6, label="Pareto front"))
    boxes = sorted({r["boxes"] for r in rows if r.get("boxes")})
    fig.suptitle(f"BoxCCD's knobs against pybullet's substeps and native CCD: a settled pile of "
                 f"{', '.join(str(b) for b in boxes) or 'N'} boxes, 4 projectiles at 50-150 m/s "
                 "(lower left is better)", y=0.99)
    fig.legend(handles=handles, loc="upper center", ncol=7, fontsize=9, bbox_to_anchor=(0.43, 0.94))
    key = "\n".join(f"{number[r['config']]:>2}  {r['config']}" for r in rows)
    fig.text(0.835, 0.5, key, fontsize=8, family="monospace", va="center")
    fig.subplots_adjust(left=0.04, right=0.82, wspace=0.25, top=0.82, bottom=0.1)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _panel(ax, rows, get, scale, floor, colors, number):
    pts = [(r, get(r)) for r in rows if get(r) not in (None, "")]
    if floor is not None:
        pts = [(r, max(float(y), floor)) for r, y in pts]
    xs = [r["us_per_step_median"] for r, _ in pts]
    ys = [float(y) for _, y in pts]
    front = pareto(xs, ys)
    if len(front) > 1:
        ax.step([xs[i] for i in front], [ys[i] for i in front], where="post", color="grey", alpha=0.6, zorder=1,
                label="Pareto front")

    def norm(v, lo, hi, log):
        if log:
            return (math.log10(v) - math.log10(lo)) / max(math.log10(hi / lo), 1e-12)
        return (v - lo) / max(hi - lo, 1e-12)

    groups = []  # [(u, v), [(x, y, number)]]: points this close (axes fractions) share a label
    for (r, y), x in zip(pts, xs):
        star = r["config"] == "BoxCCD default"
        ax.scatter(x, y, s=220 if star else 45, marker="*" if star else "o", color=colors[r["kind"]],
                   edgecolor="k", linewidth=0.5, zorder=3 + star)
        uv = (norm(x, min(xs), max(xs), True), norm(y, min(ys), max(ys), scale == "log"))
        for g in groups:
            if abs(g[0][0] - uv[0]) < 0.12 and abs(g[0][1] - uv[1]) < 0.04:
                g[1].append((x, y, number[r["config"]]))
                break
        else:
            groups.append((uv, [(x, y, number[r["config"]])]))
    for _, group in groups:
        x, y, _ = group[0]
        ax.annotate(",".join(str(n) for _, _, n in sorted(group, key=lambda g: g[2])), (x, y), fontsize=7,
                    xytext=(4, 4), textcoords="offset points")
