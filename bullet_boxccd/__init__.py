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
    if name in ("BoxCCD", "BoxCCDWarning", "CCDEvent", "CCDStats"):
        from . import pybullet_ccd

        return getattr(pybullet_ccd, name)
    raise AttributeError(f"module 'bullet_boxccd' has no attribute {name!r}")


# A script that imported pybullet first gets the adapter now: importing it starts the
# journal of pybullet's world changes (filters, removals, teleports) that BoxCCD reads,
# so a world built before BoxCCD(...) is made is still seen whole.
if "pybullet" in _sys.modules:
    from . import pybullet_ccd  # noqa: E402, F401
