"""The solver's tests fail when the solver is wrong: each solver test file runs
again (in a subprocess) with the core's contact queries replaced by a broken stub
(tests/conftest.py, --broken-solver): one that never reports a contact, one that
reports every pair touching at t_range[0]. Every test that queries the solver must
fail under both. Part of the stress tier (it runs the files twice)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
SOLVER_TESTS = ["test_solver.py", "test_solver_oracle.py", "test_solver_poly.py", "test_properties.py",
                "test_fuzz.py", "test_stress.py", "test_bms_planes.py", "test_step_path.py", "test_validate.py"]


@pytest.mark.stress
@pytest.mark.parametrize("mode", ["never", "t0"])
def test_every_solver_test_fails_against_a_broken_solver(mode, tmp_path):
    report = tmp_path / "report.jsonl"
    root = os.path.dirname(HERE)
    # Run from an empty directory: `python -m pytest` puts its working directory first on
    # sys.path, and from the checkout that would import the source tree (no compiled
    # core) instead of the installed package.
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-c", os.path.join(root, "pyproject.toml"),
           "--rootdir", root, "-m", "not stress", f"--broken-solver={mode}", f"--broken-solver-report={report}",
           *[os.path.join(HERE, f) for f in SOLVER_TESTS]]
    run = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=1800)
    assert report.exists(), f"the broken-solver run wrote no report:\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}"
    rows = [json.loads(line) for line in report.read_text().splitlines()]
    queried = [r for r in rows if r["queried"]]
    passed = [r["test"] for r in queried if r["outcome"] != "failed"]
    assert len(queried) >= 60, f"only {len(queried)} of {len(rows)} tests queried the solver"
    assert not passed, f"passed against a solver that answers '{mode}':\n" + "\n".join(passed)
