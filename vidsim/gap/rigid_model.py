"""Candidate effects for a rigid free-flight fit, as additive parameters with 0 = off.

The base model is :mod:`vidsim.rigid.dynamics` (torque-free Newton-Euler, gravity direction
fitted) rendered by :mod:`vidsim.rigid.silhouette`. Each candidate of :data:`RIGID_EFFECTS` adds a
small block of parameters; with all blocks at zero the extended model reproduces the base model.

Dynamics (centre-of-mass accelerations added to ``g``; the rotation is torque free unless an
effect below applies a torque: quadratic_drag, angular_drag, drag_torque)::

    linear_drag     c1  (1/s)      a += -c1 V
    quadratic_drag  c2  (kg/m^3)   air pressure on the faces of each box of the known shape at the
                                   box's own velocity u_b = R^T V + w x r_b (body axes):
                                   F_b = -c2 sum_i A_bi |u_bi| u_bi e_i (A_bi: face area normal to
                                   body axis i), force sum_b F_b / m and torque sum_b r_b x F_b
                                   together (c2 = rho C / 2; drag and the lift of oblique faces)
    wind            a_w (3, m/s^2) a += a_w         (steady uniform push, camera axes)
    magnus          s   (-)        a += s (W x V)   (W: spin in world axes, rad/s; s >= 0: the lift
                                   of a spinning body is toward W x V)
    angular_drag    k   (1/s)      w' += -k w       (spin decays)
    drag_torque     u   (3, -)     torque of a quadratic drag force m c |V| V (c in 1/m: drag per
                                   unit mass, not the kg/m^3 c2 above) acting at a centre of
                                   pressure r_p (body axes) off the centre of mass: u = c r_p
                                   (dimensionless), tau = -m |V| (u x V_body)
    com_offset      d   (3, m)     the true centre of mass sits at body-frame ``d``
    gravity_scale   e   (-)        |g| -> 9.81 (1 + e)

Imaging and timing (the camera, not the motion)::

    lens_k1         k1  (-)        radial distortion the calibration missed
    motion_blur     b   (s^2)      exposure^2: an exposure sqrt(b) centred on the frame time,
                                   segmented (foreground where the coverage over the exposure
                                   exceeds ``blur_threshold``, :func:`segmented_blur`)
    rolling_shutter rs  (s)        image row v is captured rs * v / H after row 0
    time_offset     dt  (s)        every frame time is late by dt
    time_rate       r   (-)        frame clock runs fast: t -> t0 + (t - t0)(1 + r)
    time_jitter     dk  (T, s)     one time error per frame

Known aliases in a single free flight (stated, not hidden): ``time_offset`` is absorbed by the
initial state, and ``time_rate`` is equivalent to ``gravity_scale`` (time scaled by 1 + r is
gravity scaled by (1 + r)^2 with the initial velocity and spin rescaled); gravity *direction* is a
fitted parameter of the base model, so the horizontal part of ``wind`` trades against it and
only its component along gravity is new. Blur enters at second order in the exposure, so its
parameter is the exposure squared (a first-order signature exists at zero).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from vidsim.rigid.body import BoxBody
from vidsim.rigid.dynamics import G_EARTH, gravity_vector, initial_state, quat_to_rot, rk4_steps
from vidsim.rigid.silhouette import render_coverage
from vidsim.video.camera import PinholeCamera

#: renders of a blurred frame spread evenly over sqrt(b), both ends included (time variance b/8)
BLUR_SAMPLES = 5


class GapError(ValueError):
    """Bad input to the gap diagnosis (unknown effect, wrong shape); the message names it."""


@dataclass(frozen=True)
class EffectSpec:
    """One candidate effect.

    Attributes:
        name: library name; size: number of parameters (-1: one per frame).
        kind: "dynamics", "imaging" or "timing".
        scale: typical magnitude of a parameter (the variable scaling and the finite-difference
            step is 0.25 of it), in the effect's units.
        units: units of the parameters; lower: lower bound (None: unbounded).
        alias: effects this one cannot be told apart from in a single free flight.
        disp_power: the image displacement grows as parameter^disp_power near zero (1: linear;
            blur's extent grows as the square root of its parameter, the exposure squared, and
            keeps its probe step in :meth:`RigidGapModel.fd_steps`).
    """

    name: str
    size: int
    kind: str
    scale: float
    units: str
    lower: float | None = None
    alias: tuple[str, ...] = ()
    disp_power: float = 1.0


#: softness of the segmentation threshold in :func:`segmented_blur` (coverage units)
BLUR_STEP = 0.2

#: Slabs of the rolling shutter's read-out in the model's render (each slab at its middle row's
#: time). Measured on the suite's rolling-shutter case with the base at the truth (docs/gap.md,
#: session 18): the training cost at the true read-out is 348 / 185 / 136 / 127 with 6 / 12 / 24 /
#: 48 slabs against footage rendered with 48 (6 were used until then).
RS_SLABS = 24


def segmented_blur(c0: np.ndarray, mean: np.ndarray, threshold: float) -> np.ndarray:
    """What a segmentation makes of a blurred frame: pixels whose coverage over the exposure
    (``mean``) exceeds the segmentation's threshold (a fraction of the exposure, set by its
    intensity threshold against the object's contrast) are foreground.

    Returned as a change of the unblurred soft silhouette ``c0``:
    ``clip(c0 + step(mean) - step(c0), 0, 1)`` with ``step(x) = clip((x - threshold) / BLUR_STEP
    + 1/2, 0, 1)``, so a zero exposure (``mean == c0``) gives ``c0`` exactly. The plain mean (the
    first version) leaves a fractional band where the footage's mask is binary, which costs in
    every residual pixel: on the rigid blur case even the right exposure then widened the
    held-out gap (docs/gap.md).
    """
    def step(x: np.ndarray) -> np.ndarray:
        return np.clip((x - threshold) / BLUR_STEP + 0.5, 0.0, 1.0)

    return np.clip(c0 + step(mean) - step(c0), 0.0, 1.0)


RIGID_EFFECTS: dict[str, EffectSpec] = {e.name: e for e in (
    EffectSpec("linear_drag", 1, "dynamics", 0.05, "1/s", 0.0),
    EffectSpec("quadratic_drag", 1, "dynamics", 0.2, "kg/m^3", 0.0),
    EffectSpec("wind", 3, "dynamics", 0.05, "m/s^2"),
    EffectSpec("magnus", 1, "dynamics", 0.002, "-", 0.0),
    EffectSpec("angular_drag", 1, "dynamics", 0.05, "1/s", 0.0),
    EffectSpec("drag_torque", 3, "dynamics", 2e-4, "-"),
    EffectSpec("com_offset", 3, "dynamics", 0.004, "m"),
    EffectSpec("gravity_scale", 1, "dynamics", 0.01, "-", alias=("time_rate",)),
    EffectSpec("lens_k1", 1, "imaging", 0.01, "-"),
    EffectSpec("motion_blur", 1, "imaging", 1e-4, "s^2", 0.0, disp_power=0.5),
    EffectSpec("rolling_shutter", 1, "timing", 0.004, "s"),
    EffectSpec("time_offset", 1, "timing", 0.002, "s"),
    EffectSpec("time_rate", 1, "timing", 0.005, "-", alias=("gravity_scale",)),
    EffectSpec("time_jitter", -1, "timing", 0.002, "s"),
)}


def effect_size(name: str, n_frames: int) -> int:
    """Number of parameters of effect ``name`` for a clip of ``n_frames`` frames."""
    if name not in RIGID_EFFECTS:
        raise GapError(f"unknown effect {name!r}; the library has {sorted(RIGID_EFFECTS)}")
    s = RIGID_EFFECTS[name].size
    return n_frames if s < 0 else s


@njit(cache=True)
def _rhs_ext(q: np.ndarray, g: np.ndarray, I: np.ndarray, Iinv: np.ndarray, c1: float, c2: float,
             aw: np.ndarray, sm: float, kw: float,
             u: np.ndarray, mass: float, boxc: np.ndarray, boxa: np.ndarray) -> np.ndarray:
    dq = np.zeros(13)
    Q = q[3:7]
    w = q[10:13]
    V = q[7:10]
    dq[0:3] = V
    # dQ = 1/2 Q * (0, w)
    dq[3] = 0.5 * (-Q[1] * w[0] - Q[2] * w[1] - Q[3] * w[2])
    dq[4] = 0.5 * (Q[0] * w[0] + Q[2] * w[2] - Q[3] * w[1])
    dq[5] = 0.5 * (Q[0] * w[1] - Q[1] * w[2] + Q[3] * w[0])
    dq[6] = 0.5 * (Q[0] * w[2] + Q[1] * w[1] - Q[2] * w[0])
    sp = np.sqrt(V[0] ** 2 + V[1] ** 2 + V[2] ** 2)
    a = g + aw - c1 * V
    Iw = I @ w
    tau = np.cross(Iw, w)
    if sm != 0.0 or c2 != 0.0:
        R = quat_to_rot(Q)
        if sm != 0.0:
            a = a + sm * np.cross(R @ w, V)
        if c2 != 0.0:
            # face pressure on each box at its own velocity: body-axes velocity of box b's centre
            # u = R^T V + w x r_b; the faces facing the flow along axis i push back with
            # c2 A_bi |u_i| u_i (A_bi: the box's face area normal to i); force and torque together
            Vb = R.T @ V
            Fb = np.zeros(3)
            for b in range(boxc.shape[0]):
                ub = Vb + np.cross(w, boxc[b])
                fb = -c2 * boxa[b] * np.abs(ub) * ub
                Fb += fb
                tau = tau + np.cross(boxc[b], fb)
            a = a + (R @ Fb) / mass
    dq[7:10] = a
    if u[0] != 0.0 or u[1] != 0.0 or u[2] != 0.0:
        # V in body axes: R^T V
        n = np.sqrt(Q[0] ** 2 + Q[1] ** 2 + Q[2] ** 2 + Q[3] ** 2)
        qw, qx, qy, qz = Q[0] / n, Q[1] / n, Q[2] / n, Q[3] / n
        Vb = np.empty(3)
        Vb[0] = (1 - 2 * (qy * qy + qz * qz)) * V[0] + 2 * (qx * qy + qw * qz) * V[1] + 2 * (qx * qz - qw * qy) * V[2]
        Vb[1] = 2 * (qx * qy - qw * qz) * V[0] + (1 - 2 * (qx * qx + qz * qz)) * V[1] + 2 * (qy * qz + qw * qx) * V[2]
        Vb[2] = 2 * (qx * qz + qw * qy) * V[0] + 2 * (qy * qz - qw * qx) * V[1] + (1 - 2 * (qx * qx + qy * qy)) * V[2]
        tau = tau - mass * sp * np.cross(u, Vb)
    dq[10:13] = Iinv @ tau - kw * w
    return dq


@njit(cache=True)
def _integrate_ext(q0: np.ndarray, t0: float, times: np.ndarray, hmax: float, g: np.ndarray, I: np.ndarray,
                   Iinv: np.ndarray, c1: float, c2: float, aw: np.ndarray, sm: float, kw: float,
                   u: np.ndarray, mass: float, boxc: np.ndarray, boxa: np.ndarray) -> tuple[np.ndarray, bool]:
    T = times.shape[0]
    order = np.argsort(times)
    states = np.zeros((T, 13))
    q = q0.copy()
    t = t0
    for idx in order:
        span = times[idx] - t
        n = rk4_steps(span, hmax, q)
        if n > 0:
            h = span / n
            for _ in range(n):
                k1 = _rhs_ext(q, g, I, Iinv, c1, c2, aw, sm, kw, u, mass, boxc, boxa)
                k2 = _rhs_ext(q + 0.5 * h * k1, g, I, Iinv, c1, c2, aw, sm, kw, u, mass, boxc, boxa)
                k3 = _rhs_ext(q + 0.5 * h * k2, g, I, Iinv, c1, c2, aw, sm, kw, u, mass, boxc, boxa)
                k4 = _rhs_ext(q + h * k3, g, I, Iinv, c1, c2, aw, sm, kw, u, mass, boxc, boxa)
                q = q + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            t = times[idx]
        if not np.all(np.isfinite(q)) or np.sqrt(q[10] ** 2 + q[11] ** 2 + q[12] ** 2) > 500.0:
            return states, False
        states[idx] = q
    return states, True


class RigidGapModel:
    """The base free-flight model plus a chosen set of candidate effects.

    Parameters are one flat vector ``[p (14), effect blocks in the order of ``effects``]`` in
    physical units (``p`` as in :mod:`vidsim.rigid.dynamics`); ``q_base`` and ``t0`` are fixed.

    Args:
        body: the known body; cam: the calibrated camera at full resolution.
        times: (T,) nominal frame times of the frames to render, seconds.
        t0: time of the initial state, seconds; q_base: (4,) base orientation.
        effects: names from :data:`RIGID_EFFECTS` (may be empty: the base model).
        scale: image scale of the rendering (0.5 renders at half resolution).
        ramp: anti-aliasing ramp of the soft silhouette, pixels at this scale.
        hmax: RK4 step bound, seconds.
        gravity: known gravity magnitude (before ``gravity_scale``), m/s^2.
    """

    def __init__(self, body: BoxBody, cam: PinholeCamera, times: np.ndarray, t0: float, q_base: np.ndarray,
                 effects: tuple[str, ...] | list[str] = (), scale: float = 0.5, ramp: float = 1.0,
                 hmax: float = 1.0 / 120.0, gravity: float = G_EARTH) -> None:
        self.body = body
        self.cam_full = cam
        self.cam = cam if scale == 1.0 else cam.scaled(scale)
        self.times = np.asarray(times, float)
        if self.times.ndim != 1 or self.times.size == 0:
            raise GapError(f"times must be a non-empty 1-D array, got shape {self.times.shape}")
        self.t0 = float(t0)
        self.q_base = np.asarray(q_base, float)
        self.scale = float(scale)
        self.ramp = float(ramp)
        self.hmax = float(hmax)
        self.gravity = float(gravity)
        self.effects = tuple(effects)
        #: segmentation threshold of :func:`segmented_blur` (a fraction of the exposure; None: the
        #: plain mean coverage over the exposure)
        self.blur_threshold: float | None = 0.35
        self.slices: dict[str, slice] = {}
        k = 14
        for name in self.effects:
            n = effect_size(name, len(self.times))
            self.slices[name] = slice(k, k + n)
            k += n
        self.n_params = k
        self.corners = body.box_vertices()
        self.Iinv = np.linalg.inv(body.inertia)
        self.box_centers = np.ascontiguousarray(body.centers, float)
        h = body.half_sizes
        # (B, 3) face areas of each box normal to its body axes x, y, z, m^2
        self.face_areas = np.ascontiguousarray(4.0 * np.stack([h[:, 1] * h[:, 2], h[:, 0] * h[:, 2],
                                                               h[:, 0] * h[:, 1]], 1))

    # ------------------------------------------------------------------ parameters
    def get(self, theta: np.ndarray, name: str) -> np.ndarray:
        """Parameters of effect ``name`` in ``theta`` (zeros when the effect is not in the model)."""
        if name in self.slices:
            return np.asarray(theta[self.slices[name]], float)
        return np.zeros(effect_size(name, len(self.times)))

    def x_scale(self) -> np.ndarray:
        """(n_params,) typical step of each parameter (optimiser scaling)."""
        from vidsim.rigid.fit import PARAM_SCALE

        s = [PARAM_SCALE]
        for name in self.effects:
            s.append(np.full(effect_size(name, len(self.times)), RIGID_EFFECTS[name].scale))
        return np.concatenate(s)

    def lower(self) -> np.ndarray:
        """(n_params,) lower bounds (-inf where unbounded)."""
        lo = np.full(self.n_params, -np.inf)
        for name, sl in self.slices.items():
            if RIGID_EFFECTS[name].lower is not None:
                lo[sl] = RIGID_EFFECTS[name].lower
        return lo

    # ------------------------------------------------------------------ motion
    def capture_times(self, theta: np.ndarray) -> np.ndarray:
        """(T,) true capture times implied by the timing effects, seconds."""
        t = self.t0 + (self.times - self.t0) * (1.0 + float(self.get(theta, "time_rate")[0]))
        return t + float(self.get(theta, "time_offset")[0]) + self.get(theta, "time_jitter")

    def poses(self, theta: np.ndarray, times: np.ndarray, q_base: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, bool]:
        """Rendered body-frame poses at true times ``times`` (any shape, seconds).

        ``q_base`` (4,) replaces the model's base orientation for this call (e.g. to score a
        distinct alternative solution of the fit).

        Returns:
            X (..., 3) positions, Q (..., 4) quaternions of the body frame, and an ok flag.
        """
        theta = np.asarray(theta, float)
        p = theta[:14]
        shp = np.shape(times)
        tt = np.ascontiguousarray(np.ravel(times), float)
        tq = np.maximum(tt, self.t0)
        d = self.get(theta, "com_offset")
        q0, _ = initial_state(p, self.q_base if q_base is None else np.asarray(q_base, float))
        R0 = quat_to_rot(q0[3:7])
        if np.any(d):
            # p describes the body-frame origin (the stated centre of mass); the true centre moves
            off = R0 @ d
            q0 = q0.copy()
            q0[0:3] += off
            q0[7:10] += np.cross(p[9:12], off)
        g = gravity_vector(p[12], p[13], self.gravity * (1.0 + float(self.get(theta, "gravity_scale")[0])))
        states, ok = _integrate_ext(q0, self.t0, tq, self.hmax, g, self.body.inertia, self.Iinv,
                                    float(self.get(theta, "linear_drag")[0]),
                                    float(self.get(theta, "quadratic_drag")[0]),
                                    np.ascontiguousarray(self.get(theta, "wind")),
                                    float(self.get(theta, "magnus")[0]),
                                    float(self.get(theta, "angular_drag")[0]),
                                    np.ascontiguousarray(self.get(theta, "drag_torque")), self.body.mass,
                                    # the boxes' lever arms from the true centre of mass, which is integrated
                                    self.box_centers - d[None, :] if np.any(d) else self.box_centers,
                                    self.face_areas)
        if not ok:
            return np.zeros(shp + (3,)), np.zeros(shp + (4,)), False
        X = states[:, 0:3].copy()
        Q = states[:, 3:7]
        if np.any(d):
            for i in range(len(X)):
                X[i] -= quat_to_rot(Q[i]) @ d
        return X.reshape(shp + (3,)), Q.reshape(shp + (4,)), True

    # ------------------------------------------------------------------ images
    def _camera(self, theta: np.ndarray) -> PinholeCamera:
        """The camera at this model's scale with the candidate lens distortion added."""
        k1 = float(self.get(theta, "lens_k1")[0])
        cam = self.cam
        if k1 != 0.0:
            dist = np.array(cam.dist, float).copy()
            dist[0] += k1
            cam = PinholeCamera(cam.K, cam.R, cam.t, cam.width, cam.height, dist)
        return cam

    def _sub_times(self, theta: np.ndarray, idx: np.ndarray, n_exp: int, n_rs: int) -> np.ndarray:
        """(F, n_exp, n_rs) capture times of the exposure x rolling-shutter sub-samples, seconds."""
        tc = self.capture_times(theta)[idx]
        b = max(float(self.get(theta, "motion_blur")[0]), 0.0)
        rs = float(self.get(theta, "rolling_shutter")[0])
        exp_off = np.linspace(-0.5, 0.5, n_exp) * np.sqrt(b) if n_exp > 1 else np.zeros(1)
        rs_off = (np.arange(n_rs) + 0.5) / n_rs * rs if n_rs > 1 else np.zeros(1)
        return tc[:, None, None] + exp_off[None, :, None] + rs_off[None, None, :]

    def image_points(self, theta: np.ndarray) -> np.ndarray:
        """(T, 4, n_corners, 2) image positions of the box corners at this model's scale, pixels.

        The four sub-samples per frame are the two ends of the exposure and the first and last
        rolling-shutter row times, so that every candidate (motion, timing, lens, blur extent,
        shutter skew) moves these points; NaN when the simulation diverged.
        """
        theta = np.asarray(theta, float)
        idx = np.arange(len(self.times))
        b = max(float(self.get(theta, "motion_blur")[0]), 0.0)
        rs = float(self.get(theta, "rolling_shutter")[0])
        tc = self.capture_times(theta)
        sub = (tc[:, None] + np.array([-0.5, 0.5, -0.5, 0.5])[None, :] * np.sqrt(b)
               + np.array([0.0, 0.0, 1.0, 1.0])[None, :] * rs)
        X, Q, ok = self.poses(theta, sub)
        C = self.corners.reshape(-1, 3)
        if not ok:
            return np.full((len(idx), 4, len(C), 2), np.nan)
        cam = self._camera(theta)
        R = np.stack([quat_to_rot(q) for q in Q.reshape(-1, 4)])
        P = np.einsum("nij,cj->nci", R, C) + X.reshape(-1, 1, 3)
        uv = cam.project(P.reshape(-1, 3))
        return uv.reshape(len(idx), 4, len(C), 2)

    def fd_steps(self, theta: np.ndarray, target_px: float = 1e-4, probe: float = 0.25) -> np.ndarray:
        """(n_params,) finite-difference steps that move the body's image by about ``target_px``.

        The soft silhouette is linear in an edge's position only within its anti-aliasing ramp
        (``ramp`` pixels) and its derivative jumps at the ramp's ends, so a derivative by
        differences is accurate only for steps that move the image by a small fraction of it
        (see :meth:`vidsim.gap.rigid_diagnose.Problem.jacobian`). Each parameter is probed by
        ``probe`` x its typical scale, the largest corner displacement over all frames is
        measured (poses and projection only, no rendering) and the step is shrunk to give
        ``target_px`` (never enlarged); per-frame time errors get one step per frame. Blur
        (``disp_power`` != 1: its extent grows as the square root of its parameter and the
        silhouette responds to it at second order, only where the ramp bends) keeps the probe
        step: a step of a tiny extent would difference nothing but the ramp's ends.
        """
        theta = np.asarray(theta, float)
        base = probe * self.x_scale()
        steps = base.copy()
        P0 = self.image_points(theta)
        if not np.all(np.isfinite(P0)):
            return steps

        def disp(tp: np.ndarray) -> np.ndarray:
            d = np.linalg.norm(self.image_points(tp) - P0, axis=-1)
            return np.where(np.isfinite(d), d, np.inf).reshape(len(self.times), -1).max(1)

        def shrink(h: np.ndarray, d: np.ndarray) -> np.ndarray:
            # a probe whose simulation diverged (d = inf) says nothing about the step: keep the
            # probe's (target/inf = 0 had made a zero step and a 0/0 Jacobian column)
            with np.errstate(divide="ignore", invalid="ignore"):
                f = np.where(np.isfinite(d) & (d > target_px), target_px / d, 1.0)
            return h * np.where(np.isfinite(f) & (f > 0), f, 1.0)

        jit = self.slices.get("time_jitter")
        linear = np.ones(self.n_params, bool)
        for name, sl in self.slices.items():
            linear[sl] = RIGID_EFFECTS[name].disp_power == 1.0
        for j in range(self.n_params):
            if (jit is not None and jit.start <= j < jit.stop) or not linear[j]:
                continue
            tp = theta.copy()
            tp[j] += base[j]
            steps[j] = float(shrink(base[j:j + 1], np.array([disp(tp).max()]))[0])
        if jit is not None:
            tp = theta.copy()
            tp[jit] += base[jit]
            steps[jit] = shrink(base[jit], disp(tp))
        return steps

    def render(self, theta: np.ndarray, frames: np.ndarray | None = None, dX: np.ndarray | None = None
               ) -> tuple[np.ndarray, bool]:
        """Soft silhouettes of the model at this model's scale.

        Args:
            theta: (n_params,) parameters.
            frames: indices into ``times`` to render (default all).
            dX: optional (F, 3) world offsets added to the rendered positions, metres (used by
                the placebo of the screen).

        Returns:
            (F, h, w) float coverage in [0, 1] and an ok flag (False: the simulation diverged or
            the body passed behind the camera; the images are then zeros).
        """
        theta = np.asarray(theta, float)
        idx = np.arange(len(self.times)) if frames is None else np.asarray(frames, int)
        cam = self._camera(theta)
        n_exp = BLUR_SAMPLES if float(self.get(theta, "motion_blur")[0]) > 0 else 1
        n_rs = RS_SLABS if float(self.get(theta, "rolling_shutter")[0]) != 0.0 else 1
        sub = self._sub_times(theta, idx, n_exp, n_rs)
        X, Q, ok = self.poses(theta, sub)
        if dX is not None:
            X = X + np.asarray(dX, float)[:, None, None, :]
        H, W = cam.height, cam.width
        if not ok or np.any((X.reshape(-1, 3) @ cam.R.T + cam.t)[:, 2] < 0.05):
            return np.zeros((len(idx), H, W)), False
        out = np.zeros((len(idx), H, W))
        c0 = None
        for e in range(n_exp):
            if n_rs == 1:
                img = render_coverage(X[:, e, 0], Q[:, e, 0], self.corners, cam, self.ramp)
            else:
                img = np.zeros((len(idx), H, W))
                for j in range(n_rs):
                    r0 = int(round(j * H / n_rs))
                    r1 = int(round((j + 1) * H / n_rs))
                    img[:, r0:r1] = render_coverage(X[:, e, j], Q[:, e, j], self.corners, cam, self.ramp)[:, r0:r1]
            if e == n_exp // 2:
                c0 = img  # the middle of the exposure: the frame time
            out += img
        out /= n_exp
        if n_exp > 1 and self.blur_threshold is not None:
            out = segmented_blur(c0, out, self.blur_threshold)
        return out, True
