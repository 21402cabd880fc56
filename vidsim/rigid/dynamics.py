"""Newton-Euler free flight with quaternions and its variational equations (seed eq. 1-2).

State ``q = [X (3), Q (4), V (3), w (3)]`` (13,): centre-of-mass position X (m) and velocity V
(m/s) in the world frame (the calibration's; the camera frame when its R = I, t = 0, as in the seed
and in the rigid footage's calibration: x right, y down, z forward), the
orientation quaternion ``Q = (w, x, y, z)`` mapping body to world, and the angular velocity ``w``
in *body* axes (rad/s). The ODE (seed eq. 1) is::

    X' = V,   Q' = 1/2 Q * (0, w),   V' = g(tilt, roll),   w' = I^-1 (I w x w)

Parameters ``p`` (14,) = ``[X0 (3), d (3), V0 (3), W0 (3), tilt, roll]``: initial position,
a rotation vector ``d`` (rad, body axes) applied to a base orientation ``Q0 = Qb * exp(d)``, initial
velocity, initial angular velocity ``W0`` in *world* axes (rad/s) and the two gravity angles (rad)
with ``g = |g| (-sin roll, cos roll cos tilt, cos roll sin tilt)`` (tilt = roll = 0: gravity along
world +y, image down when the world frame is the camera's).

The sensitivities ``S = dq/dp`` (13, 14) obey ``S' = (dF/dq) S + dF/dp`` (variational equations),
integrated together with the state by the same fixed-step RK4, so they are the exact derivatives of
the discrete trajectory up to round-off. Everything runs in numba (``cache=True``, serial).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from vidsim.rigid.body import RigidBodyError

N_STATE = 13
N_PARAM = 14
G_EARTH = 9.81

PARAM_NAMES = ("x", "y", "z", "rx", "ry", "rz", "vx", "vy", "vz", "wx", "wy", "wz", "tilt", "roll")

T0_TOL = 1e-9
"""Seconds an output time may lie before ``t0`` (round-off in frame times); such a time gets the
initial state. :func:`vidsim.rigid.fit.fit_throw` uses the same bound for the guess's ``t0``."""


