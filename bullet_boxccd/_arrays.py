"""Shape and dtype checks at the package boundary (values are checked by the core)."""

from __future__ import annotations

import numpy as np

from ._core import InvalidInputError, NonFiniteInputError

__all__ = ["InvalidShapeError", "as_float_array"]


class InvalidShapeError(InvalidInputError):
    """An argument has the wrong shape or cannot be read as float64."""


def as_float_array(name: str, value, shape: tuple, finite: bool = False) -> np.ndarray:
    """``value`` as a C-contiguous float64 array of ``shape`` (-1 matches any length);
    with ``finite``, NaN or inf is an error naming the first bad index."""
    if np.iscomplexobj(value):
        raise InvalidShapeError(f"{name}: expected real numbers, got complex values")
    try:
        a = np.ascontiguousarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError) as e:  # OverflowError: an int beyond float64
        raise InvalidShapeError(f"{name}: cannot be read as a float64 array ({e})") from None
    if a.ndim != len(shape) or any(want not in (-1, got) for want, got in zip(shape, a.shape)):
        want = "(" + ", ".join("N" if s == -1 else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        raise InvalidShapeError(f"{name}: expected shape {want}, got {a.shape}")
    if finite and not np.all(np.isfinite(a)):
        i = tuple(int(k) for k in np.argwhere(~np.isfinite(a))[0])
        raise NonFiniteInputError(f"{name}[{', '.join(map(str, i))}] is {a[i]}; expected a finite number")
    return a
