"""The Python face of the compiled BMS solver.

t runs over ``t_range = (t_min, t_max)``. Box A plays the seed's static box S,
box B its moving box M (both may move). Contacts and planes are in world
coordinates. The Minkowski difference D(t) = A(t) + (-B(t)) contains the origin
exactly when the boxes intersect; its 30 facets (the seed's BMS planes) are

* ``OV``: a face of A against a vertex of B (vertex of S's sphere / octant of M's),
* ``VO``: a face of B against a vertex of A,
* ``EE``: an edge of A against an edge of B (18 of them).

A facet's outward normal points from A towards B. See ``_core/box_ccd.hpp`` for
the algebra and ``Tolerances`` for every tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Optional

import numpy as np

from . import _core
from ._arrays import InvalidShapeError, as_float_array
from ._core import (
    InvalidBoxError,
    InvalidInputError,
    InvalidMotionError,
    InvalidTimeRangeError,
    NonFiniteInputError,
    SingularMotionError,
)
from .geometry import Box
from .motion import QuadraticMotion

__all__ = [
    "Contact",
    "Feature",
    "Plane",
    "Tolerances",
    "bms_planes",
    "sections",
    "time_of_impact",
    "time_of_impact_batch",
    "InvalidInputError",
    "InvalidShapeError",
    "NonFiniteInputError",
    "InvalidBoxError",
    "InvalidMotionError",
    "SingularMotionError",
    "InvalidTimeRangeError",
]


@dataclass(frozen=True)
class Tolerances:
    """Every tolerance of the solver, in one frozen object.

    Guarantee: a reported contact time t is never later than the true first
    contact of the motions as given, and a pair that comes within
    ``gap_rel * size`` of touching (``size`` = sum over both boxes of their world
    half edge lengths) is reported as touching. Rounding can only move the answer
    earlier: each facet's evaluation error is bounded by ``rounding`` machine
    epsilons times a magnitude bound of its terms, and that bound is added to
    the touching tolerance.

    Attributes
    ----------
    gap_rel : float
        Touching tolerance relative to the boxes' world size (default 1e-12: a
        1e-9 relative gap is a clear miss, rounding noise (~1e-16) a hit); at most 0.1.
    rounding : float
        Multiple of DBL_EPSILON allowed per facet for rounding (default 64:
        the facet polynomials take about 20 dependent operations to build and
        evaluate, and each coefficient sums up to 12 products; measured, about 10x
        what rounding actually costs: benchmarks/solver_tradeoff.py); at most 1e10.
    max_steps : int
        Cap on advancement steps per section (each passes one root of one of the
        30 facet polynomials of degree <= 6, so exact arithmetic needs at most
        180). On reaching it the solver reports contact at the current time.
    """

    gap_rel: float = 1e-12
    rounding: float = 64.0
    max_steps: int = 400

    def __post_init__(self):
        # Upper bounds keep the tolerances meaningful: a touching tolerance of a tenth
        # of the boxes' size, or a rounding allowance of 1e10 eps (2e-6 relative),
        # is already far past any use.
        for name, top in (("gap_rel", 0.1), ("rounding", 1e10)):
            v = getattr(self, name)
            if not (np.isfinite(v) and 0.0 <= v <= top):
                raise InvalidInputError(f"Tolerances.{name} is {v!r}; expected a number in [0, {top:g}]")
        if int(self.max_steps) < 1:
            raise InvalidInputError(f"Tolerances.max_steps is {self.max_steps!r}; expected an integer >= 1")
        core = _core.Tolerances()
        core.gap_rel, core.rounding, core.max_steps = float(self.gap_rel), float(self.rounding), int(self.max_steps)
        object.__setattr__(self, "_core", core)


DEFAULT_TOLERANCES = Tolerances()


class Feature(NamedTuple):
    """Which BMS facet: ``kind`` is "OV" (face of A, vertex of B), "VO" (face of B,
    vertex of A) or "EE"; ``a`` and ``b`` are the seed names of the touching
    features of A and of B (``"X'"``, ``"XY'"``, ``"XY'Z"``)."""

    kind: str
    a: str
    b: str


class Contact(NamedTuple):
    """First contact of two boxes.

    Attributes
    ----------
    t : float
        Contact time in ``t_range`` (``t_range[0]`` when ``initial``).
    point : (3,) float
        World contact point: the vertex for a face-vertex contact, the midpoint of
        the closest points of the two edges for an edge-edge contact.
    normal : (3,) float
        Unit world normal of the touching facet, from A towards B. For an initial
        overlap, the facet of least penetration.
    feature : Feature
        Which BMS plane touched and which elements of A and B.
    initial : bool
        True when the boxes already touch or overlap at ``t_range[0]``.
    """

    t: float
    point: np.ndarray
    normal: np.ndarray
    feature: Feature
    initial: bool


# The core builds Contact and Feature instances itself (no Python code runs per hit).
_core.set_result_types(Contact, Feature)


class Plane(NamedTuple):
    """A BMS facet at one time: points x of D = A - B on it satisfy ``normal . x = offset``."""

    normal: np.ndarray
    offset: float
    feature: Feature


def _t_range(t_range) -> tuple[float, float]:
    r = as_float_array("t_range", t_range, (2,))  # values are checked by the core
    return float(r[0]), float(r[1])


def _core_tolerances(tolerances):
    if not isinstance(tolerances, Tolerances):
        raise InvalidInputError(f"tolerances: expected a Tolerances, got {type(tolerances).__name__}")
    return tolerances._core


def _pair_args(a, m_a, b, m_b):
    for name, v, cls in (("a", a, Box), ("m_a", m_a, QuadraticMotion), ("b", b, Box), ("m_b", m_b, QuadraticMotion)):
        if not isinstance(v, cls):
            raise InvalidInputError(f"{name}: expected a {cls.__name__}, got {type(v).__name__}")
    return a._data, m_a._data, b._data, m_b._data


def time_of_impact(
    a: Box,
    m_a: QuadraticMotion,
    b: Box,
    m_b: QuadraticMotion,
    t_range=(0.0, 1.0),
    tolerances: Tolerances = DEFAULT_TOLERANCES,
) -> Optional[Contact]:
    """First time in ``t_range`` at which box ``a`` moving by ``m_a`` touches box ``b``
    moving by ``m_b``; None if they never do.

    Raises an ``InvalidInputError`` subclass for bad input (for example
    ``SingularMotionError`` when a 3x3 part collapses inside ``t_range``).
    """
    try:  # the common case: one core call, which rejects wrong types with a TypeError
        return _core.solve(a._data, m_a._data, b._data, m_b._data, t_range, tolerances._core)
    except (AttributeError, TypeError):
        pass
    # Something is of the wrong type or shape: the checks below say what.
    return _core.solve(*_pair_args(a, m_a, b, m_b), _t_range(t_range), _core_tolerances(tolerances))


def time_of_impact_batch(
    lo_a, hi_a, coeffs_a, lo_b, hi_b, coeffs_b, t_range=(0.0, 1.0), tolerances: Tolerances = DEFAULT_TOLERANCES
) -> np.ndarray:
    """Contact times of N box pairs, NaN where a pair never touches.

    Parameters
    ----------
    lo_a, hi_a, lo_b, hi_b : (N, 3) float
        Box corners (each box in its own frame).
    coeffs_a, coeffs_b : (N, 3, 4, 4) float
        Quadratic motions.

    Returns
    -------
    (N,) float64. Bad rows raise one ``InvalidInputError`` subclass whose message
    names the first bad row's problem and lists every bad row's index. The GIL is
    released while solving.
    """
    t0, t1 = _t_range(t_range)
    arrays = [
        as_float_array(name, v, shape)
        for name, v, shape in (
            ("lo_a", lo_a, (-1, 3)),
            ("hi_a", hi_a, (-1, 3)),
            ("coeffs_a", coeffs_a, (-1, 3, 4, 4)),
            ("lo_b", lo_b, (-1, 3)),
            ("hi_b", hi_b, (-1, 3)),
            ("coeffs_b", coeffs_b, (-1, 3, 4, 4)),
        )
    ]
    n = {len(x) for x in arrays}
    if len(n) != 1:
        raise InvalidShapeError(f"batch arrays disagree on N: got lengths {[len(x) for x in arrays]}")
    return _core.solve_batch(*arrays, t0, t1, _core_tolerances(tolerances))


def sections(a, m_a, b, m_b, t_range=(0.0, 1.0), tolerances: Tolerances = DEFAULT_TOLERANCES) -> np.ndarray:
    """The route division: ``t_range[0]``, every octant switch in order, ``t_range[1]``.

    Between consecutive entries (a section) the BMS topology is constant.
    """
    t0, t1 = _t_range(t_range)
    return _core.sections(*_pair_args(a, m_a, b, m_b), t0, t1, _core_tolerances(tolerances))


def bms_planes(a, m_a, b, m_b, t: float, t_range=(0.0, 1.0), tolerances: Tolerances = DEFAULT_TOLERANCES):
    """The 30 BMS planes at time ``t``, from the section containing ``t``.

    Returns a list of 30 ``Plane`` (unit outward normal, offset, feature) in facet
    order: OV (6), VO (6), EE (18); facet 2k and 2k+1 share an axis with opposite
    normals.
    """
    t0, t1 = _t_range(t_range)
    tol = _core_tolerances(tolerances)
    normals, offsets, features = _core.planes(*_pair_args(a, m_a, b, m_b), t0, t1, float(t), tol)
    return [Plane(normals[k], float(offsets[k]), Feature(*features[k])) for k in range(30)]
