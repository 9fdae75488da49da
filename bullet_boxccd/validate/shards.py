"""Shards of validation queries, their tallies, and the ``validate`` driver.

A run of N queries is cut into shards of ``shard_size`` (the last one shorter); shard k
holds queries k * shard_size onwards, shared among the chosen families as evenly as
possible (the first families get one more). Family f's part of shard k is drawn from
``numpy.random.default_rng([seed, k, FAMILY_ID[f]])``: a shard's queries depend only on
(seed, shard index, its size, the families), never on which worker runs it or when, so
the totals are the same for any number of workers and the report is a resumable record
of finished shards. Each shard is solved with ``time_of_impact_batch`` (one call per
family) and judged by ``checker.check``.

Tallies per family: queries; hits (answers that report a contact); misses, late, false
hits (certified failures: see ``checker``); unresolved (no verdict even in mpmath);
mpmath (queries the float64 tier handed on); early (answers given while the boxes were
certified more than the touching tolerance apart: a contact does come, later; not a
failure, since the solver promises never late, but counted); worst early (the largest
SAT gap at a reported contact, in units of the smaller box's size: how far apart the
boxes still were when reported touching).
"""

from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..solver import time_of_impact_batch
from . import checker as C
from .casefile import case_name, case_text
from .families import FAMILIES, make_batch
from .report import Report
from .runner import progress, run_jobs
from .tables import markdown

__all__ = ["FAMILY_ID", "COUNTS", "Summary", "run_shard", "validate", "summary_table", "last_line"]

FAMILY_ID = {name: i for i, name in enumerate(FAMILIES)}  # fixed: a family's stream ignores the others
COUNTS = ("queries", "hits", "misses", "late", "false_hits", "unresolved", "mp", "early")
FAILURES = {C.MISS: "miss", C.LATE: "late", C.FALSE_HIT: "false_hit"}
SAVED = 20  # unresolved and early cases kept per shard and family: enough to study, not a flood


