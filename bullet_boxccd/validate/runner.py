"""Where tasks run: in this process (``workers=0``) or on Ray (``bullet_boxccd._ray``).

Both yield ``(key, result)`` for ``(key, args)`` jobs, the in-process loop in order, Ray
as tasks finish; callers must not depend on the order (they key results). A tqdm bar
counts ``weight(result)`` units (queries, trials) when tqdm is installed.
"""

from __future__ import annotations

from contextlib import contextmanager

__all__ = ["run_jobs", "progress"]


def run_jobs(fn, jobs, workers=None, address=None):
    """Yield ``(key, fn(*args))`` for every ``(key, args)`` job."""
    if workers == 0 and not address:
        for key, args in jobs:
            yield key, fn(*args)
        return
    from .. import _ray

    yield from _ray.map_unordered(fn, jobs, workers=workers, address=address)


class _NoBar:
    def update(self, n):
        pass

    def close(self):
        pass


@contextmanager
def progress(total, initial=0, desc="", unit="", enabled=True):
    """A tqdm bar on stderr (a no-op without tqdm or when not ``enabled``)."""
    bar = _NoBar()
    if enabled:
        try:
            from tqdm import tqdm

            bar = tqdm(total=total, initial=initial, desc=desc, unit=unit, unit_scale=True, smoothing=0.1)
        except ImportError:
            pass
    try:
        yield bar
    finally:
        bar.close()
