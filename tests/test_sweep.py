"""boxccd sweep: the trade-off grid of benchmarks/tradeoff.py as tasks, in-process and on Ray.

A tiny grid (10 boxes, the --quick configurations, 1 seed, 24 steps) keeps it fast; the
timing columns depend on where a task ran, every other column only on the trials' seeds.
"""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import pytest
import ray_local

from bullet_boxccd import cli
from bullet_boxccd.pybullet_ccd.tradeoff import grid as SW

local_ray = ray_local.local_ray  # the module's local Ray (a fixture)

ROOT = Path(__file__).resolve().parent.parent
TINY = ["--boxes", "10", "--quick", "--trials", "1", "--window", "24", "--no-progress"]
TIMING = {"us_per_step_median", "us_per_step_min"}


def rows_of(path):
    return [{k: v for k, v in r.items() if k not in TIMING} for r in csv.DictReader(open(path))]


def test_single_process_benchmark_and_sweep_on_ray_agree(tmp_path, local_ray):
    """benchmarks/tradeoff.py (in its own process) and `boxccd sweep` on 2 Ray workers
    write the same CSV (but timings) and a Pareto plot each."""
    subprocess.run([sys.executable, str(ROOT / "benchmarks" / "tradeoff.py"), "--boxes", "10", "--quick",
                    "--trials", "1", "--window", "24", "--csv", str(tmp_path / "bench.csv"), "--png",
                    str(tmp_path / "bench.png")], check=True, capture_output=True)
    assert cli.main(["sweep", *TINY, "--workers", "2", "--csv", str(tmp_path / "ray.csv"), "--png",
                     str(tmp_path / "ray.png"), "--report", str(tmp_path / "ray.jsonl")]) == 0
    want = rows_of(tmp_path / "bench.csv")
    assert len(want) == len(SW.configs(quick=True))
    assert rows_of(tmp_path / "ray.csv") == want
    assert (tmp_path / "bench.png").stat().st_size > 10_000 and (tmp_path / "ray.png").stat().st_size > 10_000
    plain = next(r for r in want if r["config"] == "plain")
    default = next(r for r in want if r["config"] == "BoxCCD default")
    assert plain["tunneled"] != "0" and default["tunneled"] == "0"  # the grid measures something


def test_resume_runs_only_missing_trials(tmp_path, monkeypatch):
    calls = []
    real = SW.task
    monkeypatch.setattr(SW, "task", lambda *a: calls.append(a[0][0]) or real(*a))
    kw = dict(boxes=[10], trials=1, window=12, quick=True, workers=0, report=tmp_path / "s.jsonl",
              show_progress=False)
    rows, _, meta = SW.sweep(**kw)
    n = len(calls)
    path = tmp_path / "s.jsonl"
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines[:-3]) + "\n" + lines[-3][:30])  # the last 3 trials lost, one cut mid-line
    calls.clear()
    again, _, meta2 = SW.sweep(**kw)
    assert len(calls) == 3 and meta2["tasks_run"] == 3 and n == meta["tasks_run"]
    strip = lambda rs: [{k: v for k, v in r.items() if k not in TIMING} for r in rs]  # noqa: E731
    assert strip(again) == strip(rows)


def test_several_scenes_write_one_plot_each(tmp_path):
    pytest.importorskip("matplotlib")  # the scale extra's; the plain test extra runs the rest
    rows, tunnels, meta = SW.sweep(boxes=[8, 10], trials=1, window=6, quick=True, workers=0, show_progress=False)
    written = SW.write_outputs(rows, str(tmp_path / "t.csv"), str(tmp_path / "t.png"), [8, 10])
    assert [Path(w).name for w in written] == ["t.csv", "t_8.png", "t_10.png"]
    assert {r["boxes"] for r in rows} == {8, 10}
    assert "trade-off, 8 boxes" in SW.summary_text(rows, tunnels, meta)


@pytest.mark.parametrize("bad", [["--boxes", "4"], ["--trials", "0"], ["--window", "1.5"], ["--workers", "-1"]])
def test_bad_grid_is_a_clear_error(bad, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit):
        cli.main(["sweep", *bad, "--workers", "0"] if "--workers" not in bad else ["sweep", *bad])
    assert "expected a whole number" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
    with pytest.raises(ValueError, match="expected scenes of >= 5 boxes"):
        SW.sweep(boxes=[3], workers=0)
