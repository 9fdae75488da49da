"""The Python face of the compiled BMS solver.

t runs over ``t_range = (t_min, t_max)``. Box A plays the BMS algorithm's static box S,
box B its moving box M (both may move). Contacts and planes are in world
coordinates. The Minkowski difference D(t) = A(t) + (-B(t)) contains the origin
exactly when the boxes intersect; its 30 facets (the BMS planes) are

* ``OV``: a face of A against a vertex of B (vertex of S's sphere / octant of M's),
* ``VO``: a face of B against a vertex of A,
* ``EE``: an edge of A against an edge of B (18 of them).

A facet's outward normal points from A towards B. See ``_core/solver/box_ccd.hpp`` for
the map of the core, ``Tolerances`` for the caller's tolerances and
``_core/solver/constants.hpp`` for every fixed constant. Every query says what happened
(``Outcome``): a contact, no contact, or a degraded answer (a cap reached, roots
closer than doubles can separate), never a degraded answer dressed as a hit.
"""

from __future__ import annotations

import enum
import inspect
import sys
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
    InvalidToleranceError,
    NonFiniteInputError,
    SingularMotionError,
)
from .geometry import Box
from .motion import QuadraticMotion

__all__ = [
    "Contact",
    "Feature",
    "Outcome",
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
    "InvalidToleranceError",
]


_CORE_DEFAULTS = _core.Tolerances()  # the defaults are defined once, in _core/solver/constants.hpp


@dataclass(frozen=True)
class Tolerances:
    """The caller's tolerances, in one frozen object (every fixed constant of the
    solver is in ``_core/solver/constants.hpp``, each with its reason).

    Guarantee: a reported contact time t is never later than the true first
    contact of the motions as given, and a pair that comes within
    ``gap_rel * size`` of touching (``size`` = sum over both boxes of their world
    half edge lengths) is reported as touching. Rounding can only move the answer
    earlier: each facet's evaluation error is bounded by ``rounding`` machine
    epsilons times a magnitude bound of its terms, and that bound is added to
    the touching tolerance. The magnitudes are those of the pair in its own frame
    (a shared translation is taken off both boxes), so a scene far from the
    origin is as exact as one at it.

    Attributes
    ----------
    gap_rel : float
        Touching tolerance relative to the boxes' world size (default 1e-12: a
        1e-9 relative gap is a clear miss, rounding noise (~1e-16) a hit); in [0, 0.1].
    rounding : float
        Multiple of DBL_EPSILON allowed per facet for rounding (default 64:
        the facet polynomials take about 20 dependent operations to build and
        evaluate, and each coefficient sums up to 12 products; measured, about 10x
        what rounding actually costs: benchmarks/solver_tradeoff.py); in [0, 1e10].
        0 drops the never-late guarantee.
    max_steps : int
        Cap on the advancement steps of one BMS search (each passes one root of
        one of the 30 facet polynomials of degree <= 6, or an octant switch, so
        exact arithmetic needs at most 180 per section); >= 1. On reaching it the
        solver reports contact at the current time with ``Outcome.STEP_CAP``.

    Raises ``InvalidToleranceError`` for a value outside those ranges (checked by
    the core, which keeps only valid tolerances).
    """

    gap_rel: float = _CORE_DEFAULTS.gap_rel
    rounding: float = _CORE_DEFAULTS.rounding
    max_steps: int = _CORE_DEFAULTS.max_steps

    def __post_init__(self):
        try:
            core = _core.Tolerances(float(self.gap_rel), float(self.rounding), int(self.max_steps))
        except (TypeError, ValueError, OverflowError) as e:
            if isinstance(e, InvalidInputError):
                raise
            raise InvalidToleranceError(f"Tolerances({self.gap_rel!r}, {self.rounding!r}, {self.max_steps!r}): "
                                        f"expected two numbers and an integer ({e})") from None
        object.__setattr__(self, "_core", core)


DEFAULT_TOLERANCES = Tolerances()


