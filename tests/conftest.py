import os
import sys

# The oracle and the case generator are plain modules beside the tests; the
# package under test is the installed one (pytest runs with --import-mode=importlib).
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import pytest
from hypothesis import HealthCheck, settings

# Deterministic: the same examples on every run and machine (CI reproducible).
settings.register_profile(
    "deterministic", derandomize=True, max_examples=60, deadline=None, print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))


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
