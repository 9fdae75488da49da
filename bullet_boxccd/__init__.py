"""Exact analytic continuous collision detection for boxes, plugged into pybullet."""

import sys as _sys

from . import solver as _solver
from .geometry import Box
from .motion import QuadraticMotion
from .solver import *  # noqa: F401,F403  (the solver's public names: solver.__all__)

# The pybullet adapter's names, imported on first use (the solver works without pybullet).
_ADAPTER = ("BoxCCD", "BoxCCDWarning", "ClientDisconnectedError", "CCDEvent", "CCDStats")

__all__ = [*_ADAPTER[:4], "Box", "QuadraticMotion", *_solver.__all__]


def __getattr__(name):
    if name in _ADAPTER:
        from . import pybullet_ccd

        return getattr(pybullet_ccd, name)
    raise AttributeError(f"module 'bullet_boxccd' has no attribute {name!r}")


# The journal of pybullet's world changes (filters, removals, teleports) that BoxCCD
# reads starts when the adapter is imported, so it must be in place before the world is
# built, whichever of bullet_boxccd and pybullet is imported first: now if pybullet is
# already imported, else when it is (an import hook; importing the adapter with
# bullet_boxccd would cost a script that only wants the solver ~40 ms and pybullet).
if "pybullet" in _sys.modules:
    from . import pybullet_ccd  # noqa: E402, F401
else:
    from ._import_hook import watch_for_pybullet as _watch  # noqa: E402

    _watch()