class Outcome(enum.IntEnum):
    """What a query found (the core's ``Outcome``, same values).

    ``SEPARATED``: no contact in the range. ``HIT``: a contact, ``Contact.t`` its
    time. ``INITIAL``: touching or overlapping at ``t_range[0]``. The degraded
    ones, whose ``t`` is early (the boxes are apart before it) but not proven a
    contact: ``STEP_CAP`` (the search reached a cap: ``Tolerances.max_steps`` or
    the core's cap on search windows) and ``CLUSTERED_ROOTS`` (the facet root it
    stopped at is one of a cluster that double precision cannot separate).
    ``NON_FINITE``: an input row was not finite (step-path queries only; the
    solver's own entry points raise ``NonFiniteInputError`` instead).
    """

    SEPARATED = 0
    HIT = 1
    INITIAL = 2
    STEP_CAP = 3
    CLUSTERED_ROOTS = 4
    NON_FINITE = 5


class Feature(NamedTuple):
    """Which BMS facet: ``kind`` is "OV" (face of A, vertex of B), "VO" (face of B,
    vertex of A) or "EE"; ``a`` and ``b`` are the seed names of the touching
    features of A and of B (``"X'"``, ``"XY'"``, ``"XY'Z"``)."""

    kind: str
    a: str
    b: str


class Contact(_core.ContactCore):
    """First contact of two boxes.

    A read-only record that behaves like the NamedTuple ``Contact(t, point, normal,
    feature, initial, outcome)``: fields by name, by position and by unpacking,
    ``_fields``, ``_asdict``, ``_replace``, ``_make``, equality with contacts and
    tuples of the same fields, pickling. The core builds contacts itself (no Python
    code runs per hit) and makes ``point`` and ``normal`` when first read; a contact
    always gives the same arrays, and a contact or array you hold never changes.

    Attributes
    ----------
    t : float
        Contact time in ``t_range`` (``t_range[0]`` when ``initial``). NaN for
        ``Outcome.NON_FINITE``.
    point : (3,) float
        World contact point: the vertex for a face-vertex contact, the midpoint of
        the closest points of the two edges for an edge-edge contact. NaN when
        there is no facet (``NON_FINITE``).
    normal : (3,) float
        Unit world normal of the touching facet, from A towards B. For an initial
        overlap, the facet of least penetration. NaN when there is no facet.
    feature : Feature or None
        Which BMS plane touched and which elements of A and B (None when there is
        no facet).
    initial : bool
        True when the boxes already touch or overlap at ``t_range[0]``.
    outcome : Outcome
        ``HIT`` or ``INITIAL`` for a contact; ``STEP_CAP`` or ``CLUSTERED_ROOTS``
        for a degraded answer (early, not proven); ``NON_FINITE`` from the step
        path. Never ``SEPARATED`` (that is ``None``).
    """

    __slots__ = ()
    _fields = ("t", "point", "normal", "feature", "initial", "outcome")
    _field_defaults: dict = {}
    __match_args__ = _fields

    def __iter__(self):
        return iter((self.t, self.point, self.normal, self.feature, self.initial, self.outcome))

    def __len__(self) -> int:
        return 6

    def __getitem__(self, index):
        return tuple(self)[index]

    def __eq__(self, other):
        if isinstance(other, (Contact, tuple)):
            return tuple(self) == tuple(other)
        return NotImplemented

    def __hash__(self):
        return hash(tuple(self))

    def __repr__(self) -> str:
        return f"{type(self).__name__}(" + ", ".join(f"{k}={v!r}" for k, v in zip(self._fields, self)) + ")"

    def __reduce__(self):
        return type(self), tuple(self)

    def _asdict(self) -> dict:
        return dict(zip(self._fields, self))

    def _replace(self, **changes) -> Contact:
        fields = self._asdict()
        unexpected = set(changes) - set(fields)
        if unexpected:
            raise ValueError(f"Got unexpected field names: {sorted(unexpected)!r}")
        fields.update(changes)
        return type(self)(**fields)

    @classmethod
    def _make(cls, iterable) -> Contact:
        values = tuple(iterable)
        if len(values) != 6:
            raise TypeError(f"Expected 6 arguments, got {len(values)}")
        return cls(*values)

    def count(self, value) -> int:
        return tuple(self).count(value)

    def index(self, value, *args) -> int:
        return tuple(self).index(value, *args)


