"""Quadratic affine motions: M(t) = C0 + C1 t + C2 t^2, a 4x4 matrix per t.

``coeffs[k]`` is the (4, 4) coefficient of t^k. The bottom row of ``coeffs[0]``
is (0, 0, 0, 1) and those of ``coeffs[1]`` and ``coeffs[2]`` are zero, so M(t)
is affine for every t. The 3x3 part need not be a rotation: a quadratic that
passes through three rotations shears slightly between them, and the solver is
exact for the motion as given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import _core
from ._arrays import as_float_array

__all__ = ["QuadraticMotion", "rotation_matrix", "rotations", "screw_coeffs", "through_coeffs"]


def axis_angle_matrix(axis, angle) -> np.ndarray:
    """(..., 3, 3) rotations by ``angle`` (...) about the unit ``axis`` (..., 3) (Rodrigues:
    the one copy in the package; ``rotations`` and ``rotation_matrix`` go through it)."""
    k = np.asarray(axis, dtype=float)
    K = np.zeros(k.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
    K = K - np.swapaxes(K, -1, -2)
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


def rotations(rotvec) -> np.ndarray:
    """(..., 3, 3) rotations by the rotation vectors ``rotvec`` (..., 3): about
    ``rotvec / |rotvec|`` by ``|rotvec|`` radians (the identity for a zero vector)."""
    rotvec = np.asarray(rotvec, dtype=float)
    theta = np.linalg.norm(rotvec, axis=-1)
    return axis_angle_matrix(rotvec / np.where(theta > 0, theta, 1.0)[..., None], theta)


def rotation_matrix(axis, angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` radians about ``axis`` (Rodrigues)."""
    k = as_float_array("axis", axis, (3,), finite=True)
    n = np.linalg.norm(k)
    if n == 0.0:
        return np.eye(3)
    return rotations(k / n * angle)


def through_coeffs(times, poses) -> np.ndarray:
    """(..., 3, 4, 4) coefficients of the quadratics through three poses:
    ``M(times[i]) = poses[..., i, :, :]``, with ``times`` (3,) distinct and
    ``poses`` (..., 3, 4, 4) affine. The bottom rows are set exactly."""
    t = np.asarray(times, dtype=float)
    P = np.asarray(poses, dtype=float)
    # Lagrange: the basis polynomial of pose i is (t - t_j)(t - t_k) / D_i.
    c = np.zeros(P.shape)
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        Pi = P[..., i, :, :] / ((t[i] - t[j]) * (t[i] - t[k]))
        c[..., 0, :, :] += t[j] * t[k] * Pi
        c[..., 1, :, :] -= (t[j] + t[k]) * Pi
        c[..., 2, :, :] += Pi
    c[..., 0, 3, :] = (0.0, 0.0, 0.0, 1.0)
    c[..., 1:, 3, :] = 0.0
    return c


