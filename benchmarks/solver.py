"""Benchmark of the bullet_boxccd solver against python-fcl, with an independent reference.

What it measures
----------------
Seeded random box pairs in three families (benchmarks/_shared.py, ``make_pairs``):
``trans`` (A static, B translating), ``rot`` (B also spins up to 0.95 pi over
t in [0, 1]), ``both`` (both move and spin); about half of each hit. Per family
and class (the pairs our solver reports hitting, and those that stay apart):

* time per pair of ``time_of_impact`` (a Python loop of single calls over the
  class's pairs that drops each result; and one that keeps every Contact, so
  that no contact is freed while the loop runs), of
  ``time_of_impact_batch`` (one call on all of them, one core), of the batch
  split over 2 Python threads (it scales only because the core releases the
  GIL), and of python-fcl's conservative advancement
  (``continuousCollide``, GJK libccd, toc_err 1e-6) between the same rigid start
  and end poses with ``CCDM_TRANS`` (translation only: it ignores the spin, its
  fastest) and ``CCDM_SCREW`` (a screw between the two poses), a Python loop like
  ours. The methods are timed in rounds, each round one pass of every method in
  an order rotated from round to round (interleaved, so that the drifts of a
  shared machine hit all alike); reported: the minimum over the rounds (the
  least disturbed pass) and the median;
* the ratio FCL trans / ours, single (both loops) and batch, from the minima (and the
  medians) of this run;
* misses, false hits and late answers of ours, and misses and false hits of FCL,
  against a dense separating-axis reference on the quadratic motion our solver
  gets (``reference``; FCL's spinning motions follow other paths between the same
  end poses, so the rigid motion's reference is counted for them too). Every
  disagreement of ours is printed with its inputs to 20 digits.

Run
---
    python benchmarks/solver.py            # ~2 min: 2000 pairs per family, 31 rounds
    python benchmarks/solver.py --quick    # ~30 s: 600 pairs per family, 11 rounds

Options: ``--seed`` (12345), ``--n`` pairs per family, ``--rounds``, ``--samples``
(reference samples over t in [0, 1]; 2000, 1000 with --quick), ``--csv``. The table
is markdown and is written to ``benchmarks/results/solver.csv``. A benchmark, not
a test: it asserts nothing about timings.
"""

from __future__ import annotations

import argparse
import csv
import os
import time
from concurrent.futures import ThreadPoolExecutor

import _shared as S  # sets OPENBLAS_NUM_THREADS before numpy loads
import numpy as np

from bullet_boxccd import time_of_impact, time_of_impact_batch

HERE = os.path.dirname(os.path.abspath(__file__))
TARGET_RATIO = 3.0


def check_ours(p, t_ours, ref):
    """Disagreements of ours with the reference: (pair, why)."""
    hit = ~np.isnan(t_ours)
    gap = np.full(len(t_ours), np.nan)
    idx = np.nonzero(hit)[0]
    if len(idx):
        gap[idx] = S.gap_at(S.subset(p, idx), t_ours[idx])
    out = []
    for i in range(len(t_ours)):
        st = ref["status"][i]
        if st == "hit" and not hit[i]:
            out.append((i, f"no hit; reference intersects at sample t={ref['first'][i]:.6g}"))
        elif st == "miss" and hit[i]:
            out.append((i, f"hit at t={t_ours[i]!r}; reference: min gap {ref['mingap'][i]:.3e} > margin"))
        elif hit[i] and st == "hit" and ref["first"][i] < t_ours[i] - 1e-12:
            out.append((i, f"t={t_ours[i]!r} later than the intersecting sample t={ref['first'][i]:.17g}"))
        elif hit[i] and gap[i] > 1e-6 * p["r"][i]:
            out.append((i, f"t={t_ours[i]!r} but the SAT gap there is {gap[i]:.3e} (r={p['r'][i]:.3g})"))
    return out, gap


def count(answer_hit, status, ids):
    return (int(np.sum((status[ids] == "hit") & ~answer_hit[ids])),
            int(np.sum((status[ids] == "miss") & answer_hit[ids])))


