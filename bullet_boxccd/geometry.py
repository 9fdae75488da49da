"""Boxes and the BMS algorithm's names for their features.

A box is given by two corners in its own frame, ``lo = (X, Y, Z)`` and
``hi = (X', Y', Z')`` as in the seed. Faces are named after their planes
(``X`` is the face in the plane x = lo[0], ``X'`` the one at x = hi[0]), edges
by their two faces (``XY'``) and vertices by their three faces (``XY'Z``).
Internally a feature is a sign triple over the local axes: -1 for the lo side,
+1 for the hi side, 0 where the feature spans that axis. No pybullet, no solver.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np

from . import _core
from ._arrays import as_float_array

__all__ = ["Box", "BoxPairs", "feature_name", "SIGNS"]

# The corners of a box as sign triples (-1: lo, +1: hi), in the order of Box.vertices():
# (-,-,-), (-,-,+), (-,+,-), ...
SIGNS = np.array(list(product((-1, 1), repeat=3)), dtype=float)


@dataclass
class BoxPairs:
    """Box pairs as the solver's batch takes them: each box by its corners and its motion's
    coefficients; one pair with (3,) corners and (3, 4, 4) coefficients, n pairs with a
    leading axis of n."""

    lo_a: np.ndarray
    hi_a: np.ndarray
    coeffs_a: np.ndarray
    lo_b: np.ndarray
    hi_b: np.ndarray
    coeffs_b: np.ndarray


def feature_name(signs) -> str:
    """Seed name of the feature with this sign triple: (1, 0, -1) -> "X'Z"."""
    return _core.feature_name([int(np.sign(s)) for s in signs])


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Box:
    """A solid box, closed, in its own frame.

    Parameters
    ----------
    lo, hi : (3,) float
        The corners (X, Y, Z) and (X', Y', Z'); ``lo < hi`` on every axis.
    """

    lo: np.ndarray
    hi: np.ndarray
    # The validated copy for the core, in a slot (time_of_impact fetches it by name,
    # for subclasses too); the fields stay in the instance dict.
    __slots__ = ("_data", "__dict__")

    def __post_init__(self):
        lo = np.array(as_float_array("lo", self.lo, (3,)))
        hi = np.array(as_float_array("hi", self.hi, (3,)))
        object.__setattr__(self, "_data", _core.make_box(lo, hi, "Box"))
        object.__setattr__(self, "lo", _readonly(lo))
        object.__setattr__(self, "hi", _readonly(hi))

    @classmethod
    def centered(cls, half_extents, center=(0.0, 0.0, 0.0)) -> Box:
        """The box ``center +- half_extents`` (both (3,) float)."""
        h = as_float_array("half_extents", half_extents, (3,))
        c = as_float_array("center", center, (3,))
        return cls(c - h, c + h)

    @property
    def half_extents(self) -> np.ndarray:
        return 0.5 * (self.hi - self.lo)

    @property
    def center(self) -> np.ndarray:
        return 0.5 * (self.hi + self.lo)

    def vertices(self) -> np.ndarray:
        """(8, 3) corners in the box frame, ordered by sign triples (-,-,-), (-,-,+), ..."""
        return np.where(SIGNS > 0, self.hi, self.lo)

    def __reduce__(self):
        return type(self), (self.lo, self.hi)

    def __repr__(self) -> str:
        return f"Box(lo={self.lo.tolist()}, hi={self.hi.tolist()})"