# ----------------------------------------------------------------------------- quaternions
@njit(cache=True)
def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of (4,) quaternions (w, x, y, z)."""
    out = np.empty(4)
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2]
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1]
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]
    return out


@njit(cache=True)
def quat_to_rot(q: np.ndarray) -> np.ndarray:
    """(3, 3) rotation matrix (body -> world) of a quaternion (normalised first)."""
    n = np.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    w, x, y, z = q[0] / n, q[1] / n, q[2] / n, q[3] / n
    R = np.empty((3, 3))
    R[0, 0] = 1 - 2 * (y * y + z * z)
    R[0, 1] = 2 * (x * y - w * z)
    R[0, 2] = 2 * (x * z + w * y)
    R[1, 0] = 2 * (x * y + w * z)
    R[1, 1] = 1 - 2 * (x * x + z * z)
    R[1, 2] = 2 * (y * z - w * x)
    R[2, 0] = 2 * (x * z - w * y)
    R[2, 1] = 2 * (y * z + w * x)
    R[2, 2] = 1 - 2 * (x * x + y * y)
    return R


@njit(cache=True)
def quat_exp(d: np.ndarray) -> np.ndarray:
    """Unit quaternion of a rotation vector ``d`` (3,), radians."""
    th = np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
    out = np.empty(4)
    out[0] = np.cos(0.5 * th)
    s = 0.5 - th * th / 48.0 if th < 1e-6 else np.sin(0.5 * th) / th
    out[1] = s * d[0]
    out[2] = s * d[1]
    out[3] = s * d[2]
    return out


@njit(cache=True)
def quat_exp_jac(d: np.ndarray) -> np.ndarray:
    """(4, 3) derivative of :func:`quat_exp` with respect to ``d``."""
    th = np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
    J = np.zeros((4, 3))
    if th < 1e-6:
        for i in range(3):
            J[0, i] = -0.25 * d[i]
            J[1 + i, i] = 0.5
        return J
    s = np.sin(0.5 * th) / th
    ds = (0.5 * np.cos(0.5 * th) * th - np.sin(0.5 * th)) / (th * th)
    for i in range(3):
        J[0, i] = -0.5 * np.sin(0.5 * th) * d[i] / th
        for j in range(3):
            J[1 + i, j] = ds * d[i] * d[j] / th
        J[1 + i, i] += s
    return J


def rot_to_quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), w >= 0, of a (3, 3) rotation matrix."""
    R = np.asarray(R, float)
    tr = np.trace(R)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = np.array([0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s])
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + R[i, i] - R[j, j] - R[k, k])
        q = np.empty(4)
        q[0] = (R[k, j] - R[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (R[j, i] + R[i, j]) / s
        q[1 + k] = (R[k, i] + R[i, k]) / s
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def rotvec_to_rot(d: np.ndarray) -> np.ndarray:
    """(3, 3) rotation matrix of a rotation vector (radians)."""
    return quat_to_rot(quat_exp(np.asarray(d, float)))


def rot_to_rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,) radians of a rotation matrix (angle in [0, pi])."""
    q = rot_to_quat(R)
    n = np.linalg.norm(q[1:])
    if n < 1e-12:
        return np.zeros(3)
    return 2.0 * np.arctan2(n, q[0]) * q[1:] / n


def rotation_angle_deg(Ra: np.ndarray, Rb: np.ndarray) -> float:
    """Angle (degrees) of the rotation ``Ra^T Rb``."""
    c = (np.trace(np.asarray(Ra).T @ np.asarray(Rb)) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


# ----------------------------------------------------------------------------- gravity
def gravity_vector(tilt: float, roll: float, g: float = G_EARTH) -> np.ndarray:
    """Gravity (3,) m/s^2 in world axes (the camera's when the calibration has R = I) from the two
    angles (radians)."""
    return g * np.array([-np.sin(roll), np.cos(roll) * np.cos(tilt), np.cos(roll) * np.sin(tilt)])


def gravity_angles(gvec: np.ndarray) -> tuple[float, float]:
    """Inverse of :func:`gravity_vector`: (tilt, roll) radians of a gravity direction."""
    u = np.asarray(gvec, float) / np.linalg.norm(gvec)
    roll = float(np.arcsin(np.clip(-u[0], -1, 1)))
    tilt = float(np.arctan2(u[2], u[1]))
    return tilt, roll


def gravity_jacobian(tilt: float, roll: float, g: float = G_EARTH) -> np.ndarray:
    """(3, 2) derivative of :func:`gravity_vector` with respect to (tilt, roll)."""
    return g * np.array([
        [0.0, -np.cos(roll)],
        [-np.cos(roll) * np.sin(tilt), -np.sin(roll) * np.cos(tilt)],
        [np.cos(roll) * np.cos(tilt), -np.sin(roll) * np.sin(tilt)],
    ])


# ----------------------------------------------------------------------------- initial state
@njit(cache=True)
def _lmat(q: np.ndarray) -> np.ndarray:
    """(4, 4) matrix with ``q * p = L(q) p``."""
    return np.array([[q[0], -q[1], -q[2], -q[3]],
                     [q[1], q[0], -q[3], q[2]],
                     [q[2], q[3], q[0], -q[1]],
                     [q[3], -q[2], q[1], q[0]]])


@njit(cache=True)
def _initial_state(p: np.ndarray, qb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    q0 = np.zeros(13)
    S0 = np.zeros((13, 14))
    e = quat_exp(p[3:6])
    Q = quat_mul(qb, e)
    dQ = _lmat(qb) @ quat_exp_jac(p[3:6])  # (4, 3)
    # body angular velocity w = R(Q)^T W (rotate by the conjugate)
    W = p[9:12]
    qw = Q[0]
    u = Q[1:4]
    uxW = np.cross(u, W)
    uW = u[0] * W[0] + u[1] * W[1] + u[2] * W[2]
    uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2]
    wb = W - 2 * qw * uxW + 2 * (u * uW - W * uu)
    # d wb / d Q (3, 4) for the formula above
    dwb = np.zeros((3, 4))
    dwb[:, 0] = -2 * uxW
    skW = np.array([[0.0, -W[2], W[1]], [W[2], 0.0, -W[0]], [-W[1], W[0], 0.0]])
    dU = 2 * qw * skW + 2 * (uW * np.eye(3) + np.outer(u, W) - 2 * np.outer(W, u))
    dwb[:, 1:4] = dU
    Rt = quat_to_rot(Q).T
    q0[0:3] = p[0:3]
    q0[3:7] = Q
    q0[7:10] = p[6:9]
    q0[10:13] = wb
    for i in range(3):
        S0[i, i] = 1.0
        S0[7 + i, 6 + i] = 1.0
    S0[3:7, 3:6] = dQ
    S0[10:13, 3:6] = dwb @ dQ
    S0[10:13, 9:12] = Rt
    return q0, S0


def initial_state(p: np.ndarray, q_base: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Initial state and its sensitivity.

    Args:
        p: (14,) parameters (see module docstring).
        q_base: (4,) base orientation quaternion.

    Returns:
        q0 (13,) and S0 = dq0/dp (13, 14).
    """
    p = _check_params(p)
    qb = np.asarray(q_base, float)
    if qb.shape != (4,) or not np.all(np.isfinite(qb)):
        raise RigidBodyError(f"q_base must be a finite (4,) quaternion, got {qb!r}")
    return _initial_state(p, qb / np.linalg.norm(qb))


# ----------------------------------------------------------------------------- ODE
@njit(cache=True)
def _rhs(q: np.ndarray, S: np.ndarray, g: np.ndarray, dg: np.ndarray, I: np.ndarray, Iinv: np.ndarray,
         sens: bool) -> tuple[np.ndarray, np.ndarray]:
    dq = np.zeros(13)
    Q = q[3:7]
    w = q[10:13]
    dq[0:3] = q[7:10]
    wq = np.array([0.0, w[0], w[1], w[2]])
    dq[3:7] = 0.5 * quat_mul(Q, wq)
    dq[7:10] = g
    Iw = I @ w
    dq[10:13] = Iinv @ np.cross(Iw, w)
    if not sens:
        return dq, S
    J = np.zeros((13, 13))
    for i in range(3):
        J[i, 7 + i] = 1.0
    # d(1/2 Q*(0,w))/dQ = 1/2 R(0,w)
    J[3, 3], J[3, 4], J[3, 5], J[3, 6] = 0.0, -w[0], -w[1], -w[2]
    J[4, 3], J[4, 4], J[4, 5], J[4, 6] = w[0], 0.0, w[2], -w[1]
    J[5, 3], J[5, 4], J[5, 5], J[5, 6] = w[1], -w[2], 0.0, w[0]
    J[6, 3], J[6, 4], J[6, 5], J[6, 6] = w[2], w[1], -w[0], 0.0
    L = _lmat(Q)
    for r in range(4):
        for c in range(4):
            J[3 + r, 3 + c] *= 0.5
        for c in range(3):
            J[3 + r, 10 + c] = 0.5 * L[r, 1 + c]
    skIw = np.array([[0.0, -Iw[2], Iw[1]], [Iw[2], 0.0, -Iw[0]], [-Iw[1], Iw[0], 0.0]])
    skw = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    J[10:13, 10:13] = Iinv @ (skIw - skw @ I)
    dS = J @ S
    dS[7:10, 12:14] += dg
    return dq, dS


MAX_TURN_PER_STEP = 0.3
"""Largest rotation (rad) of one RK4 step: an interval's steps are shortened below ``hmax`` when
the spin would turn the body further per step. Without it a fixed 1/60 s step turned a T-object
spinning at 80 rad/s by 1.3 rad per step and its orientation was up to 21 degrees off after 1 s
(170 at 150 rad/s; found in review, 6 Dec 2026). With 0.3 rad the error against a 1e-4 s
integration is at most 0.13 degree at 80 rad/s and 0.37 at 150 rad/s over 1 s (four orientations;
0.5 rad left 4.2 degrees at 150), and bodies spinning slower than 0.3 / hmax (18 rad/s at 1/60 s,
36 at the gap model's 1/120 s; the synthetic throws' 4-10 rad/s stay under 11.2 over their flight)
integrate exactly as before."""


@njit(cache=True)
def rk4_steps(span: float, hmax: float, q: np.ndarray) -> int:
    """Number of equal RK4 steps over ``span`` seconds from state ``q``: none longer than ``hmax``
    nor turning the body by more than :data:`MAX_TURN_PER_STEP` at its current spin."""
    wn = np.sqrt(q[10] ** 2 + q[11] ** 2 + q[12] ** 2)
    h = hmax
    if wn * h > MAX_TURN_PER_STEP:
        h = MAX_TURN_PER_STEP / wn
    return int(np.ceil(span / h - 1e-9))


@njit(cache=True)
def _integrate(q0: np.ndarray, S0: np.ndarray, t0: float, times: np.ndarray, hmax: float,
               g: np.ndarray, dg: np.ndarray, I: np.ndarray, Iinv: np.ndarray, sens: bool,
               wmax: float) -> tuple[np.ndarray, np.ndarray, bool]:
    T = times.shape[0]
    states = np.zeros((T, 13))
    sout = np.zeros((T, 13, 14))
    q = q0.copy()
    S = S0.copy()
    t = t0
    ok = True
    for k in range(T):
        span = times[k] - t
        n = rk4_steps(span, hmax, q)
        if n > 0:
            h = span / n
            for _ in range(n):
                k1, s1 = _rhs(q, S, g, dg, I, Iinv, sens)
                k2, s2 = _rhs(q + 0.5 * h * k1, S + 0.5 * h * s1, g, dg, I, Iinv, sens)
                k3, s3 = _rhs(q + 0.5 * h * k2, S + 0.5 * h * s2, g, dg, I, Iinv, sens)
                k4, s4 = _rhs(q + h * k3, S + h * s3, g, dg, I, Iinv, sens)
                q = q + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
                if sens:
                    S = S + h / 6.0 * (s1 + 2 * s2 + 2 * s3 + s4)
            t = times[k]
        wn = np.sqrt(q[10] ** 2 + q[11] ** 2 + q[12] ** 2)
        if not (np.all(np.isfinite(q)) and wn < wmax):
            ok = False
            break
        states[k] = q
        sout[k] = S
    return states, sout, ok


@dataclass
class Trajectory:
    """Result of :func:`simulate`.

    Attributes:
        states: (T, 13) state at each requested time (quaternions as integrated, not renormalised).
        sens: (T, 13, 14) dq/dp at each time (zeros when sensitivities were not requested).
        ok: False when the integration diverged (non-finite state or spin above ``wmax``); the
            states after the failure are zeros and must not be used. Optimisers score it as bad.
    """

    states: np.ndarray
    sens: np.ndarray
    ok: bool


def _check_params(p: np.ndarray) -> np.ndarray:
    p = np.asarray(p, float)
    if p.shape != (N_PARAM,):
        raise RigidBodyError(f"parameters must have shape ({N_PARAM},) {PARAM_NAMES}, got {p.shape}")
    return p


def simulate(p: np.ndarray, q_base: np.ndarray, inertia: np.ndarray, times: np.ndarray, t0: float,
             hmax: float = 1.0 / 120.0, sensitivities: bool = True, g: float = G_EARTH,
             wmax: float = 500.0) -> Trajectory:
    """Integrate free flight (and optionally dq/dp) with fixed-step RK4.

    Each interval between consecutive output times is split into equal steps no longer than
    ``hmax`` (and short enough that no step turns the body by more than :data:`MAX_TURN_PER_STEP`),
    so irregular frame times are hit exactly.

    Args:
        p: (14,) parameters (module docstring).
        q_base: (4,) base orientation quaternion.
        inertia: (3, 3) inertia about the centre of mass in body axes, kg m^2.
        times: (T,) output times, seconds, finite, non-decreasing and >= ``t0`` (up to ``T0_TOL``).
        t0: time of the initial state, seconds (finite: a NaN one integrated nothing and
            returned the initial state at every time, flagged ok).
        hmax: largest RK4 step, seconds.
        sensitivities: integrate the variational equations too.
        g: gravity magnitude, m/s^2.
        wmax: spin (rad/s) above which the integration is declared diverged.

    Returns:
        :class:`Trajectory`.
    """
    p = _check_params(p)
    times = np.ascontiguousarray(times, dtype=float)
    if times.ndim != 1 or times.size == 0:
        raise RigidBodyError(f"times must be a non-empty 1-D array, got shape {times.shape}")
    try:
        t0 = float(t0)
    except (TypeError, ValueError):
        raise RigidBodyError(f"t0 must be a finite time (s), got {t0!r}") from None
    if not np.isfinite(t0):
        raise RigidBodyError(f"t0 must be a finite time (s), got {t0}")
    if not np.all(np.isfinite(times)):
        raise RigidBodyError(f"times must be finite, got {times[~np.isfinite(times)].tolist()} at index "
                             f"{np.flatnonzero(~np.isfinite(times)).tolist()}")
    if np.any(np.diff(times) < 0):
        raise RigidBodyError("times must be non-decreasing")
    if times[0] < t0 - T0_TOL:
        raise RigidBodyError(f"times must not be before t0 = {t0!r} (more than {T0_TOL:g} s), the first is {times[0]!r}")
    if not (hmax > 0 and np.isfinite(hmax)):
        raise RigidBodyError(f"hmax must be positive and finite, got {hmax}")
    I = np.ascontiguousarray(inertia, dtype=float)
    q0, S0 = initial_state(p, q_base)
    gv = gravity_vector(p[12], p[13], g)
    dg = gravity_jacobian(p[12], p[13], g)
    states, sens, ok = _integrate(q0, S0, float(t0), times, float(hmax), gv, dg, I, np.linalg.inv(I),
                                  bool(sensitivities), float(wmax))
    return Trajectory(states, sens, bool(ok))


def pose_tangent_jacobian(state: np.ndarray, sens: np.ndarray) -> np.ndarray:
    """(6, 14) derivative of the pose tangent [dX (world), dtheta (body axes)] with respect to p.

    ``dtheta = 2 vec(Q^-1 * dQ)`` is the small body-axis rotation that a change of ``p`` causes,
    the coordinates in which image-space derivatives are taken by finite differences.
    """
    Q = state[3:7] / np.linalg.norm(state[3:7])
    Qc = np.array([Q[0], -Q[1], -Q[2], -Q[3]])
    out = np.empty((6, N_PARAM))
    out[0:3] = sens[0:3]
    out[3:6] = 2.0 * (_lmat(Qc) @ sens[3:7])[1:4]
    return out
