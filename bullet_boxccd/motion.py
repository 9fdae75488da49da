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


# --------------------------------------------------------------------------
# Motion over one physics step, as Bullet integrates it (vectorised over boxes).
#
# Bullet moves a body's centre of mass linearly with the post-solve velocity v
# and turns it about the fixed world axis of the post-solve angular velocity w
# (an exponential map). Above pi/4 per step Bullet clamps the angle, but it
# scales the quaternion's vector part by |w| / (clamped |w|) before
# normalising, so the realised angle is 2 atan(|w| dt / (pi/4) * tan(pi/8))
# (btMultiBody::stepPositionsMultiDof and btTransformUtil::integrateTransform
# both do this; measured on pybullet 3.2.7 to 1e-15).
# tau in [0, 1] is the fraction of the step: tau = 1 is the pose after the step.

_ANGULAR_MOTION_THRESHOLD = 0.25 * np.pi
# Quadratic interpolation through tau = 0, 1/2, 1 of sin(phi tau) or
# 1 - cos(phi tau) errs by at most phi^3 / 6 * max |tau (tau - 1/2)(tau - 1)|
# = phi^3 sqrt(3) / 216 each; a rotation is I + sin K + (1 - cos) K^2 with
# |K| = |K^2| = 1, so the 3x3 part errs by at most twice that.
_FIT_ERROR_PER_CUBED_ANGLE = 2.0 * np.sqrt(3.0) / 216.0


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


def matrix_to_quat(R) -> np.ndarray:
    """(..., 4) unit quaternions (x, y, z, w) of (..., 3, 3) rotation matrices (Shepperd:
    each from the largest of w^2, x^2, y^2, z^2, so none divides by a small number)."""
    R = np.asarray(R, dtype=float)
    m = R.reshape(-1, 3, 3)
    tr = np.trace(m, axis1=1, axis2=2)
    cand = np.stack([tr, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1)
    k = np.argmax(cand, axis=1)
    q = np.empty((len(m), 4))
    for case in range(4):
        sel = k == case
        if not sel.any():
            continue
        a = m[sel]
        if case == 0:
            s = 2.0 * np.sqrt(1.0 + tr[sel])
            q[sel] = np.stack([(a[:, 2, 1] - a[:, 1, 2]) / s, (a[:, 0, 2] - a[:, 2, 0]) / s,
                               (a[:, 1, 0] - a[:, 0, 1]) / s, 0.25 * s], axis=1)
        else:
            i = case - 1
            j, n = (i + 1) % 3, (i + 2) % 3
            s = 2.0 * np.sqrt(1.0 + a[:, i, i] - a[:, j, j] - a[:, n, n])
            qi = np.empty((len(a), 4))
            qi[:, i] = 0.25 * s
            qi[:, j] = (a[:, j, i] + a[:, i, j]) / s
            qi[:, n] = (a[:, n, i] + a[:, i, n]) / s
            qi[:, 3] = (a[:, n, j] - a[:, j, n]) / s
            q[sel] = qi
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q.reshape(R.shape[:-2] + (4,))


def bullet_step_angle(angular_speed, dt: float) -> np.ndarray:
    """The angle Bullet turns a body in one step of ``dt`` at ``angular_speed`` (rad/s)."""
    a = np.asarray(angular_speed, dtype=float) * dt
    clamped = 2.0 * np.arctan(a / _ANGULAR_MOTION_THRESHOLD * np.tan(0.5 * _ANGULAR_MOTION_THRESHOLD))
    return np.where(a > _ANGULAR_MOTION_THRESHOLD, clamped, a)


def _rodrigues(axis, angle) -> np.ndarray:
    """(..., 3, 3) rotations by ``angle`` (...) about unit ``axis`` (..., 3)."""
    k = np.asarray(axis, dtype=float)
    K = np.zeros(k.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
    K = K - np.swapaxes(K, -1, -2)
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


class StepPath:
    """The exact path of N rigid frames over one Bullet step, rebuilt from the
    pose after the step and the post-solve velocities.

    Parameters
    ----------
    X_W1 : (N, 4, 4) float
        Poses after the step (the centre-of-mass frame).
    v, w : (N, 3) float
        Post-solve linear and angular velocities (world).
    dt : float
        The step.
    """

    def __init__(self, X_W1, v, w, dt: float):
        self.X_W1 = np.asarray(X_W1, dtype=float)
        self.v = np.asarray(v, dtype=float)
        self.w = np.asarray(w, dtype=float)
        self.dv = self.v * dt  # displacement over the step
        speed = np.linalg.norm(self.w, axis=-1)
        self.angle = bullet_step_angle(speed, dt)  # turned over the step, about self.axis
        self.axis = np.where(speed[:, None] > 0, self.w / np.where(speed > 0, speed, 1.0)[:, None], 0.0)
        self.dt = dt

    def take(self, index) -> StepPath:
        """The paths of a subset of the frames."""
        return StepPath(self.X_W1[index], self.v[index], self.w[index], self.dt)

    def at(self, tau) -> np.ndarray:
        """(N, 4, 4) poses at step fraction ``tau`` (a scalar, or (N,): one per frame)."""
        return self._at(np.broadcast_to(np.asarray(tau, dtype=float), self.angle.shape))

    def at_times(self, taus, frames=None) -> np.ndarray:
        """(K, n, 4, 4) poses at each of the step fractions ``taus`` (K,), of every frame or
        of the ``frames`` given (n indices)."""
        idx = slice(None) if frames is None else np.asarray(frames)
        angle = self.angle[idx]
        return self._at(np.asarray(taus, dtype=float)[:, None] + np.zeros_like(angle), idx)

    def _at(self, tau, idx=slice(None)) -> np.ndarray:
        back = tau - 1.0  # (..., n)
        X1 = self.X_W1[idx]
        X = np.broadcast_to(X1, back.shape + (4, 4)).copy()
        X[..., :3, :3] = _rodrigues(self.axis[idx], back * self.angle[idx]) @ X1[:, :3, :3]
        X[..., :3, 3] = X1[:, :3, 3] + back[..., None] * self.dv[idx]
        return X

    def fit(self, X_CS, pieces: int = 1, window=(0.0, 1.0)):
        """Quadratic motions of frames rigidly attached at ``X_CS`` ((N, 4, 4), in the
        moving frame) over ``window`` (step fractions), one per piece of it.

        Returns ``coeffs`` (pieces, N, 3, 4, 4), each piece on its own t in [0, 1]
        (piece k covers tau in lo + (hi - lo) [k, k + 1] / pieces), and ``error`` (N,):
        a bound on the 3x3 part's deviation from the true rotation (spectral norm);
        a point at distance r from the centre of mass is off by at most error * r.
        The position is linear, so it is fitted exactly.
        """
        lo, hi = window
        X_CS = np.asarray(X_CS, dtype=float)
        taus = lo + (hi - lo) * (np.arange(pieces)[:, None] + np.array([0.0, 0.5, 1.0])) / pieces
        P = (self.at_times(taus.ravel()) @ X_CS).reshape(pieces, 3, len(X_CS), 4, 4)
        c0, c1, c2 = P[:, 0], -3 * P[:, 0] + 4 * P[:, 1] - P[:, 2], 2 * P[:, 0] - 4 * P[:, 1] + 2 * P[:, 2]
        c1[..., 3, :] = 0.0
        c2[..., 3, :] = 0.0
        error = _FIT_ERROR_PER_CUBED_ANGLE * (self.angle * (hi - lo) / pieces) ** 3
        return np.stack([c0, c1, c2], axis=2), error
