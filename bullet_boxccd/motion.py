"""Quadratic affine motions: M(t) = C0 + C1 t + C2 t^2, a 4x4 matrix per t.

``coeffs[k]`` is the (4, 4) coefficient of t^k. The bottom row of ``coeffs[0]``
is (0, 0, 0, 1) and those of ``coeffs[1]`` and ``coeffs[2]`` are zero, so M(t)
is affine for every t. The 3x3 part need not be a rotation: a quadratic that
passes through three rotations shears slightly between them, and the solver is
exact for the motion as given.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _core
from ._arrays import as_float_array

__all__ = ["QuadraticMotion", "rotation_matrix"]


def rotation_matrix(axis, angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` radians about ``axis`` (Rodrigues)."""
    k = as_float_array("axis", axis, (3,), finite=True)
    n = np.linalg.norm(k)
    if n == 0.0:
        return np.eye(3)
    k = k / n
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def _pose(rotation=None, translation=None) -> np.ndarray:
    T = np.eye(4)
    if rotation is not None:
        T[:3, :3] = as_float_array("rotation", rotation, (3, 3), finite=True)
    if translation is not None:
        T[:3, 3] = as_float_array("translation", translation, (3,), finite=True)
    return T


@dataclass(frozen=True, eq=False)
class QuadraticMotion:
    """A motion whose 4x4 matrix entries are quadratic in t.

    Parameters
    ----------
    coeffs : (3, 4, 4) float
        ``M(t) = coeffs[0] + coeffs[1] * t + coeffs[2] * t**2``.
    """

    coeffs: np.ndarray

    def __post_init__(self):
        c = np.array(as_float_array("coeffs", self.coeffs, (3, 4, 4)))
        object.__setattr__(self, "_data", _core.make_motion(c, "QuadraticMotion"))  # validated copy for the core
        c.setflags(write=False)
        object.__setattr__(self, "coeffs", c)

    def at(self, t: float) -> np.ndarray:
        """(4, 4) matrix M(t)."""
        c = self.coeffs
        return c[0] + t * (c[1] + t * c[2])

    # ----- constructors -----
    @classmethod
    def static(cls, pose=None) -> QuadraticMotion:
        """Constant pose ((4, 4) float; identity if omitted)."""
        c = np.zeros((3, 4, 4))
        c[0] = np.eye(4) if pose is None else as_float_array("pose", pose, (4, 4))
        return cls(c)

    @classmethod
    def ballistic(cls, position, velocity, acceleration=(0.0, 0.0, 0.0), rotation=None) -> QuadraticMotion:
        """Fixed orientation, translation ``p + v t + a t^2 / 2`` (each (3,) float)."""
        c = np.zeros((3, 4, 4))
        c[0] = _pose(rotation, position)
        c[1, :3, 3] = as_float_array("velocity", velocity, (3,), finite=True)
        c[2, :3, 3] = 0.5 * as_float_array("acceleration", acceleration, (3,), finite=True)
        return cls(c)

    @classmethod
    def through(cls, times, poses) -> QuadraticMotion:
        """The quadratic through three poses: ``M(times[i]) = poses[i]``.

        ``times`` (3,) distinct floats, ``poses`` (3, 4, 4) affine matrices.
        Sampling a rigid motion (for example a screw) at its start, middle and end
        gives the fit that the pybullet adapter uses.
        """
        t = as_float_array("times", times, (3,), finite=True)
        P = as_float_array("poses", poses, (3, 4, 4), finite=True)
        if len(set(t.tolist())) != 3:
            raise _core.InvalidInputError(f"times: expected three distinct times, got {t.tolist()}")
        V = np.vander(t, 3, increasing=True)  # rows (1, t, t^2)
        c = np.linalg.solve(V, P.reshape(3, 16)).reshape(3, 4, 4)
        c[0, 3] = (0.0, 0.0, 0.0, 1.0)
        c[1:, 3] = 0.0
        return cls(c)

    @classmethod
    def screw(cls, pose, velocity, angular_velocity, t_range=(0.0, 1.0)) -> QuadraticMotion:
        """Quadratic fit (through start, middle and end of ``t_range``) of the rigid motion
        that translates the pose's origin at ``velocity`` and spins it at constant
        ``angular_velocity`` (rad per unit t, world axes) about that moving origin."""
        P0 = as_float_array("pose", pose, (4, 4), finite=True)
        v = as_float_array("velocity", velocity, (3,), finite=True)
        w = as_float_array("angular_velocity", angular_velocity, (3,), finite=True)
        t0, t1 = float(t_range[0]), float(t_range[1])
        times = np.array([t0, 0.5 * (t0 + t1), t1])
        poses = []
        # Inputs near the top of the double range overflow here; the motion's own
        # check then names the result (a typed error), so numpy need not warn.
        with np.errstate(all="ignore"):
            for t in times:
                dt = t - t0
                poses.append(_pose(rotation_matrix(w, np.linalg.norm(w) * dt) @ P0[:3, :3], P0[:3, 3] + v * dt))
        return cls.through(times, poses)

    def transformed(self, T) -> QuadraticMotion:
        """The motion seen after the fixed affine map ``T`` ((4, 4)): ``T @ M(t)``."""
        T = as_float_array("T", T, (4, 4))
        return QuadraticMotion(np.einsum("ij,kjl->kil", T, self.coeffs))

    def reparametrized(self, scale: float, offset: float) -> QuadraticMotion:
        """``M'(u) = M(scale * u + offset)``: the same path on a new time variable."""
        c0, c1, c2 = self.coeffs
        return QuadraticMotion(
            np.stack([c0 + offset * c1 + offset**2 * c2, scale * (c1 + 2 * offset * c2), scale**2 * c2])
        )

    def __repr__(self) -> str:
        return f"QuadraticMotion(coeffs={self.coeffs.tolist()})"


def quat_to_matrix(q) -> np.ndarray:
    """(..., 3, 3) rotation matrices of (..., 4) quaternions (x, y, z, w), pybullet's order."""
    q = np.asarray(q, dtype=float)
    q = q * np.sqrt(2.0 / np.einsum("...i,...i->...", q, q))[..., None]  # scaled: the products below carry the 2
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - (y * y + z * z)
    R[..., 0, 1] = x * y - z * w
    R[..., 0, 2] = x * z + y * w
    R[..., 1, 0] = x * y + z * w
    R[..., 1, 1] = 1 - (x * x + z * z)
    R[..., 1, 2] = y * z - x * w
    R[..., 2, 0] = x * z - y * w
    R[..., 2, 1] = y * z + x * w
    R[..., 2, 2] = 1 - (x * x + y * y)
    return R
