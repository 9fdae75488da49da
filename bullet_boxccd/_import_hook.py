"""Installs the pybullet adapter's hooks the moment pybullet is imported.

``import bullet_boxccd`` before ``import pybullet`` must still journal every world change
(``pybullet_ccd._hooks``), without importing pybullet for a script that only wants the
solver. A ``sys.meta_path`` finder answers for the module ``pybullet`` only: it finds it
with the other finders and wraps the loader so that, once pybullet's own initialisation
has run, the adapter is imported (which wraps pybullet's world-changing functions) before
the importing statement gets the module. The finder then removes itself.
"""

from __future__ import annotations

import importlib.abc
import sys
import warnings

__all__ = ["watch_for_pybullet"]


class _Loader(importlib.abc.Loader):
    def __init__(self, loader):
        self.loader = loader

    def create_module(self, spec):
        return self.loader.create_module(spec)

    def exec_module(self, module):
        self.loader.exec_module(module)
        _unwatch()
        try:
            from . import pybullet_ccd  # noqa: F401 - installs the hooks
        except Exception as e:  # pybullet itself is fine: do not fail the user's import for us
            warnings.warn(f"bullet_boxccd could not install its pybullet hooks ({e!r}): BoxCCD will not see "
                          "world changes made through pybullet's own functions", stacklevel=2)

    def __getattr__(self, name):  # anything else a loader is asked (resource readers, ...)
        return getattr(self.loader, name)


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name != "pybullet":
            return None
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(name, path, target)
            if spec is not None:
                if spec.loader is not None and hasattr(spec.loader, "exec_module"):
                    spec.loader = _Loader(spec.loader)
                return spec
        return None


_finder = _Finder()


def watch_for_pybullet() -> None:
    """Install the adapter when pybullet is imported (at once if it already is)."""
    if "pybullet" in sys.modules:
        from . import pybullet_ccd  # noqa: F401
    elif _finder not in sys.meta_path:
        sys.meta_path.insert(0, _finder)


def _unwatch() -> None:
    if _finder in sys.meta_path:
        sys.meta_path.remove(_finder)
