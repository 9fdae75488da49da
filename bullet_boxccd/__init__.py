"""Exact analytic continuous collision detection for boxes, plugged into pybullet."""

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
    NonFiniteInputError,
    Plane,
    SingularMotionError,
    Tolerances,
    bms_planes,
    sections,
    time_of_impact,
    time_of_impact_batch,
)

__all__ = [
    "Box",
    "QuadraticMotion",
    "Contact",
    "Feature",
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
]
