"""Free flight of a small ball from an uncalibrated real video: track, split into flights, fit.

A ball far from the camera and moving roughly parallel to the image is seen under weak
perspective: its image centroid follows ``u(t) = u0 + a t + 1/2 g_u t^2`` (same for ``v``), where
``(g_u, g_v)`` is gravity projected into the image in pixels / s^2. Its direction is the gravity
direction in the camera frame (in-plane angle), and ``|g_img| / 9.81 m/s^2`` is the image scale
in pixels per metre: scale from gravity's known magnitude. Model limits (stated): depth changes
during a flight (the ball grows as it approaches) and air drag are not modelled; they show up in
the residual.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vidsim.rigid.dynamics import G_EARTH


class BallisticError(ValueError):
    """Bad input to the ball tracker or fit; the message names the field."""


def track_blob(masks: np.ndarray, min_area: int = 15, max_area: int = 600, min_fill: float = 0.6,
               max_jump: float = 90.0) -> tuple[np.ndarray, np.ndarray]:
    """Follow one compact blob through (T, H, W) masks.

    Per frame the candidates are connected components of ``min_area..max_area`` pixels whose
    area fills at least ``min_fill`` of the circle spanning their bounding box. The candidate
    nearest to the previous detection (within ``max_jump`` pixels per frame elapsed) is taken;
    with no recent detection, or none within reach, the roundest (largest fill x sqrt(area)) is.

    Returns:
        centres (T, 2) (u, v) pixels, NaN where not found, and areas (T,) pixels.
    """
    m = np.asarray(masks, bool)
    if m.ndim != 3:
        raise BallisticError(f"masks must be (T, H, W), got shape {m.shape}")
    T = m.shape[0]
    c = np.full((T, 2), np.nan)
    area = np.zeros(T)
    last, last_k = None, -10
    for k in range(T):
        n, lab, stats, cent = cv2.connectedComponentsWithStats(m[k].astype(np.uint8), connectivity=8)
        cands = []
        for j in range(1, n):
            a = stats[j, cv2.CC_STAT_AREA]
            w, h = stats[j, cv2.CC_STAT_WIDTH], stats[j, cv2.CC_STAT_HEIGHT]
            fill = a / (np.pi * (max(w, h) / 2.0) ** 2)
            if min_area <= a <= max_area and fill >= min_fill:
                cands.append((cent[j], a, fill))
        if not cands:
            continue
        j = -1
        if last is not None and k - last_k <= 3:
            d = [np.linalg.norm(cc[0] - last) for cc in cands]
            j = int(np.argmin(d))
            if d[j] > max_jump * (k - last_k):
                j = -1
        if j < 0:
            j = int(np.argmax([cc[2] * np.sqrt(cc[1]) for cc in cands]))
        c[k], area[k] = cands[j][0], cands[j][1]
        last, last_k = c[k], k
    return c, area


def split_flights(times: np.ndarray, centres: np.ndarray, min_len: int = 6) -> list[np.ndarray]:
    """Index arrays of free flights: runs of detections ended by a gap or a bounce.

    A gap is a frame without a detection (non-finite centre). A bounce is where the image row
    velocity ``dv/dt`` (``centres[:, 1]``, image v grows downwards: the test assumes gravity points
    down the image, not along an estimated gravity direction) turns from positive (moving down) to
    negative (moving up) between consecutive detections and drops by more than a fixed 200 px/s
    (not scaled with the image size or frame rate); an apex turns the other way and is not split.
    Runs shorter than 3 detections and flights shorter than ``min_len`` are dropped.
    """
    t = np.asarray(times, float)
    c = np.asarray(centres, float)
    ok = np.all(np.isfinite(c), axis=1)
    runs, cur = [], []
    for k in range(len(t)):
        if ok[k]:
            cur.append(k)
        elif cur:
            runs.append(cur)
            cur = []
    if cur:
        runs.append(cur)
    flights = []
    for r in runs:
        r = np.asarray(r)
        if len(r) < 3:
            continue
        v = np.diff(c[r, 1]) / np.diff(t[r])  # image v grows downwards: falling = v > 0
        start = 0
        for i in range(1, len(v)):
            if v[i - 1] > 0 and v[i] < 0 and v[i - 1] - v[i] > 200.0:  # abrupt reversal: a bounce
                flights.append(r[start:i + 1])
                start = i + 1
        flights.append(r[start:])
    return [f for f in flights if len(f) >= min_len]


@dataclass
class FlightFit:
    """Weak-perspective parabola of one flight.

    Attributes:
        frames: (n,) frame indices used.
        coef: (3, 2) [position (px), velocity (px/s), acceleration (px/s^2)] at the first frame.
        gravity_angle_deg: angle of image gravity from the image +v axis (down), degrees,
            positive towards +u.
        pixels_per_metre: |image acceleration| / 9.81.
        rms_px: RMS residual of the centroids, pixels; residuals: (n, 2).
    """

    frames: np.ndarray
    coef: np.ndarray
    gravity_angle_deg: float
    pixels_per_metre: float
    rms_px: float
    residuals: np.ndarray

    def summary(self) -> dict:
        """Plain dictionary."""
        return {"frames": self.frames.tolist(), "position_px": self.coef[0].tolist(),
                "velocity_px_s": self.coef[1].tolist(), "accel_px_s2": self.coef[2].tolist(),
                "gravity_angle_deg": self.gravity_angle_deg, "pixels_per_metre": self.pixels_per_metre,
                "rms_px": self.rms_px}


def fit_flight(times: np.ndarray, centres: np.ndarray, frames: np.ndarray) -> FlightFit:
    """Least-squares parabola through the centroids of ``frames`` at ``times``."""
    idx = np.asarray(frames, int)
    if idx.size < 4:
        raise BallisticError(f"a flight needs >= 4 detections, got {idx.size}")
    t = np.asarray(times, float)[idx]
    t = t - t[0]
    uv = np.asarray(centres, float)[idx]
    if not np.all(np.isfinite(uv)):
        raise BallisticError("centres of the flight frames must be finite")
    A = np.stack([np.ones_like(t), t, 0.5 * t * t], axis=1)
    coef, *_ = np.linalg.lstsq(A, uv, rcond=None)
    res = uv - A @ coef
    g = coef[2]
    return FlightFit(idx, coef, float(np.degrees(np.arctan2(g[0], g[1]))), float(np.linalg.norm(g) / G_EARTH),
                     float(np.sqrt((res ** 2).sum(1).mean())), res)


@dataclass
class PerspectiveFlightFit:
    """Full-perspective free flight of a ball seen by a camera with unknown focal length.

    Attributes:
        frames: (n,) frame indices used.
        position: (3,) ball centre at the first frame, camera frame, metres.
        velocity: (3,) m/s; gravity: (3,) m/s^2 in the camera frame (|g| = 9.81 fixed: the scale).
        focal: focal length, pixels (principal point at the image centre).
        radius: ball radius, metres (from the blob area).
        rms_px: RMS residual of the centroids, pixels; residuals: (n, 2).
        focal_sd_log: standard error of ln(focal) at the optimum (Gauss-Newton, residual variance
            of the fit): 0.1 means the flight determines the focal to about 10 %.
    """

    frames: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    gravity: np.ndarray
    focal: float
    radius: float
    rms_px: float
    residuals: np.ndarray
    focal_sd_log: float = float("nan")

    def summary(self) -> dict:
        """Plain dictionary."""
        return {"frames": self.frames.tolist(), "position_m": self.position.tolist(),
                "velocity_m_s": self.velocity.tolist(), "gravity_cam": self.gravity.tolist(),
                "focal_px": self.focal, "focal_sd_log": self.focal_sd_log, "focal_determined": self.focal_determined,
                "radius_m": self.radius, "rms_px": self.rms_px}

    @property
    def focal_determined(self) -> bool:
        """The flight fixes the focal to better than 10 % (one standard error of ln f)."""
        return bool(self.focal_sd_log < 0.1)


def fit_flight_perspective(times: np.ndarray, centres: np.ndarray, areas: np.ndarray, frames: np.ndarray,
                           image_size: tuple[int, int], focal_guess: float = 600.0) -> PerspectiveFlightFit:
    """Fit ``X(t) = X0 + V0 t + g t^2 / 2`` (|g| = 9.81 m/s^2) projected by a pinhole of unknown focal.

    Observations: blob centroids (pixels) and apparent radii ``sqrt(area / pi)`` (pixels, weight
    0.5: blob areas are coarse). Starts from the weak-perspective fit.

    Args:
        times: (T,) seconds; centres: (T, 2) pixels; areas: (T,) pixels; frames: indices to use.
        image_size: (width, height) pixels.
        focal_guess: initial focal length, pixels.
    """
    from scipy.optimize import least_squares

    idx = np.asarray(frames, int)
    weak = fit_flight(times, centres, idx)
    t = np.asarray(times, float)[idx]
    t = t - t[0]
    uv = np.asarray(centres, float)[idx]
    rad = np.sqrt(np.asarray(areas, float)[idx] / np.pi)
    if np.any(rad <= 0):
        raise BallisticError("areas of the flight frames must be positive")
    cx, cy = (image_size[0] - 1) / 2.0, (image_size[1] - 1) / 2.0
    ppm = weak.pixels_per_metre
    Z0 = focal_guess / ppm
    g_img = weak.coef[2] / np.linalg.norm(weak.coef[2])
    x0 = np.r_[(weak.coef[0] - [cx, cy]) / ppm, Z0, weak.coef[1] / ppm, 0.0,
               np.arctan2(g_img[0], g_img[1]), 0.0, np.log(focal_guess), np.log(rad.mean() * Z0 / focal_guess)]

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
        a, b = x[6], x[7]  # in-plane angle and out-of-plane angle of gravity
        g = G_EARTH * np.array([np.sin(a) * np.cos(b), np.cos(a) * np.cos(b), np.sin(b)])
        return x[0:3], x[3:6], g, float(np.exp(x[8])), float(np.exp(x[9]))

    def resid(x: np.ndarray) -> np.ndarray:
        X0, V0, g, f, R = unpack(x)
        P = X0 + np.outer(t, V0) + 0.5 * np.outer(t * t, g)
        z = np.maximum(P[:, 2], 1e-3)
        pu = f * P[:, 0] / z + cx
        pv = f * P[:, 1] / z + cy
        return np.concatenate([pu - uv[:, 0], pv - uv[:, 1], 0.5 * (f * R / z - rad)])

    sol = least_squares(resid, x0, method="lm", max_nfev=2000)
    X0, V0, g, f, R = unpack(sol.x)
    r = resid(sol.x)
    res2 = np.stack([r[: len(t)], r[len(t): 2 * len(t)]], 1)
    # how well the flight determines the focal: Gauss-Newton covariance of ln f at the optimum
    # (residual variance from the fit itself, no truncation of small singular values). On the real
    # toss one flight leaves a direction free to numerical precision (singular value ratio ~2e-9):
    # depth, focal, depth velocity and the out-of-plane gravity angle move together, so the focal
    # is where the optimiser stopped (scipy 1.15 and 1.17 stop at 431 and 378 px on the same flight
    # with the same RMS), and focal_sd_log says so instead of presenting a number.
    _, sv, Vt = np.linalg.svd(sol.jac, full_matrices=False)
    dof = max(len(r) - len(sol.x), 1)
    s2 = float(r @ r) / dof
    with np.errstate(divide="ignore", over="ignore"):
        var_logf = s2 * float(np.sum(Vt[:, 8] ** 2 / np.maximum(sv, 1e-300) ** 2))
    sd_logf = float(np.sqrt(var_logf)) if np.isfinite(var_logf) else float("inf")
    return PerspectiveFlightFit(idx, X0, V0, g, f, R, float(np.sqrt((res2 ** 2).sum(1).mean())), res2, sd_logf)