def timing_jobs(p, fcl_items):
    """The timed passes over one class's pairs: name -> callable returning the queries made."""
    objs, bargs = S.our_objects(p), S.batch_args(p)
    halves = [tuple(a[c] for a in bargs) for c in np.array_split(np.arange(len(objs)), 2)]
    pool = ThreadPoolExecutor(2)

    def single():
        for o in objs:
            time_of_impact(*o)
        return len(objs)

    def single_kept():  # every Contact kept: none is freed while the loop runs
        kept = [time_of_impact(*o) for o in objs]
        return len(kept)

    def batch():
        time_of_impact_batch(*bargs)
        return len(objs)

    def batch_2_threads():
        list(pool.map(lambda part: time_of_impact_batch(*part), halves))
        return len(objs)

    jobs = dict(single=single, single_kept=single_kept, batch=batch, batch_2_threads=batch_2_threads)
    for motion, items in fcl_items.items():
        def run(items=items):
            for it in items:
                S.fcl_safe(*it)
            return len(items)
        jobs[f"fcl_{motion}"] = run
    return jobs, pool


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer pairs, rounds and samples (~30 s)")
    ap.add_argument("--seed", type=int, default=12345)
    ap.add_argument("--n", type=int, default=None, help="pairs per family (2000; 600 with --quick)")
    ap.add_argument("--rounds", type=int, default=None, help="timing rounds (31; 11 with --quick)")
    ap.add_argument("--samples", type=int, default=None, help="reference samples over [0, 1]")
    ap.add_argument("--csv", default=os.path.join(HERE, "results", "solver.csv"))
    args = ap.parse_args(argv)
    n = args.n or (600 if args.quick else 2000)
    rounds = args.rounds or (11 if args.quick else 31)
    samples = args.samples or (1000 if args.quick else 2000)
    t_start = time.perf_counter()
    info = S.machine_info()
    print("# bullet_boxccd solver benchmark")
    print("\n".join(info))
    print(f"seed {args.seed}, {n} pairs per family, {rounds} interleaved timing rounds, {samples} reference samples; "
          f"FCL: conservative advancement, GJK libccd, num_max_iterations=100, toc_err=1e-6")

    rows, notes, disagreements = [], [], []
    for fam, fname in enumerate(S.FAMILIES):
        p = S.make_pairs(args.seed, fam, n)
        t_ours = time_of_impact_batch(*S.batch_args(p))
        single = np.array([np.nan if c is None else c.t for c in (time_of_impact(*o) for o in S.our_objects(p))])
        differ = np.nonzero(~((np.isnan(single) & np.isnan(t_ours)) | (single == t_ours)))[0]
        disagreements += [(fname, int(i), f"single {single[i]!r} != batch {t_ours[i]!r}", p) for i in differ]
        ref = S.reference(p, samples, desc=f"{fname}: reference")
        ref_rigid = ref if fname == "trans" else S.reference(p, samples, rigid=True, desc=f"{fname}: rigid reference")
        bad, gap = check_ours(p, t_ours, ref)
        disagreements += [(fname, i, why, p) for i, why in bad]
        fcl_items, fcl_hit = {}, {}
        if S.fcl is not None:
            for motion in S.FCL_MOTIONS:
                fcl_items[motion] = S.fcl_setup(p, motion)
                t_f, err_f = S.fcl_answers(fcl_items[motion])
                fcl_hit[motion] = ~np.isnan(t_f) & ~err_f
        ours_hit = ~np.isnan(t_ours)
        for cls, sel in (("hit", ours_hit), ("apart", ~ours_hit)):
            ids = np.nonzero(sel)[0]
            jobs, pool = timing_jobs(S.subset(p, ids), {m: [it[i] for i in ids] for m, it in fcl_items.items()})
            times = S.round_robin(jobs, rounds, desc=f"{fname}/{cls}: timing")
            pool.shutdown()
            best = {k: float(v.min()) * 1e6 for k, v in times.items()}
            med = {k: float(np.median(v)) * 1e6 for k, v in times.items()}
            row = dict(family=fname, cls=cls, pairs=len(ids), **{f"{k}_us": best[k] for k in best},
                       **{f"{k}_us_median": med[k] for k in med})
            row["misses"], row["false_hits"] = count(ours_hit, ref["status"], ids)
            if "fcl_trans" in best:
                for how in ("single", "single_kept", "batch"):
                    row[f"ratio_{how}"] = best["fcl_trans"] / best[how]
                    row[f"ratio_{how}_median"] = med["fcl_trans"] / med[how]
                row["threads_speedup"] = best["batch"] / best["batch_2_threads"]
                for motion in S.FCL_MOTIONS:
                    m, f = count(fcl_hit[motion], ref["status"], ids)
                    row[f"fcl_{motion}_misses"], row[f"fcl_{motion}_false_hits"] = m, f
                    if fname != "trans":
                        m, f = count(fcl_hit[motion], ref_rigid["status"], ids)
                        row[f"fcl_{motion}_misses_rigid"], row[f"fcl_{motion}_false_hits_rigid"] = m, f
            rows.append(row)
        notes.append(f"{fname}: {n} pairs, ours hit {int(ours_hit.sum())}; reference hit "
                     f"{int(np.sum(ref['status'] == 'hit'))}, miss {int(np.sum(ref['status'] == 'miss'))}, ambiguous "
                     f"{int(np.sum(ref['status'] == 'ambig'))}; SAT gap at our t / r in "
                     f"[{np.nanmin(gap / p['r']):.2e}, {np.nanmax(gap / p['r']):.2e}] (> 0: early, as guaranteed)")

    print_table(rows)
    for line in notes:
        print("  " + line)
    print()
    if disagreements:
        print(f"!! {len(disagreements)} disagreement(s) of our solver (seed {args.seed}):")
        for fname, i, why, p in disagreements[:20]:
            print(f"  family {fname} (index {S.FAMILIES.index(fname)}), pair {i}: {why}\n    {S.repro(p, i)}")
    else:
        print("ours: no miss, false hit or late answer against the dense reference; single == batch on every pair")
    if rows and "ratio_single" in rows[0]:
        low = min(min(r["ratio_single"], r["ratio_batch"]) for r in rows)
        verdict = "met in every family and class" if low >= TARGET_RATIO else "not met everywhere"
        print(f"smallest ratio FCL trans / ours (minima of the rounds): {low:.2f}; target {TARGET_RATIO:g}: {verdict}")
    write_csv(args.csv, rows, dict(seed=args.seed, n=n, rounds=rounds, samples=samples, machine=" | ".join(info)))
    print(f"\nwrote {args.csv}")
    if S.machine_info()[2] != info[2]:
        print("!! the compiled core changed on disk during the run: timings mix two builds; run again")
    print(f"total time {time.perf_counter() - t_start:.0f} s")


