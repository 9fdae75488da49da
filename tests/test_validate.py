"""boxccd validate: the checker's verdicts, fault injection, shards on Ray, resume, case files.

The checker (bullet_boxccd/validate/checker.py) is judged two ways: it must catch
failures injected into the solver's answers (dropped hits, answers moved later, hits
reported on pairs that never touch), and its certified verdicts must agree with the
independent mpmath oracle of bullet_boxccd/testing.py. The Ray tests start a local Ray with 2
CPUs for this module and shut it down at the end (no process left behind).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest
import ray_local

from bullet_boxccd import cli, time_of_impact_batch
from bullet_boxccd.testing import Case, mp_gap, reference
from bullet_boxccd.validate import checker as C
from bullet_boxccd.validate import shards
from bullet_boxccd.validate.casefile import read_case
from bullet_boxccd.validate.families import FAMILIES, QueryBatch, ballistic, static
from bullet_boxccd.validate.report import ReportMismatchError

local_ray = ray_local.local_ray  # the module's local Ray (a fixture)

SMALL = 120  # queries per family in the checker tests


def solved(name, seed=3, n=SMALL):
    b = FAMILIES[name](np.random.default_rng(seed), n)
    return b, time_of_impact_batch(b.lo_a, b.hi_a, b.coeffs_a, b.lo_b, b.hi_b, b.coeffs_b, b.t_range)


def counts(verdicts):
    return dict(zip(C.VERDICTS, np.bincount(verdicts, minlength=len(C.VERDICTS)).tolist()))


def as_case(b, i):
    return Case(b.lo_a[i], b.hi_a[i], b.coeffs_a[i], b.lo_b[i], b.hi_b[i], b.coeffs_b[i], *b.t_range)


# ------------------------------------------------------------------ the checker
@pytest.mark.parametrize("name", list(FAMILIES))
def test_solver_answers_pass_the_checker(name):
    b, ts = solved(name)
    c = C.check(b, ts)
    got = counts(c.verdict)
    assert got["miss"] == got["late"] == got["false_hit"] == got["unresolved"] == 0, got
    assert got["hit"] == np.isfinite(ts).sum()
    # Early answers are counted, not failed, by the checker (the solver rounds early); on these
    # seeded batches none is early beyond the touching tolerance, so an early one is a defect
    # (it is how an answer given too soon, such as always t_range[0], shows).
    assert not c.early.any(), f"{c.early.sum()} answers with the boxes still apart, up to {np.nanmax(c.early_gap):.2e}"


@pytest.mark.parametrize("name", ["scale", "rotation", "far", "both_moving", "one_static", "aspect", "speed"])
def test_injected_misses_late_answers_and_ghosts_are_caught(name):
    """Every injected fault is certified: hits dropped (misses), hits moved 1e-3 of the range
    later (late), random contact times given to pairs certified apart (ghosts)."""
    b, ts = solved(name)
    c = C.check(b, ts)
    hit, apart = c.verdict == C.HIT, c.verdict == C.CLEAR_MISS
    t0, t1 = b.t_range
    assert hit.sum() > 20
    dropped = np.where(hit, np.nan, ts)
    assert counts(C.check(b, dropped).verdict[hit])["miss"] == hit.sum()
    later = np.where(hit, np.minimum(ts + 1e-3 * (t1 - t0), t1), ts)
    assert counts(C.check(b, later).verdict[hit])["late"] == hit.sum()
    ghost = np.where(apart, t0 + np.random.default_rng(0).uniform(0, 1, b.n) * (t1 - t0), ts)
    assert counts(C.check(b, ghost).verdict[apart])["false_hit"] == apart.sum()


def test_injected_faults_agree_with_the_independent_oracle():
    """Certified misses overlap at their evidence time by bullet_boxccd.testing's 40-digit gap;
    certified ghosts are apart there at the reported time."""
    b, ts = solved("one_static", n=60)
    c = C.check(b, ts)
    got = counts(c.verdict)  # the solver's own answers pass
    assert got["miss"] == got["late"] == got["false_hit"] == 0 and got["hit"] > 20 and not c.early.any(), got
    hit, apart = c.verdict == C.HIT, c.verdict == C.CLEAR_MISS
    cm = C.check(b, np.where(hit, np.nan, ts))
    misses = np.nonzero(cm.verdict == C.MISS)[0][:10]
    assert len(misses) == 10
    for i in misses:
        assert mp_gap(as_case(b, i), cm.evidence[i]) < 0
    t_ghost = b.t_range[0] + 0.5 * (b.t_range[1] - b.t_range[0])
    cg = C.check(b, np.where(apart, t_ghost, ts))
    ghosts = np.nonzero(cg.verdict == C.FALSE_HIT)[0][:10]
    assert len(ghosts) == 10
    for i in ghosts:
        assert mp_gap(as_case(b, i), t_ghost) > 0


def test_grazing_touches_are_settled_by_mpmath_and_agree_with_the_oracle():
    """Gap-0 grazing pairs (moved and turned: the exact gap is a rounding's +-1e-16): with
    the answer dropped, the float64 tier cannot decide; mpmath certifies an overlap
    (a miss) or a positive gap, and the oracle's 40-digit gap agrees with each."""
    b, ts = solved("grazing", seed=3, n=80)
    c = C.check(b, ts)
    assert not c.early.any()
    zero = (b.param == 0) & (c.verdict == C.HIT)
    cm = C.check(b, np.where(zero, np.nan, ts))
    assert cm.mp[zero].all()
    miss = np.nonzero(zero & (cm.verdict == C.MISS))[0]
    clear = np.nonzero(zero & (cm.verdict == C.CLEAR_MISS))[0]
    assert len(miss) + len(clear) == zero.sum() and len(miss) > 3 and len(clear) > 3
    for i in miss[:4]:
        assert mp_gap(as_case(b, i), cm.evidence[i]) < 0
    for i in clear[:4]:
        near = np.linspace(ts[i] - 1e-6, ts[i] + 1e-6, 41)
        assert min(mp_gap(as_case(b, i), t) for t in near) > 0


def test_mpmath_tier_gives_the_float_tiers_verdicts():
    """With float64 rounding bounds inflated 1e12-fold, mpmath decides alone (its own bounds
    stay far below anything that matters), and decides the same."""
    b, ts = solved("rotation", n=24)
    dropped = ts.copy()
    dropped[::3] = np.nan  # some certified misses too
    ref = C.check(b, dropped)
    forced = C.check(b, dropped, C.CheckTolerances(gap_round=1e12, overlap_round=1e12))
    assert forced.mp.sum() >= 10
    np.testing.assert_array_equal(forced.verdict, ref.verdict)


def test_translation_closed_forms():
    """Unit cubes, B sliding along x: touching at t = 0.5 (hit), a start inside (hit at 0),
    and a pass 1e-6 above (clear miss); a solver answer at 0.5 + 1e-9 is late."""
    n = 3
    eye = np.tile(np.eye(3), (n, 1, 1))
    h = np.full((n, 3), 0.5)
    start = np.array([[2.0, 0, 0], [0.5, 0, 0], [2.0, 1.0 + 1e-6, 0]])
    b = QueryBatch(-h, h, static(eye, np.zeros((n, 3))), -h, h, ballistic(eye, start, [[-2.0, 0, 0]] * n),
                   (0.0, 1.0), np.zeros(n), "")
    assert counts(C.check(b, np.array([0.5, 0.0, np.nan])).verdict) == counts(np.array([C.HIT, C.HIT, C.CLEAR_MISS]))
    assert C.VERDICTS[C.check(b, np.array([0.5 + 1e-9, 0.0, np.nan])).verdict[0]] == "late"
    assert C.VERDICTS[C.check(b, np.array([0.5, 0.0, 0.7])).verdict[2]] == "false_hit"


# ------------------------------------------------------------------ shards, report, CLI
def run(tmp_path, name="r.jsonl", **kw):
    args = dict(queries=600, families=["rotation", "one_static", "grazing"], seed=5, workers=0,
                report=tmp_path / name, shard_size=200, show_progress=False)
    return shards.validate(**(args | kw))


def records(path):
    lines = [json.loads(x) for x in open(path).read().splitlines()[1:]]
    return sorted((r for r in lines if "key" in r), key=lambda r: int(r["key"]))


def test_last_line_and_table(tmp_path, capsys):
    assert cli.main(["validate", "--queries", "300", "--families", "scale,far", "--workers", "0", "--no-progress",
                     "--shard-size", "100", "--report", str(tmp_path / "c.jsonl")]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert re.fullmatch(r"validated 300 queries: \d+ hits, 0 misses, 0 late, 0 false hits", out[-1])
    assert any(line.startswith("| far ") for line in out)


def test_resume_runs_only_missing_shards(tmp_path, monkeypatch):
    full, _ = run(tmp_path, "full.jsonl")
    total = full["total"]
    assert total["hits"] > 300 and total["misses"] == total["late"] == total["false_hits"] == total["early"] == 0, total
    calls = []
    real = shards.run_shard
    monkeypatch.setattr(shards, "run_shard", lambda *a: calls.append(a[1]) or real(*a))
    path = tmp_path / "cut.jsonl"
    run(tmp_path, "cut.jsonl", queries=400)  # shards 0 and 1 of the same run
    text = path.read_text().splitlines()
    path.write_text("\n".join(text[:2]) + "\n" + text[2][:40])  # shard 1 cut short mid-line
    calls.clear()
    resumed, info = run(tmp_path, "cut.jsonl")
    assert sorted(calls) == [1, 2] and info["queries_run"] == 400
    assert resumed == full
    calls.clear()
    again, info = run(tmp_path, "cut.jsonl")
    assert calls == [] and info["queries_run"] == 0 and again == full
    with pytest.raises(ReportMismatchError):
        run(tmp_path, "cut.jsonl", seed=6)


def test_failures_are_saved_and_replay_with_boxccd_toi(tmp_path, monkeypatch, capsys):
    """A solver that drops every fifth hit: validate counts the misses, exits 1, and each
    case file replays through ``boxccd toi`` to the real solver's hit."""
    real = shards.time_of_impact_batch

    def lossy(*args):
        t = real(*args)
        t[::5] = np.nan
        return t

    monkeypatch.setattr(shards, "time_of_impact_batch", lossy)
    report = tmp_path / "lossy.jsonl"
    code = cli.main(["validate", "--queries", "200", "--families", "one_static", "--workers", "0", "--no-progress",
                     "--report", str(report)])
    last = capsys.readouterr().out.strip().splitlines()[-1]
    misses = int(re.search(r"(\d+) misses", last).group(1))
    assert code == 1 and misses > 0
    files = sorted((tmp_path / "lossy_cases").glob("*_miss.json"))
    assert len(files) == misses
    monkeypatch.setattr(shards, "time_of_impact_batch", real)
    for f in files[:5]:
        case = read_case(f)
        assert case["verdict"] == "miss" and case["solver_t"] is None
        assert re.search(r"\d\.\d{19}", f.read_text())  # 20 significant digits
        batch = FAMILIES["one_static"](np.random.default_rng([case["seed"], case["shard"], shards.FAMILY_ID[
            "one_static"]]), 200)
        i = case["index"]
        np.testing.assert_array_equal(case["coeffs_b"], batch.coeffs_b[i])  # bit for bit
        assert cli.main(["toi", str(f)]) == 0
        toi = json.loads(capsys.readouterr().out)
        t = real(*(np.asarray(case[k])[None] for k in ("lo_a", "hi_a", "coeffs_a", "lo_b", "hi_b", "coeffs_b")),
                 case["t_range"])[0]
        assert toi["hit"] and toi["t"] == t
        # and that answer is a first contact, certified by the checker
        rows = (np.asarray(case[k], float)[None] for k in ("lo_a", "hi_a", "coeffs_a", "lo_b", "hi_b", "coeffs_b"))
        one = QueryBatch(*rows, tuple(case["t_range"]), np.zeros(1), "")
        verdict = C.check(one, np.array([t]))
        assert C.VERDICTS[verdict.verdict[0]] == "hit" and not verdict.early[0]


def test_ray_missing_is_a_clear_error(monkeypatch):
    from bullet_boxccd import _ray

    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(_ray.RayMissingError, match=r'pip install ".\[scale\]"'):
        next(_ray.map_unordered(len, [("a", ([],))]))


# ------------------------------------------------------------------ on Ray
def test_two_workers_equal_in_process_bit_for_bit(tmp_path, local_ray):
    one, _ = run(tmp_path, "inproc.jsonl")
    two, _ = run(tmp_path, "ray.jsonl", workers=2)
    assert two == one
    assert records(tmp_path / "ray.jsonl") == records(tmp_path / "inproc.jsonl")


def test_killed_worker_is_retried_with_the_same_totals(tmp_path, local_ray):
    local_ray.write_text("1")  # the worker that starts shard 1 dies on its first attempt
    want, _ = run(tmp_path, "ref.jsonl")
    got, _ = run(tmp_path, "killed.jsonl", workers=2)
    assert not local_ray.exists() and local_ray.with_name("kill.done").exists()  # it did die
    assert got == want
    assert records(tmp_path / "killed.jsonl") == records(tmp_path / "ref.jsonl")


# An answer early beyond the touching tolerance is early, not false: found by `boxccd validate
# --queries 4e5` (near_parallel, seed 0, shard 32, index 494): edges 1.7e-4 rad from parallel,
# the solver reports the edge-edge contact 2.6e-9 of the range before it happens, with the boxes
# still 9.3e-9 apart (8e-9 box sizes; docs/accuracy.md's worst near 1e-4 rad was 1.5e-9).
EARLY_NEAR_PARALLEL = """{
  "lo_a": [-0.57410332465273317126, -0.5745322487603543582, -0.53185583375552858421],
  "hi_a": [0.57410332465273317126, 0.5745322487603543582, 0.53185583375552858421],
  "coeffs_a": [[[0.87794780348441414652, 0.2180361133803051521, 0.4262251841678328379, 7.5812383272221479658],
      [-0.44323402364718744728, 0.70670003659486557712, 0.55146954454288776848, 6.3658497950717718439],
      [-0.18097307710932244995, -0.67307897867845067896, 0.71708676868476439736, -0.69910444292376405784],
      [0, 0, 0, 1]],
     [[0, 0, 0, 0],
      [0, 0, 0, 0],
      [0, 0, 0, 0],
      [0, 0, 0, 0]],
     [[0, 0, 0, 0],
      [0, 0, 0, 0],
      [0, 0, 0, 0],
      [0, 0, 0, 0]]],
  "lo_b": [-0.57410332465273317126, -0.5745322487603543582, -0.53185583375552858421],
  "hi_b": [0.57410332465273317126, 0.5745322487603543582, 0.53185583375552858421],
  "coeffs_b": [[[0.87792493316071595899, 0.21796560268437648045, 0.42630834824242996861, 8.8930355941037859679],
      [-0.4432636139242503992, 0.70660880784550672562, 0.55156265396232606602, 3.8129731352339488737],
      [-0.18101154743707789652, -0.67319758520183947681, 0.71696571115559382115, 0.19771575676448849279],
      [0, 0, 0, 1]],
     [[0, 0, 0, -1.8665121242275644065],
      [0, 0, 0, 3.2525046876581420463],
      [0, 0, 0, -1.3918856802458008382],
      [0, 0, 0, 0]],
     [[0, 0, 0, 0],
      [0, 0, 0, 0],
      [0, 0, 0, 0],
      [0, 0, 0, 0]]],
  "t_range": [0, 1],
  "solver_t": 0.34389952978551685536
}"""


def test_an_early_answer_is_counted_early_not_false():
    case = json.loads(EARLY_NEAR_PARALLEL)
    arrays = [np.asarray(case[k], float)[None] for k in ("lo_a", "hi_a", "coeffs_a", "lo_b", "hi_b", "coeffs_b")]
    b = QueryBatch(*arrays, tuple(case["t_range"]), np.zeros(1), "")
    c = C.check(b, np.array([case["solver_t"]]))
    assert C.VERDICTS[c.verdict[0]] == "hit" and c.early[0] and 5e-9 < c.early_gap[0] < 1e-8
    ref = reference(as_case(b, 0))
    assert ref.outcome == "hit" and case["solver_t"] < ref.t_hit < case["solver_t"] + 1e-8


KEEPER = """
import sys, ray
ctx = ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR")
print(ctx.address_info["gcs_address"], flush=True)
sys.stdin.read()  # until the test closes our stdin
ray.shutdown()
"""


def test_joins_a_running_cluster_by_address(tmp_path):
    """`--address` joins a Ray cluster that another process started (and leaves it up); the
    totals equal the in-process run's. Both sides use Ray's token authentication (the
    cluster's token is in ~/.ray/auth_token, which ray.init writes)."""
    pytest.importorskip("ray")
    import psutil

    env = dict(os.environ, RAY_AUTH_MODE="token")
    # Both run outside the checkout, so that they import the installed package.
    keeper = subprocess.Popen([sys.executable, "-c", KEEPER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              text=True, env=env, cwd=tmp_path)
    try:
        address = keeper.stdout.readline().strip()
        assert re.fullmatch(r"[\d.]+:\d+", address), address
        out = subprocess.run([sys.executable, "-m", "bullet_boxccd", "validate", "--queries", "600", "--families",
                              "rotation,one_static,grazing", "--seed", "5", "--shard-size", "200", "--address", address,
                              "--no-progress"], capture_output=True, text=True, check=True, env=env,
                             cwd=tmp_path).stdout
        assert psutil.Process(keeper.pid).is_running()  # the cluster outlives the command
        cluster = psutil.Process(keeper.pid).children(recursive=True)
    finally:
        keeper.stdin.close()
        keeper.wait(timeout=60)
    want, _ = run(tmp_path)
    assert out.strip().splitlines()[-1] == shards.last_line(want)
    _, alive = psutil.wait_procs(cluster, timeout=20)
    assert not alive, f"the cluster left processes behind: {alive}"
