"""Test configuration: the case modules beside the tests, the
deterministic hypothesis profile, and --broken-solver, which swaps the core's
contact queries for a broken stub to check that the tests can fail:

    pytest tests/test_solver.py --broken-solver=never --broken-solver-report=r.jsonl

``never``: no pair ever touches; ``t0``: every pair touches at t_range[0]. The
report has one JSON line per test: did it query the solver, and its outcome.
Every test that queries the solver must fail under both (tests/test_solver_meta.py
checks it)."""

import json
import os
import sys

import numpy as np

# The case generators (cases.py, stress.py) are plain modules beside the tests; the
# package under test is the installed one (pytest runs with --import-mode=importlib).
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import pytest  # noqa: E402
from hypothesis import HealthCheck, Phase, settings  # noqa: E402

# Deterministic: the same examples on every run and machine (CI reproducible).
settings.register_profile(
    "deterministic", derandomize=True, max_examples=60, deadline=None, print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
# Under a broken solver every example fails: report the first, do not shrink.
settings.register_profile(
    "broken", derandomize=True, max_examples=60, deadline=None, phases=[Phase.explicit, Phase.generate],
    suppress_health_check=list(HealthCheck),
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))

_queried = [False]  # set by the broken stubs while a test runs
_report = []


def pytest_addoption(parser):
    parser.addoption("--broken-solver", choices=("never", "t0"), default=None,
                     help="replace the core's contact queries by a broken stub (see tests/conftest.py)")
    parser.addoption("--broken-solver-report", default=None, help="JSON lines: per test, queried the solver? outcome")


def _broken_core(mode):
    """Stand-ins for _core.solve, solve_batch, first_touches and the box paths' contact queries
    (paths_contact, paths_first_touch, paths_window_contact)."""
    from bullet_boxccd.solver import Contact, Feature, Outcome

    def contact(t):
        return Contact(t, np.zeros(3), np.array([1.0, 0.0, 0.0]), Feature("OV", "X'", "X"), True, Outcome.INITIAL)

    def solve(a, m_a, b, m_b, t_range, tol):
        _queried[0] = True
        return None if mode == "never" else contact(float(t_range[0]))

    def solve_batch(lo_a, hi_a, c_a, lo_b, hi_b, c_b, t0, t1, tol, states=False):
        _queried[0] = True
        t = np.full(len(lo_a), np.nan if mode == "never" else t0)
        code = Outcome.SEPARATED if mode == "never" else Outcome.INITIAL
        return (t, np.full(len(lo_a), int(code), dtype=np.int8)) if states else t

    def first_touches(rows, pairs, fit_tolerance, tol, penetration=0.0, creep=-1.0, states=False):
        _queried[0] = True
        tau = np.full(len(pairs), np.nan if mode == "never" else 0.0)
        code = Outcome.SEPARATED if mode == "never" else Outcome.INITIAL
        out = (tau, np.full(len(pairs), int(code), dtype=np.int8)) if states else (tau,)
        return (*out, len(pairs))

    def paths_window_contact(a, b, lo, hi, tol):
        _queried[0] = True
        return None if mode == "never" else contact(float(lo))

    def paths_first_touch(a, b, fit_tolerance, tol, state=False):
        _queried[0] = True
        t, code = (np.nan, Outcome.SEPARATED) if mode == "never" else (0.0, Outcome.INITIAL)
        return (t, int(code), 1) if state else (t, 1)

    def paths_contact(a, b, fit_tolerance, tol):
        _queried[0] = True
        return (np.nan, 1, None) if mode == "never" else (0.0, 1, contact(0.0))

    return dict(solve=solve, solve_batch=solve_batch, first_touches=first_touches,
                paths_window_contact=paths_window_contact, paths_first_touch=paths_first_touch,
                paths_contact=paths_contact)


def pytest_configure(config):
    mode = config.getoption("--broken-solver")
    if mode:
        from bullet_boxccd import _core

        for name, stub in _broken_core(mode).items():
            setattr(_core, name, stub)
        _core.set_fast_time_of_impact(False)  # time_of_impact's common call would not reach the stub
        settings.load_profile("broken")


@pytest.fixture(autouse=True)
def _track_queries():
    _queried[0] = False
    yield


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if report.when == "call" or (report.when == "setup" and report.outcome != "passed"):
        _report.append(dict(test=item.nodeid, queried=_queried[0], outcome=report.outcome))


def pytest_sessionfinish(session):
    path = session.config.getoption("--broken-solver-report")
    if path:
        with open(path, "w") as f:
            f.writelines(json.dumps(r) + "\n" for r in _report)


@pytest.fixture(scope="module")
def cid():
    """A pybullet DIRECT client for one test module, with pybullet_data on its search path
    (pybullet is imported here, not at the top: the solver's tests run without it)."""
    import pybullet as p
    import pybullet_data

    c = p.connect(p.DIRECT)
    p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=c)
    yield c
    p.disconnect(c)