# The core builds Contact and Feature instances itself (no Python code runs per hit).
_core.set_result_types(Contact, Feature, Outcome)


class Plane(NamedTuple):
    """A BMS facet at one time: points x of D = A - B on it satisfy ``normal . x = offset``."""

    normal: np.ndarray
    offset: float
    feature: Feature


def _t_range(t_range) -> tuple[float, float]:
    r = as_float_array("t_range", t_range, (2,))  # values are checked by the core
    return float(r[0]), float(r[1])


def _core_tolerances(tolerances):
    if tolerances is None:
        return DEFAULT_TOLERANCES._core
    if not isinstance(tolerances, Tolerances):
        raise InvalidInputError(f"tolerances: expected a Tolerances, got {type(tolerances).__name__}")
    return tolerances._core


def _pair_args(a, m_a, b, m_b):
    for name, v, cls in (("a", a, Box), ("m_a", m_a, QuadraticMotion), ("b", b, Box), ("m_b", m_b, QuadraticMotion)):
        if not isinstance(v, cls):
            raise InvalidInputError(f"{name}: expected a {cls.__name__}, got {type(v).__name__}")
    return a._data, m_a._data, b._data, m_b._data


def _time_of_impact(
    a: Box,
    m_a: QuadraticMotion,
    b: Box,
    m_b: QuadraticMotion,
    t_range=(0.0, 1.0),
    tolerances: Optional[Tolerances] = None,
) -> Optional[Contact]:
    """First time in ``t_range`` at which box ``a`` moving by ``m_a`` touches box ``b``
    moving by ``m_b``; None if they never do. ``tolerances``: None for the defaults.

    Raises an ``InvalidInputError`` subclass for bad input (for example
    ``SingularMotionError`` when a 3x3 part collapses inside ``t_range``).
    """
    return _core.solve(*_pair_args(a, m_a, b, m_b), _t_range(t_range), _core_tolerances(tolerances))


def _make_time_of_impact():
    """The public function: a builtin made by the core from the one above. The common
    call (boxes, motions, a tuple of two floats, Tolerances or None) runs no Python
    code; any other call, and any the core raises on, runs the function above, which
    converts or names what is wrong. Its doc starts with the function's signature
    without annotations (a builtin's text signature)."""
    sig = inspect.signature(_time_of_impact)
    plain = sig.replace(parameters=[p.replace(annotation=p.empty) for p in sig.parameters.values()],
                        return_annotation=sig.empty)
    doc = f"time_of_impact{plain}\n--\n\n{inspect.getdoc(_time_of_impact)}"
    return _core.make_time_of_impact(sys.modules[__name__], "_time_of_impact", tuple(sig.parameters), doc,
                                     Box, QuadraticMotion)


time_of_impact = _make_time_of_impact()


def time_of_impact_batch(
    lo_a, hi_a, coeffs_a, lo_b, hi_b, coeffs_b, t_range=(0.0, 1.0), tolerances: Tolerances = DEFAULT_TOLERANCES,
    states: bool = False,
):
    """Contact times of N box pairs, NaN where a pair never touches.

    Parameters
    ----------
    lo_a, hi_a, lo_b, hi_b : (N, 3) float
        Box corners (each box in its own frame).
    coeffs_a, coeffs_b : (N, 3, 4, 4) float
        Quadratic motions.
    states : bool
        Also return each row's ``Outcome``.

    Returns
    -------
    t : (N,) float64
        Contact time, NaN where the pair stays apart (``Outcome.SEPARATED``). A
        degraded row (``STEP_CAP``, ``CLUSTERED_ROOTS``) has its early time here
        too (the pair is apart before it): ask for ``states`` to tell it from a hit.
    states : (N,) int8, only with ``states=True``
        Each row's ``Outcome`` value (``Outcome(states[i])`` names it).

    Bad rows raise one ``InvalidInputError`` subclass whose message names the
    first bad row's problem and lists every bad row's index. The GIL is released
    while solving.
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
    return _core.solve_batch(*arrays, t0, t1, _core_tolerances(tolerances), bool(states))


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