def screw_coeffs(rotation, position, velocity, angular_velocity, t_range=(0.0, 1.0)) -> np.ndarray:
    """(..., 3, 4, 4) coefficients of the quadratic motion that translates the
    origin from ``position`` at ``velocity`` and spins the frame at constant
    ``angular_velocity`` (rad per unit t, world axes) about that moving origin,
    starting from ``rotation`` at ``t_range[0]``: all (..., 3) except
    ``rotation`` (..., 3, 3). The translation is linear, so it is exact; the 3x3
    part is the quadratic through the rotations at the start, middle and end of
    ``t_range`` (exactly constant when the spin is zero)."""
    R0 = np.asarray(rotation, dtype=float)
    p0, v, w = (np.asarray(x, dtype=float) for x in (position, velocity, angular_velocity))
    t0, t1 = float(t_range[0]), float(t_range[1])
    times = np.array([t0, 0.5 * (t0 + t1), t1])
    poses = np.zeros(np.broadcast_shapes(R0.shape[:-2], p0.shape[:-1], v.shape[:-1], w.shape[:-1]) + (3, 4, 4))
    for i, t in enumerate(times):
        poses[..., i, :3, :3] = rotations(w * (t - t0)) @ R0
    c = through_coeffs(times, poses)
    still = ~np.any(w != 0.0, axis=-1)
    c[still, 0, :3, :3] = np.broadcast_to(R0, poses.shape[:-3] + (3, 3))[still]
    c[still, 1:, :3, :3] = 0.0
    c[..., 0, :3, 3] = p0 - v * t0
    c[..., 1, :3, 3] = v
    c[..., 2, :3, 3] = 0.0
    return c


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
    __slots__ = ("_data", "__dict__")  # the validated copy for the core: see Box

    def __post_init__(self):
        c = np.array(as_float_array("coeffs", self.coeffs, (3, 4, 4)))
        object.__setattr__(self, "_data", _core.make_motion(c, "QuadraticMotion"))
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
        return cls(through_coeffs(t, P))

    @classmethod
    def screw(cls, pose, velocity, angular_velocity, t_range=(0.0, 1.0)) -> QuadraticMotion:
        """The motion that translates the pose's origin at ``velocity`` (exactly: it is
        linear) and spins it at constant ``angular_velocity`` (rad per unit t, world
        axes) about that moving origin, its rotation fitted by the quadratic through
        the start, middle and end of ``t_range`` (``screw_coeffs``)."""
        P0 = as_float_array("pose", pose, (4, 4), finite=True)
        v = as_float_array("velocity", velocity, (3,), finite=True)
        w = as_float_array("angular_velocity", angular_velocity, (3,), finite=True)
        t0, t1 = float(t_range[0]), float(t_range[1])
        if not t0 != t1:
            raise _core.InvalidInputError(f"t_range: expected two distinct times, got {(t0, t1)}")
        # Inputs near the top of the double range overflow here; the motion's own
        # check then names the result (a typed error), so numpy need not warn.
        with np.errstate(all="ignore"):
            return cls(screw_coeffs(P0[:3, :3], P0[:3, 3], v, w, (t0, t1)))

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

    def __reduce__(self):
        return type(self), (self.coeffs,)

    def __repr__(self) -> str:
        return f"QuadraticMotion(coeffs={self.coeffs.tolist()})"


def quat_to_matrix(q) -> np.ndarray:
    """(..., 3, 3) rotation matrices of (..., 4) quaternions (x, y, z, w), pybullet's order."""
    q = np.asarray(q, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    scale = np.sqrt(2.0 / ((x * x + z * z) + (y * y + w * w)))  # the products below carry the 2
    x, y, z, w = x * scale, y * scale, z * scale, w * scale
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


def matrix_to_quat(R) -> np.ndarray:
    """(4,) unit quaternion (x, y, z, w) of a (3, 3) rotation matrix."""
    R = np.asarray(R, dtype=float)
    t = np.trace(R)
    if t > 0:
        s = 2.0 * np.sqrt(t + 1.0)
        q = [(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, 0.25 * s]
    else:  # the largest diagonal term gives the best-conditioned component
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + R[i, i] - R[j, j] - R[k, k])
        q = [0.0] * 4
        q[i], q[j], q[k], q[3] = 0.25 * s, (R[j, i] + R[i, j]) / s, (R[k, i] + R[i, k]) / s, (R[k, j] - R[j, k]) / s
    q = np.array(q)
    return q / np.linalg.norm(q)


def pose_matrix(position, quaternion) -> np.ndarray:
    """(4, 4) rigid pose of a position and a quaternion (x, y, z, w): ``quat_to_matrix``'s
    arithmetic on Python floats (numpy's per-call cost dominates one pose)."""
    x, y, z, w = (float(c) for c in quaternion)
    scale = math.sqrt(2.0 / ((x * x + z * z) + (y * y + w * w)))
    x, y, z, w = x * scale, y * scale, z * scale, w * scale
    a, b, c = (float(c) for c in position)
    return np.array([[1 - (y * y + z * z), x * y - z * w, x * z + y * w, a],
                     [x * y + z * w, 1 - (x * x + z * z), y * z - x * w, b],
                     [x * z - y * w, y * z + x * w, 1 - (x * x + y * y), c],
                     [0.0, 0.0, 0.0, 1.0]])


def pose7(X) -> np.ndarray:
    """(7,) position and quaternion (x, y, z, w) of a (4, 4) rigid pose."""
    X = np.asarray(X)
    return np.concatenate([X[:3, 3], matrix_to_quat(X[:3, :3])])
