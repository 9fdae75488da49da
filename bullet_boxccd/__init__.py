"""Exact analytic continuous collision detection for boxes, plugged into pybullet."""

import sys as _sys

from .geometry import Box
from .motion import QuadraticMotion
from .solver import (
    Contact,
    Feature,
    InvalidBoxError,
    InvalidInputError,
    InvalidMotionError,
    InvalidShapeError,
    InvalidTimeRangeError,
    InvalidToleranceError,
    NonFiniteInputError,
    Outcome,
    Plane,
    SingularMotionError,
    Tolerances,
    bms_planes,
    sections,
    time_of_impact,
    time_of_impact_batch,
)

__all__ = [
    "BoxCCD",
    "BoxCCDWarning",
    "ClientDisconnectedError",
    "CCDEvent",
    "Box",
    "QuadraticMotion",
    "Contact",
    "Feature",
    "Outcome",
    "Plane",
    "Tolerances",
    "time_of_impact",
    "time_of_impact_batch",
    "sections",
    "bms_planes",
    "InvalidInputError",
    "InvalidShapeError",
    "NonFiniteInputError",
    "InvalidBoxError",
    "InvalidMotionError",
    "SingularMotionError",
    "InvalidTimeRangeError",
    "InvalidToleranceError",
]


def __getattr__(name):
    # The pybullet adapter is imported on first use, so the solver works without pybullet.
    if name in ("BoxCCD", "BoxCCDWarning", "ClientDisconnectedError", "CCDEvent", "CCDStats"):
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
