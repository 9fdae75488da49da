"""Ray, for ``boxccd validate`` and ``boxccd sweep`` (the only module that imports ray).

``map_unordered(fn, jobs)`` runs ``fn(*args)`` for every ``(key, args)`` job as a Ray task
and yields ``(key, result)`` as tasks finish. With ``address`` it joins that cluster
(``ray.init(address=...)``: "auto" for the cluster the local machine belongs to, or
"ray://host:10001" through Ray Client); without one it starts a local Ray on this
machine's cores (or ``workers`` of them) and shuts it down afterwards. ``workers``
bounds the tasks in flight (default: the cluster's CPUs), so results stream back and
an interruption loses only those.

Faults: a task whose worker process dies (killed, out of memory, node lost) is run
again by Ray, up to ``max_retries`` times; a task is a pure function of its arguments,
so a retry gives the same result and the caller counts it once. Exceptions raised by
``fn`` itself are not retried (a bug does not go away on a retry): they reach the caller.

Fault injection (for tests and for trying a cluster's recovery): if the environment
variable ``BOXCCD_FAULT_FILE`` names a file that exists and holds a job key, the worker
that starts that job renames the file (so the retry proceeds) and exits at once with
``os._exit``, as a killed process would.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["RayMissingError", "init", "map_unordered"]

FAULT_ENV = "BOXCCD_FAULT_FILE"


class RayMissingError(ImportError):
    """Ray is needed and not installed."""


def _ray():
    try:
        import ray
    except ImportError:
        raise RayMissingError(
            'this needs Ray: pip install ".[scale]" in the bullet_boxccd checkout (the package is not on an '
            "index), or run in this process with --workers 0") from None
    return ray


def init(**kwargs):
    """``ray.init(**kwargs)``, started from the directory this package was imported from.

    Ray puts the driver's working directory on every worker's ``sys.path``, ahead of
    site-packages; run from a source checkout, that is the uninstalled ``bullet_boxccd/``
    (without its compiled core), which workers would import instead of the installed
    package. From the package's own parent directory, workers import what the driver did."""
    ray = _ray()
    here = os.getcwd()
    os.chdir(Path(__file__).resolve().parent.parent)
    try:
        return ray.init(**kwargs)
    finally:
        os.chdir(here)


def _maybe_die(key: str) -> None:
    path = os.environ.get(FAULT_ENV)
    if not path or not os.path.exists(path):
        return
    try:
        with open(path) as fh:
            if fh.read().strip() != key:
                return
        os.rename(path, path + ".done")  # atomic: exactly one attempt dies
    except OSError:
        return
    os._exit(17)


def _run(key, fn, args):
    _maybe_die(key)
    return fn(*args)


def map_unordered(fn, jobs, workers=None, address=None, max_retries=3):
    """Yield ``(key, fn(*args))`` for each ``(key, args)`` in ``jobs``, in completion order."""
    ray = _ray()
    own = not ray.is_initialized()
    if own:
        env = {k: v for k, v in os.environ.items() if k == FAULT_ENV}
        # Workers' own output (pybullet's banner, per task) stays in Ray's logs; results and errors come back.
        common = dict(logging_level="ERROR", log_to_driver=False, runtime_env={"env_vars": env} if env else None)
        if address:  # an existing cluster brings its own resources
            init(address=address, **common)
        else:
            init(num_cpus=workers or os.cpu_count(), include_dashboard=False, **common)
    try:
        slots = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
        task = ray.remote(num_cpus=1, max_retries=max_retries)(_run)
        jobs = iter(jobs)
        pending = {}

        def submit():
            for key, args in jobs:
                pending[task.remote(key, fn, args)] = key
                if len(pending) >= slots:
                    return

        submit()
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            key = pending.pop(done[0])
            yield key, ray.get(done[0])
            submit()
    finally:
        if own:
            ray.shutdown()
