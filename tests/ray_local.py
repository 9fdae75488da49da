"""A local Ray for one test module: 2 CPUs, started on first use, shut down after the
module's last test, with a check that no process of it is left behind. Tests import the
fixture; ``local_ray`` yields the fault file of ``bullet_boxccd._ray`` (write a task key
into it to kill the worker that starts that task, once)."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="module")
def local_ray(tmp_path_factory):
    ray = pytest.importorskip("ray")
    import psutil

    from bullet_boxccd._ray import FAULT_ENV, init

    fault = tmp_path_factory.mktemp("fault") / "kill"
    os.environ[FAULT_ENV] = str(fault)
    init(num_cpus=2, include_dashboard=False, logging_level="ERROR", log_to_driver=False,
         runtime_env={"env_vars": {FAULT_ENV: str(fault)}})
    yield fault
    ray.shutdown()
    del os.environ[FAULT_ENV]
    _, alive = psutil.wait_procs(psutil.Process().children(recursive=True), timeout=20)
    assert not alive, f"Ray left processes behind: {alive}"