COLUMNS = [("family", "family", "s"), ("cls", "class", "s"), ("pairs", "pairs", "d"),
           ("single_us", "ours single (us)", ".2f"), ("batch_us", "ours batch (us)", ".2f"),
           ("fcl_trans_us", "FCL trans (us)", ".2f"), ("fcl_screw_us", "FCL screw (us)", ".2f"),
           ("ratio_single", "ratio single", ".2f"), ("ratio_batch", "ratio batch", ".2f"),
           ("ratio_single_kept", "ratio single, kept", ".2f"),
           ("ratio_single_median", "ratio single (medians)", ".2f"),
           ("ratio_batch_median", "ratio batch (medians)", ".2f"),
           ("threads_speedup", "batch, 2 threads", ".2f"), ("misses", "ours misses", "d"),
           ("false_hits", "ours false hits", "d"), ("fcl_trans_misses", "FCL trans misses", "d"),
           ("fcl_screw_misses", "FCL screw misses", "d"), ("fcl_screw_false_hits", "FCL screw false hits", "d")]


def print_table(rows):
    cols = [c for c in COLUMNS if any(c[0] in r for r in rows)]
    print()
    print("| " + " | ".join(h for _, h, _ in cols) + " |")
    print("|" + "|".join("---" for _ in cols) + "|")
    for r in rows:
        print("| " + " | ".join("-" if r.get(k) is None else format(r[k], f) for k, _, f in cols) + " |")
    print()
    print("Times per pair: the minimum over the interleaved rounds (the medians are in the CSV); ratio = FCL trans "
          "/ ours (single: a Python loop of time_of_impact that drops each result, like FCL's; single, kept: one that "
          "keeps every Contact, so that none is freed while it runs; batch: one time_of_impact_batch call). "
          "'batch, 2 threads': speed-up of the batch split over two Python threads. Misses and false hits against "
          "the dense reference on the quadratic motion (FCL's spinning motions follow other paths: the CSV also "
          "counts them against the rigid motion).")


def write_csv(path, rows, meta):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(keys + list(meta))
        for r in rows:
            w.writerow([r.get(k, "") for k in keys] + list(meta.values()))


if __name__ == "__main__":
    main()
