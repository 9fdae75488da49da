"""Throughput of ``boxccd validate``: in this process, and on a local Ray with 1 and 2 workers.

What it measures
----------------
The same run (``--queries`` queries of every family, seed ``--seed``, shards of
``--shard-size``) with ``--workers 0`` (in this process, no Ray: the baseline, measured
in the same run), then on a local Ray started with as many CPUs as workers (1, 2 by
default). Per run: wall seconds from the call to the summary (Ray's start-up and
shut-down included), queries per second, and the ratio to the in-process rate; and the
in-process run's CPU seconds (queries per CPU second: what an idle core would do). Ray's
start-up alone is measured as a 1-query run. Every run's summary must equal the
baseline's (the totals do not depend on the worker count); the program stops if not.

Run
---
    python benchmarks/validate_scale.py                    # about 3 min on 2 cores
    python benchmarks/validate_scale.py --queries 1e5      # about 1 min

Output: a markdown table and ``benchmarks/results/validate_scale.csv``. The machine may
carry other load (it is shared): compare the ratios, not the seconds. This is a
benchmark, not a test: it asserts nothing about timings.
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import tempfile
import time

from bullet_boxccd.validate.shards import last_line, validate

HERE = os.path.dirname(os.path.abspath(__file__))


def run(queries, seed, shard_size, workers):
    """(summary, wall seconds, this process's CPU seconds)."""
    with tempfile.TemporaryDirectory() as tmp:
        t, cpu = time.perf_counter(), time.process_time()
        summary, _ = validate(queries, seed=seed, workers=workers, report=os.path.join(tmp, "r.jsonl"),
                              shard_size=shard_size, show_progress=False)
        return summary, time.perf_counter() - t, time.process_time() - cpu


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--queries", type=lambda s: int(float(s)), default=400_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--shard-size", type=lambda s: int(float(s)), default=10_000)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--csv", default=os.path.join(HERE, "results", "validate_scale.csv"))
    args = ap.parse_args(argv)
    print(f"machine: {platform.platform()}, {os.cpu_count()} CPUs, python {platform.python_version()}; "
          f"load average before: {os.getloadavg()[0]:.2f}")
    base, base_s, base_cpu = run(args.queries, args.seed, args.shard_size, 0)
    print(last_line(base))
    print(f"in this process: {base_cpu:.1f} CPU s, {args.queries / base_cpu:,.0f} queries per CPU second "
          "(what one idle core would do)")
    rows = [dict(workers=0, where="in this process", queries=args.queries, seconds=round(base_s, 2),
                 queries_per_s=round(args.queries / base_s), ratio=1.0, startup_s="")]
    for w in args.workers:
        _, startup, _ = run(1, args.seed, args.shard_size, w)
        summary, s, _ = run(args.queries, args.seed, args.shard_size, w)
        if summary != base:
            raise SystemExit(f"{w} workers gave other totals than in-process:\n{last_line(summary)}")
        rows.append(dict(workers=w, where=f"local Ray, {w} CPU{'s' if w > 1 else ''}", queries=args.queries,
                         seconds=round(s, 2), queries_per_s=round(args.queries / s),
                         ratio=round(base_s / s, 2), startup_s=round(startup, 1)))
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    head = list(rows[0])
    widths = [max(len(str(x)) for x in col) for col in zip(head, *[[r[k] for k in head] for r in rows])]
    fmt = lambda r: "| " + " | ".join(str(x).ljust(w) for x, w in zip(r, widths)) + " |"  # noqa: E731
    print("\n".join([fmt(head), "|" + "|".join("-" * (w + 2) for w in widths) + "|",
                     *(fmt([r[k] for k in head]) for r in rows)]))
    os.makedirs(os.path.dirname(args.csv), exist_ok=True)
    with open(args.csv, "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=head)
        wr.writeheader()
        wr.writerows(rows)
    print(f"written: {args.csv} (totals equal for every worker count)")


if __name__ == "__main__":
    main()