def plan(queries: int, shard_size: int) -> list[tuple[int, int]]:
    """(shard index, its number of queries) for a run of ``queries``."""
    return [(k, min(shard_size, queries - k * shard_size)) for k in range(-(-queries // shard_size))]


def split(n: int, families) -> list[int]:
    F = len(families)
    return [n // F + (f < n % F) for f in range(F)]


def run_shard(seed: int, shard: int, n: int, families, tolerances: dict) -> dict:
    """Solve and check shard ``shard``; returns its record (tallies per family, and the
    failing cases as case-file texts, for the caller to write where it runs)."""
    tol = C.CheckTolerances(**tolerances)
    tallies, cases = {}, {}
    for name, nf in zip(families, split(n, families)):
        if nf == 0:
            continue
        batch = make_batch(name, np.random.default_rng([seed, shard, FAMILY_ID[name]]), nf)
        ts = time_of_impact_batch(batch.lo_a, batch.hi_a, batch.coeffs_a, batch.lo_b, batch.hi_b, batch.coeffs_b,
                                  batch.t_range)
        c = C.check(batch, ts, tol)
        v = np.bincount(c.verdict, minlength=len(C.VERDICTS))
        early = c.early_gap[np.isfinite(c.early_gap)]
        tallies[name] = dict(queries=nf, hits=int(np.isfinite(ts).sum()), misses=int(v[C.MISS]), late=int(v[C.LATE]),
                             false_hits=int(v[C.FALSE_HIT]), unresolved=int(v[C.UNRESOLVED]), mp=int(c.mp.sum()),
                             early=int(c.early.sum()), worst_early=float(early.max()) if len(early) else 0.0)
        save = {int(i): C.VERDICTS[c.verdict[i]] for i in np.nonzero(np.isin(c.verdict, list(FAILURES)))[0]}
        for i in np.nonzero(c.verdict == C.UNRESOLVED)[0][:SAVED]:
            save[int(i)] = "unresolved"
        for i in np.nonzero(c.early & (c.verdict == C.HIT))[0][:SAVED]:
            save[int(i)] = "early"
        for i, verdict in sorted(save.items()):
            origin = dict(family=name, seed=seed, shard=shard, index=int(i))
            cases[case_name(name, seed, shard, int(i), verdict)] = case_text(batch, i, ts[i], verdict, c.evidence[i],
                                                                               origin)
    return dict(key=str(shard), n=n, tallies=tallies, cases=cases)


class Summary(dict):
    """{family: tallies} over finished shards, with a "total" entry."""

    @classmethod
    def of(cls, records) -> "Summary":
        out = cls()
        for rec in sorted(records, key=lambda r: int(r["key"])):
            for name, t in rec["tallies"].items():
                s = out.setdefault(name, dict.fromkeys(COUNTS, 0) | {"worst_early": 0.0})
                for k in COUNTS:
                    s[k] += t[k]
                s["worst_early"] = max(s["worst_early"], t["worst_early"])
        total = dict.fromkeys(COUNTS, 0) | {"worst_early": 0.0}
        for s in out.values():
            for k in COUNTS:
                total[k] += s[k]
            total["worst_early"] = max(total["worst_early"], s["worst_early"])
        out["total"] = total
        return out

    @property
    def failures(self) -> int:
        t = self["total"]
        return t["misses"] + t["late"] + t["false_hits"]


def summary_table(s: Summary) -> str:
    head = ("family", "queries", "hits", "misses", "late", "false hits", "unresolved", "mpmath", "early",
            "worst early (box sizes)")
    return markdown(head, [(name, *(f"{t[k]:,}" for k in COUNTS), f"{t['worst_early']:.1e}") for name, t in s.items()])


def last_line(s: Summary) -> str:
    t = s["total"]
    return (f"validated {t['queries']} queries: {t['hits']} hits, {t['misses']} misses, {t['late']} late, "
            f"{t['false_hits']} false hits")


def header(seed, shard_size, families, tolerances) -> dict:
    return dict(command="boxccd validate", format=1, seed=seed, shard_size=shard_size, families=list(families),
                tolerances=tolerances)


def validate(queries, families=None, seed=0, workers=None, address=None, report=None, cases_dir=None,
             shard_size=10_000, tolerances: C.CheckTolerances = C.DEFAULT, show_progress=True):
    """Run (or resume) a validation; returns (Summary, dict(queries_run, seconds, cases_dir))."""
    families = list(families or FAMILIES)
    unknown = [f for f in families if f not in FAMILIES]
    if unknown:
        raise ValueError(f"unknown families {unknown}; expected some of {list(FAMILIES)}")
    if queries < 1 or shard_size < 1:
        raise ValueError(f"expected queries >= 1 and shard_size >= 1, got {queries} and {shard_size}")
    tol = asdict(tolerances)
    rep = Report(report, header(seed, shard_size, families, tol))
    cases_dir = Path(cases_dir or (Path(report).with_suffix("").as_posix() + "_cases" if report else "boxccd_cases"))
    shards = plan(queries, shard_size)
    todo = [(k, n) for k, n in shards if rep.records.get(str(k), {}).get("n") != n]
    done = sum(n for _, n in shards) - sum(n for _, n in todo)
    start = time.perf_counter()
    jobs = ((str(k), (seed, k, n, families, tol)) for k, n in todo)
    with progress(queries, done, "validate", " queries", show_progress) as bar:
        for _, rec in run_jobs(run_shard, jobs, workers, address):
            for name, text in rec["cases"].items():
                cases_dir.mkdir(parents=True, exist_ok=True)
                (cases_dir / name).write_text(text)
            rep.add(dict(rec, cases=sorted(rec["cases"])))
            bar.update(rec["n"])
    seconds = time.perf_counter() - start
    summary = Summary.of(rep.records[str(k)] for k, _ in shards)
    rep.note(dict(summary=summary, queries=queries))
    return summary, dict(queries_run=sum(n for _, n in todo), seconds=seconds, cases_dir=str(cases_dir))
