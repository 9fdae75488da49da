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
                "test_fuzz.py", "test_stress.py", "test_bms_planes.py", "test_step_path.py"]


@pytest.mark.stress
@pytest.mark.parametrize("mode", ["never", "t0"])
def test_every_solver_test_fails_against_a_broken_solver(mode, tmp_path):
    report = tmp_path / "report.jsonl"
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "not stress",
           f"--broken-solver={mode}", f"--broken-solver-report={report}",
           *[os.path.join(HERE, f) for f in SOLVER_TESTS]]
    subprocess.run(cmd, cwd=os.path.dirname(HERE), capture_output=True, text=True, timeout=1800)
    rows = [json.loads(line) for line in report.read_text().splitlines()]
    queried = [r for r in rows if r["queried"]]
    passed = [r["test"] for r in queried if r["outcome"] != "failed"]
    assert len(queried) >= 60, f"only {len(queried)} of {len(rows)} tests queried the solver"
    assert not passed, f"passed against a solver that answers '{mode}':\n" + "\n".join(passed)
