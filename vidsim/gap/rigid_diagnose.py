"""Diagnose the sim-to-real gap of a rigid free-flight fit: where it lies, which effect, how far.

Input is what an estimator may read: the silhouettes of the footage, the frame times, the
calibrated camera, the known body and the fitted initial state (a :class:`~vidsim.rigid.fit.FitResult`
summary). Nothing here reads truth.

Procedure (all residuals are soft-silhouette differences ``a_sim - A_obs`` on a fixed region of
interest around the body, at a reduced image scale; the *gap* is the mean per frame of
``sum |a_sim - A_obs|``, i.e. the mismatch area in full-resolution pixels, seed eq. 3):

1. Split the visible frames into training frames and held-out frames (every third, or the end
   of the flight with ``split=end``), never used by any refit.
2. Base refit (no effect) on the training frames from the given fit: the gap before, on held-out
   frames.
3. Noise floor: each held-out frame's pose fitted on its own (6 free numbers per frame, no
   dynamics) -- the error that no motion model can remove with this renderer and these masks
   (rendering + segmentation noise). The base gap minus this floor is the *dynamics* part; the
   floor itself is the *rendering/camera* part plus noise.
4. Screen (score test at zero, all frames, at the base refit): for each candidate block ``e`` with
   Jacobian ``J_e`` the first-order decrease of the sum of squares after re-optimising the base
   parameters, ``D_e = g^T M^+ g`` with ``g = J_e^T r`` and ``M = J_e^T (I - P_theta) J_e``. The
   Jacobians are differences over steps that move the image by 1e-4 of the soft-silhouette ramp
   (:meth:`Problem.jacobian`): the score needs the small part of a column the base cannot absorb.
5. Forward selection, judged on held-out frames: refit the best ``top_k`` candidates one at a
   time; *closure* = (gap_before - gap_after) / (gap_before - floor). The effect with the largest
   closure is named when the held-out gap before exceeds the floor by ``min_excess`` (relative)
   and it closes at least ``min_closure`` -- a penalty so that an effect without support is not
   named. While the held-out gap the named effects leave still exceeds the floor by
   ``min_excess``, screen again with them in the model (a conditional score test), refit the
   ``top_k`` best of the rest together with them, and name the best that closes ``min_closure``
   of what remains (``pairs``: up to two effects). Per-frame time jitter cannot be checked on
   held-out frames (its parameters there are not identified), so it is judged on its training
   closure and on whether its fitted time errors are white (most of their variance is not a
   cubic drift, ``jitter_min_white``), unlike the smooth drift a missing force leaves; in a model
   with jitter each held-out frame's own time error is fitted on that frame alone (one number),
   so that the other effects are judged at the right times, and jitter must beat, on those
   held-out frames, the same one-number fit of a placebo (a shift across the frame's motion).
6. Where: per-frame gap with motion phases (fast/slow image speed, start/end), accumulated residual
   heatmap, per face of the body (through the rasteriser's face ids), and the per-part split.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.optimize import least_squares

import vidsim
from vidsim.gap.rigid_model import RIGID_EFFECTS, GapError, RigidGapModel
from vidsim.optim.cache import StepMemo, fingerprint
from vidsim.rigid.body import BoxBody
from vidsim.rigid.dynamics import G_EARTH, quat_exp, quat_mul
from vidsim.rigid.fit import visible_frames
from vidsim.rigid.silhouette import render_coverage
from vidsim.video.camera import PinholeCamera

BAD_RESIDUAL = 1.0
"""Residual of every pixel when the simulation diverged (the worst possible coverage mismatch)."""

FD_TARGET = 1e-4
"""Finite-difference steps move the body's image by this fraction of the soft-silhouette ramp."""


@dataclass
class DiagnoseConfig:
    """Settings of the rigid gap diagnosis.

    Attributes:
        candidates: effect names to consider (default: the whole library).
        holdout: fraction of the visible frames held out.
        split: "interleaved" (every round(1/holdout)-th frame is held out) or "end" (the last
            frames: an extrapolation test, harsher on every extra parameter).
        scale: image scale of the residuals (0.5: half resolution).
        ramp: soft-silhouette ramp, pixels at that scale.
        roi_px: region of interest: pixels within this distance (at scale) of either silhouette.
        top_k: number of screened candidates refitted.
        max_nfev: refit budget (residual evaluations per refit).
        min_closure: held-out closure an effect needs to be named (of the excess the effects
            named before it leave): at least half of the gap must go for an effect to explain it.
        min_excess: the held-out gap must exceed the floor by this fraction for anything to be named.
        jitter_min_white: time jitter is named only when at least this fraction of the variance
            of its fitted time errors is not explained by a cubic drift in time.
        pairs: forward selection may name a second effect (conditional screen, then joint refits).
        joint_pairs: (with ``pairs``) when no single candidate is named although a gap remains, refit every pair of
            the ``top_k`` screened candidates jointly (two effects that each close a quarter of
            the gap pass no single-effect test) and name a pair when it closes ``min_closure`` of
            the held-out excess and beats each of its members alone by ``pair_min_gain``.
        pair_min_gain: held-out closure each member of a jointly named pair must add.
        blur_thresholds: segmentation thresholds (fractions of the exposure,
            :func:`vidsim.gap.rigid_model.segmented_blur`) tried in a refit with motion blur; the
            one with the lowest training cost is kept and reported (the screen uses 0.35).
    """

    candidates: list[str] = field(default_factory=lambda: list(RIGID_EFFECTS))
    holdout: float = 0.3
    split: str = "interleaved"
    scale: float = 0.5
    ramp: float = 1.0
    roi_px: int = 12
    top_k: int = 3
    max_nfev: int = 15
    min_closure: float = 0.5
    min_excess: float = 0.15
    jitter_min_white: float = 0.5
    pairs: bool = True
    joint_pairs: bool = True
    pair_min_gain: float = 0.2
    blur_thresholds: list[float] = field(default_factory=lambda: [0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5])

    def validate(self) -> None:
        """Raise :class:`GapError` naming the field when a setting is not usable."""
        if not all(0.0 < c < 1.0 for c in self.blur_thresholds):
            raise GapError(f"gap.diagnose.blur_thresholds must be fractions in (0, 1), got {self.blur_thresholds}")
        if not 0.0 <= self.pair_min_gain <= 1.0:
            raise GapError(f"gap.diagnose.pair_min_gain must be in [0, 1], got {self.pair_min_gain}")
        for c in self.candidates:
            if c not in RIGID_EFFECTS:
                raise GapError(f"gap.diagnose.candidates: unknown effect {c!r}; the library has {sorted(RIGID_EFFECTS)}")
        if not 0.05 <= self.holdout <= 0.6:
            raise GapError(f"gap.diagnose.holdout must be in [0.05, 0.6], got {self.holdout}")
        if self.split not in ("interleaved", "end"):
            raise GapError(f"gap.diagnose.split must be 'interleaved' or 'end', got {self.split!r}")
        if not 0.1 <= self.scale <= 1.0:
            raise GapError(f"gap.diagnose.scale must be in [0.1, 1], got {self.scale}")
        if self.top_k < 1 or self.max_nfev < 1:
            raise GapError(f"gap.diagnose.top_k and gap.diagnose.max_nfev must be >= 1, got {self.top_k}, {self.max_nfev}")


# ----------------------------------------------------------------------------- residuals
class Problem:
    """Soft-silhouette residuals of a :class:`RigidGapModel` against observed masks on a fixed ROI.

    Args:
        model: the model (its ``times`` are all visible frames).
        obs: (T, h, w) observed coverage at the model's scale (area-averaged masks).
        roi: (T, h, w) bool region of interest.
        frames: indices of the frames whose residuals count.
    """

    def __init__(self, model: RigidGapModel, obs: np.ndarray, roi: np.ndarray, frames: np.ndarray) -> None:
        self.model = model
        self.obs = obs
        self.roi = roi
        self.frames = np.asarray(frames, int)
        self.n_evals = 0

    def residual_images(self, theta: np.ndarray) -> tuple[np.ndarray, bool]:
        """(F, h, w) ``a_sim - A_obs`` on ``frames`` (zero outside the ROI) and an ok flag."""
        self.n_evals += 1
        a, ok = self.model.render(theta, self.frames)
        if not ok:
            return np.where(self.roi[self.frames], BAD_RESIDUAL, 0.0), False
        return (a - self.obs[self.frames]) * self.roi[self.frames], True

    def residual(self, theta: np.ndarray) -> np.ndarray:
        """Flat residual vector over the ROI pixels of ``frames``."""
        img, _ = self.residual_images(theta)
        return img[self.roi[self.frames]]

    def row_frames(self) -> np.ndarray:
        """(n_res,) the frame (position in ``frames``) of each residual row."""
        return np.repeat(np.arange(len(self.frames)), self.roi[self.frames].reshape(len(self.frames), -1).sum(1))

    def jacobian(self, theta: np.ndarray, target_px: float | None = None) -> np.ndarray:
        """(n_res, n_params) central finite differences (one-sided at a lower bound).

        Each parameter's step moves the body's image by about ``target_px`` pixels at the
        model's scale (default :data:`FD_TARGET` x the soft-silhouette ramp; see
        :meth:`RigidGapModel.fd_steps`). The soft silhouette's derivative jumps at the ends of
        its ramp, so a difference over a step straddling them errs by ~step/ramp of the column;
        the screen and the refit's Gauss-Newton model combine effect and base columns whose raw
        image motions (many pixels for a drag or a Magnus force) cancel to a net motion of a
        fraction of a pixel, which needs columns accurate to ~0.1 %. (Measured on the MuJoCo drag
        case: with steps of 0.1 px the linear model predicted a training cost of 764 where the
        refit reached 39, and per-box drag screened at 2 % of the residual instead of 41 %.)
        Per-frame parameters (time jitter) are differenced all at once: frame ``k``'s column
        only sees frame ``k``'s rows.
        """
        theta = np.asarray(theta, float)
        hs = self.model.fd_steps(theta, FD_TARGET * self.model.ramp if target_px is None else target_px)
        m = self.roi[self.frames]
        cols = np.zeros((int(m.sum()), self.model.n_params))
        jit = self.model.slices.get("time_jitter")
        lower = self.model.lower()
        for j in range(self.model.n_params):
            if jit is not None and jit.start <= j < jit.stop:
                continue
            h = hs[j]
            tp = theta.copy()
            tp[j] += h
            tm = theta.copy()
            tm[j] -= h
            if np.isfinite(lower[j]) and tm[j] < lower[j]:  # one-sided at a bound
                cols[:, j] = (self.residual(tp) - self.residual(theta)) / h
            else:
                cols[:, j] = (self.residual(tp) - self.residual(tm)) / (2 * h)
        if jit is not None:
            h = hs[jit]
            tp = theta.copy()
            tp[jit] += h
            tm = theta.copy()
            tm[jit] -= h
            dimg = (self.residual_images(tp)[0] - self.residual_images(tm)[0]) / (2 * h[self.frames, None, None])
            for i, k in enumerate(self.frames):
                col = np.zeros_like(dimg)
                col[i] = dimg[i]
                cols[:, jit.start + k] = col[m]
        return cols

    def placebo_jacobian(self, theta: np.ndarray) -> np.ndarray:
        """(n_res, F) per-frame columns of a placebo for time jitter: each frame's body moved
        across its image motion (perpendicular to the velocity, in the image plane) by as much as
        a time error of one jitter step moves it along. Equal size and count, no timing meaning.
        The steps are the time-jitter steps of :meth:`jacobian` (the model must hold time_jitter)."""
        m = self.roi[self.frames]
        theta = np.asarray(theta, float)
        h = self.model.fd_steps(theta, FD_TARGET * self.model.ramp)[self.model.slices["time_jitter"]][self.frames]
        dX = h[:, None] * across_motion(self.model, theta, self.frames)
        ip, _ = self.model.render(theta, self.frames, dX)
        im, _ = self.model.render(theta, self.frames, -dX)
        self.n_evals += 2
        dimg = (ip - im) / (2 * h[:, None, None])
        cols = np.zeros((int(m.sum()), len(self.frames)))
        for i in range(len(self.frames)):
            col = np.zeros_like(dimg)
            col[i] = dimg[i]
            cols[:, i] = col[m]
        return cols

    def gap_per_frame(self, theta: np.ndarray, frames: np.ndarray | None = None) -> np.ndarray:
        """(F,) mismatch area per frame, full-resolution pixels."""
        fr = self.frames if frames is None else np.asarray(frames, int)
        a, ok = self.model.render(theta, fr)
        if not ok:
            return np.full(len(fr), np.inf)
        d = np.abs(a - self.obs[fr]) * self.roi[fr]
        return d.reshape(len(fr), -1).sum(1) / self.model.scale ** 2


def residual_region(model: RigidGapModel, masks: np.ndarray, theta: np.ndarray, roi_px: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Observed coverage and the fixed region of interest of a :class:`Problem`.

    Args:
        model: the model (its ``times`` are the frames of ``masks``).
        masks: (T, H, W) bool observed silhouettes at full resolution.
        theta: parameters whose rendering, with the observation, defines the region.
        roi_px: pixels (at the model's scale) within this distance of either silhouette are in the region.

    Returns:
        obs (T, h, w) area-averaged coverage at the model's scale and roi (T, h, w) bool.
    """
    h, w = model.cam.height, model.cam.width
    obs = np.stack([cv2.resize(m.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) for m in masks])
    a0, ok0 = model.render(theta)
    if not ok0:
        raise GapError("fit: the fitted throw diverges or passes behind the camera; nothing to diagnose")
    ker = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * roi_px + 1, 2 * roi_px + 1))
    roi = np.stack([cv2.dilate(((o > 0.01) | (a > 0.01)).astype(np.uint8), ker) > 0 for o, a in zip(obs, a0)])
    return obs, roi


def frame_sandwich_cov(J: np.ndarray, r: np.ndarray, groups: np.ndarray | None) -> np.ndarray:
    """Covariance of least-squares parameters with residuals correlated within frames.

    The residual left after a refit is mostly model error, correlated over each frame's pixels,
    so the Gauss-Newton ``s2 (J'J)^-1``, which counts every pixel as an independent observation,
    is far too narrow (review of 5 Dec 2026: the rigid suite's "95 %" intervals held the true
    strength in 3 of 24 components). With one cluster per frame: ``B^-1 M B^-1``, ``B = J'J``,
    ``M = sum_f (J_f' r_f)(J_f' r_f)'``, times the CR1 small-sample factor
    ``G/(G-1) (n-1)/(n-p)`` (``G`` frames). ``groups`` None: the i.i.d. form. A parameter that
    only one frame sees (a per-frame time error) gets no usable variance from its own frame
    (its score there is zero at the minimum): its entry is not an interval.
    """
    n, p = J.shape
    Binv = np.linalg.pinv(J.T @ J, rcond=1e-10)
    if groups is None or len(np.unique(groups)) < 2:
        return Binv * float(r @ r / max(n - p, 1))
    G = np.unique(groups)
    S = np.stack([J[groups == g].T @ r[groups == g] for g in G])  # (G, p) per-frame scores
    c = len(G) / (len(G) - 1) * (n - 1) / max(n - p, 1)
    return c * Binv @ (S.T @ S) @ Binv


def refit(prob: Problem, theta0: np.ndarray, max_nfev: int = 15, upper: np.ndarray | None = None,
          lower: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """Least-squares refit of all parameters of ``prob.model`` on ``prob.frames``.

    ``upper`` / ``lower`` (n_params,): optional bounds (``inf``: none); the lower ones default to
    the model's (:meth:`RigidGapModel.lower`).

    Returns:
        theta and info ``{cost, nfev, ok, cov}`` where ``cov`` is the parameters' covariance
        (physical units) with the residuals clustered by frame (:func:`frame_sandwich_cov`).
    """
    xs = prob.model.x_scale()
    lo = ((prob.model.lower() if lower is None else np.asarray(lower, float)) - theta0) / xs
    x0 = np.zeros(prob.model.n_params)
    # a parameter starting on its bound cannot move under the trust-region's bound scaling
    # (Coleman-Li): start bounded ones a quarter of their typical size inside
    x0 = np.where(np.isfinite(lo), np.maximum(x0, lo + 0.25), x0)
    hi = np.full_like(lo, np.inf) if upper is None else (np.asarray(upper, float) - theta0) / xs
    x0 = np.minimum(x0, hi - 0.25)

    def fun(x: np.ndarray) -> np.ndarray:
        return prob.residual(theta0 + x * xs)

    def jac(x: np.ndarray) -> np.ndarray:
        return prob.jacobian(theta0 + x * xs) * xs

    sol = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf",
                        max_nfev=max_nfev, x_scale=1.0)
    theta = theta0 + sol.x * xs
    J = sol.jac
    n, p = J.shape
    try:
        groups = prob.row_frames() if hasattr(prob, "row_frames") and len(sol.fun) == n else None
        cov_x = frame_sandwich_cov(J, np.asarray(sol.fun, float), groups if groups is not None and len(groups) == n else None)
    except np.linalg.LinAlgError:
        cov_x = np.full((p, p), np.nan)
    cov = cov_x * np.outer(xs, xs)
    return theta, {"cost": float(2 * sol.cost), "nfev": int(sol.nfev), "ok": bool(np.isfinite(sol.cost)),
                   "cov": cov, "jac": J}


def score_screen(J_theta: np.ndarray, blocks: dict[str, np.ndarray], r: np.ndarray,
                 one_sided: dict[str, bool] | None = None) -> dict[str, dict]:
    """Score test at zero of each candidate block.

    Args:
        J_theta: (n, p) Jacobian of the base parameters; blocks: name -> (n, k_e) Jacobian of the
            effect's parameters at zero; r: (n,) residuals at the base optimum.
        one_sided: name -> True when the effect's parameter is bounded below by zero.

    Returns:
        name -> ``{decrease, fraction, df, step}``: first-order decrease of the sum of squares
        after re-optimising the base parameters, as a fraction of the current sum, the block's
        size and the Gauss-Newton step of its parameters (scaled units of the Jacobian).
    """
    one_sided = one_sided or {}
    sse = float(r @ r)
    A = J_theta.T @ J_theta
    Ainv = np.linalg.pinv(A, rcond=1e-10)
    Pr = r - J_theta @ (Ainv @ (J_theta.T @ r))
    out = {}
    for name, Je in blocks.items():
        Jp = Je - J_theta @ (Ainv @ (J_theta.T @ Je))
        g = Jp.T @ Pr
        M = Jp.T @ Jp
        if M.shape[0] == 0 or not np.any(M):
            out[name] = {"decrease": 0.0, "fraction": 0.0, "df": int(Je.shape[1]), "step": []}
            continue
        Minv = np.linalg.pinv(M, rcond=1e-8)
        step = -Minv @ g
        dec = float(g @ Minv @ g)
        if one_sided.get(name) and Je.shape[1] == 1 and step[0] < 0:
            dec, step = 0.0, np.zeros(1)
        out[name] = {"decrease": dec, "fraction": dec / sse if sse > 0 else 0.0, "df": int(Je.shape[1]),
                     "step": step.tolist()}
    return out


def rank_screen(scr: dict[str, dict], names) -> dict[str, dict]:
    """Rank the screened candidates ``names`` by their fraction (``rank`` 1 = first), after
    crediting per-frame time jitter only with what it explains beyond its placebo (``placebo_jitter``
    in ``scr``: per-frame freedom explains some residual whatever its cause). Modifies and returns
    ``scr``."""
    if "time_jitter" in scr:
        scr["time_jitter"]["fraction_raw"] = scr["time_jitter"]["fraction"]
        scr["time_jitter"]["fraction"] -= scr["placebo_jitter"]["fraction"]
    for i, c in enumerate(sorted(names, key=lambda c: -scr[c]["fraction"])):
        scr[c]["rank"] = i + 1
    return scr


def _free_pose_gap(model: RigidGapModel, obs: np.ndarray, roi: np.ndarray, theta: np.ndarray,
                   frames: np.ndarray) -> np.ndarray:
    """(F,) per-frame mismatch after fitting each frame's pose on its own (6 free numbers)."""
    X, Q, ok = model.poses(theta, model.capture_times(theta)[frames])
    out = np.zeros(len(frames))
    cam = model.cam
    corners = model.corners
    depth = max(float(np.median((X @ cam.R.T + cam.t)[:, 2])), 0.1) if ok else 1.0
    sx = 0.5 * depth / cam.K[0, 0]
    sr = sx / max(np.linalg.norm(corners.reshape(-1, 3), axis=1).max(), 1e-3)
    for i, k in enumerate(frames):
        A = obs[k]
        m = roi[k]

        def res(x: np.ndarray, X0=X[i], Q0=Q[i], A=A, m=m) -> np.ndarray:
            Xp = X0 + x[0:3] * sx
            Qp = quat_mul(Q0, quat_exp(x[3:6] * sr))
            a = render_coverage(Xp[None], Qp[None], corners, cam, model.ramp)[0]
            return (a - A)[m]

        sol = least_squares(res, np.zeros(6), method="trf", diff_step=0.5, max_nfev=40)
        out[i] = np.abs(res(sol.x)).sum() / model.scale ** 2
    return out


def across_motion(model: RigidGapModel, theta: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """(F, 3) world offsets, per second of time error: the body's velocity at each frame's capture
    time turned by 90 degrees in the image plane (camera x, y; the camera's depth component
    dropped), so that an offset of ``dt`` times this moves the body across its image motion by
    about as far as a time error ``dt`` moves it along. The time-jitter placebo's direction."""
    tc = model.capture_times(theta)[np.asarray(frames, int)]
    X, _, _ = model.poses(theta, tc)
    Xp, _, _ = model.poses(theta, tc + 1e-4)
    Vc = (Xp - X) / 1e-4 @ model.cam.R.T
    return np.nan_to_num(np.stack([-Vc[:, 1], Vc[:, 0], np.zeros(len(Vc))], 1) @ model.cam.R)


def jitter_search_bound(errors: np.ndarray, train: np.ndarray) -> float:
    """Bound of a held-out frame's own time error (and of the placebo's equal shift): four
    standard deviations of the training frames' fitted errors, at least 0.5 ms."""
    return max(4.0 * float(np.std(np.asarray(errors, float)[np.asarray(train, int)])), 5e-4)


def beats_placebo(heldout_after: float, placebo_after: float, heldout_before: float, floor: float,
                  min_closure: float) -> bool:
    """The held-out half of the time-jitter rule (both domains): per-frame time errors, each fitted
    on its own held-out frame, must leave less than the same one-number fit of the placebo by
    ``min_closure`` of the held-out excess ``heldout_before - floor``. A placebo left worse than
    the model before jitter counts as that model (no credit for beating a placebo that starts
    from images the jitter refit broke)."""
    return bool(min(placebo_after, heldout_before) - heldout_after >= min_closure * (heldout_before - floor))


def pick_supported(results: dict[str, dict]) -> str | None:
    """Which supported candidate to name at a forward-selection step (both domains): the one that
    leaves the least held-out gap (``heldout_after_px``), or None when none is supported.

    Every candidate is compared on the held-out frames, time jitter included (its held-out gap
    has each held-out frame's own time error fitted on that frame, an optimistic figure for it).
    Until 5 Dec 2026 (session 37) the pick was the largest ``closure_of_remaining``, which for jitter is a
    *training* closure: 16 free time errors closing 0.88 of the training excess beat a time
    offset that closed 0.74 of the held-out excess although jitter left the larger held-out gap
    (69 against 55 px; docs/gap.md, "Comparing like with like")."""
    best, best_after = None, np.inf
    for c, res in results.items():
        if res.get("supported") and float(res["heldout_after_px"]) < best_after:
            best, best_after = c, float(res["heldout_after_px"])
    return best


def heldout_comparison(results: dict[str, dict], best: str, heldout: np.ndarray) -> dict[str, dict]:
    """Per other supported candidate of a selection step: its per-frame held-out gap minus
    ``best``'s (``gap_per_frame_after_px`` on the frames ``heldout``), as the mean, its standard
    error and the frame count (``{c: {"mean_diff_px", "se_px", "n"}}``; candidates whose difference
    is not finite are left out)."""
    g0 = np.asarray(results[best]["gap_per_frame_after_px"], float)[heldout]
    out = {}
    for c, res in results.items():
        if c == best or not res.get("supported"):
            continue
        d = np.asarray(res["gap_per_frame_after_px"], float)[heldout] - g0
        if d.size < 2 or not np.all(np.isfinite(d)):
            continue
        out[c] = {"mean_diff_px": float(d.mean()), "se_px": float(np.std(d, ddof=1)) / float(np.sqrt(d.size)),
                  "n": int(d.size)}
    return out


def as_good_on_heldout(results: dict[str, dict], best: str, heldout: np.ndarray,
                       level: float = 0.975) -> list[str] | None:
    """The other supported candidates of a selection step that the held-out frames cannot tell from
    ``best`` (both domains): those whose per-frame held-out gap does not exceed ``best``'s by more
    than Student's t quantile ``level`` (n - 1 degrees of freedom) times the standard error of the
    mean paired difference (:func:`heldout_comparison`). A named effect with such alternatives is
    reported as undecided between them. None (not tested) when fewer than 2 frames are held out.

    Caveats: the frames are treated as independent (consecutive held-out frames' differences are
    correlated, lag-1 autocorrelation 0.55 in the rigid angular-drag case, so the standard error is
    understated and the test leans towards "decided"); there is no minimum effect size; time
    jitter's held-out gaps have each frame's own time fitted on it (optimistic for jitter); a stated
    alias of ``best`` is listed like any other candidate.

    Measured (5 Dec 2026): near a swatch's gripped corners, which sit on nearly the same image rows,
    a rolling shutter acts as a time offset; in the cloth suite's time-offset case the offset left
    about 4-5 px per frame less than the shutter on the 5 held-out frames with a standard error of
    about 5.7."""
    from scipy.stats import t as student_t

    heldout = np.asarray(heldout)
    if heldout.size < 2:
        return None
    cmp = heldout_comparison(results, best, heldout)
    return [c for c, v in cmp.items()
            if v["mean_diff_px"] <= float(student_t.ppf(level, v["n"] - 1)) * v["se_px"]]


def _fit_one_number(cost, bound: float, keep: float) -> float:
    """The minimiser of ``cost`` on [-bound, bound] by Brent's bounded search, or ``keep`` (the
    value before the fit) when that costs no more: the search can settle in a worse local minimum
    of a rough cost, and a fit of one number must never leave the frame's cost (the squared
    residual it minimises; the absolute-pixel gap reported is not guaranteed) worse than it found
    it."""
    from scipy.optimize import minimize_scalar

    sol = minimize_scalar(cost, bounds=(-bound, bound), method="bounded", options={"xatol": 1e-5})
    return float(keep) if cost(float(keep)) <= float(sol.fun) else float(sol.x)


def _heldout_time_fit(model: RigidGapModel, theta: np.ndarray, obs: np.ndarray, roi: np.ndarray,
                      test: np.ndarray, train: np.ndarray, placebo: bool = False) -> np.ndarray:
    """(F,) mismatch of each held-out frame after fitting its own time error alone (one number).

    For a model with per-frame time errors: a held-out frame's error is not identified by the
    refit (it never saw the frame), so it is fitted on the frame itself within four standard
    deviations of the training frames' fitted errors (at least 0.5 ms), every other parameter
    fixed. Full-resolution pixels.

    ``placebo``: fit the same one number per frame as a shift across the frame's image motion
    instead (perpendicular to the velocity in the image plane, as far as that time error would
    move the body along it: :meth:`Problem.placebo_jacobian`'s direction), the frame's time error
    left at the refit's. Equal count and size, no timing meaning: what a per-frame parameter
    gains on a held-out frame without being a time error. Each fit keeps the frame's value before
    it when the search finds nothing better (:func:`_fit_one_number`).
    """

    sl = model.slices["time_jitter"]
    theta = np.asarray(theta, float)
    bound = jitter_search_bound(theta[sl], train)
    out = np.zeros(len(test))
    n_c = across_motion(model, theta, test) if placebo else np.zeros((len(test), 3))
    for i, k in enumerate(test):
        def render(dt: float, i=i, k=k) -> tuple[np.ndarray, bool]:
            th = theta.copy()
            if placebo:
                return model.render(th, np.array([k]), dt * n_c[i][None])
            th[sl.start + k] = dt
            return model.render(th, np.array([k]))

        def cost(dt: float, k=k) -> float:
            a, ok = render(dt)
            return float(np.sum(((a[0] - obs[k]) * roi[k]) ** 2)) if ok else np.inf

        a, ok = render(_fit_one_number(cost, bound, 0.0 if placebo else theta[sl.start + k]))
        out[i] = float(np.abs(a[0] - obs[k])[roi[k]].sum() / model.scale ** 2) if ok else np.inf
    return out


# ----------------------------------------------------------------------------- where
def motion_phases(X: np.ndarray, cam: PinholeCamera, times: np.ndarray) -> dict[str, np.ndarray]:
    """Boolean masks (T,) of motion phases: fast/slow image speed (median split), start, end (thirds)."""
    uv = cam.project(X)
    sp = np.zeros(len(X))
    if len(X) > 1:
        v = np.gradient(uv, times, axis=0)
        sp = np.linalg.norm(v, axis=1)
    T = len(X)
    k = np.arange(T)
    return {"fast": sp > np.median(sp), "slow": sp <= np.median(sp), "start": k < T / 3,
            "middle": (k >= T / 3) & (k < 2 * T / 3), "end": k >= 2 * T / 3}


def face_attribution(model: RigidGapModel, theta: np.ndarray, obs: np.ndarray, frames: np.ndarray
                     ) -> dict[str, float]:
    """Mismatch pixels attributed to the body's parts and face directions through the rasteriser.

    A pixel the model covers but the footage does not is charged to the face drawn there; a pixel
    the footage covers but the model misses, to the face drawn at the nearest covered pixel.

    Returns:
        ``{"box<i>": px, "face<+x|-x|+y|-y|+z|-z>": px}`` summed over ``frames`` (full-res pixels).
    """
    from vidsim.render.raster import rasterize_batch
    from vidsim.rigid.dynamics import quat_to_rot

    V, F = model.body.mesh()
    X, Q, ok = model.poses(theta, model.capture_times(theta)[frames])
    out: dict[str, float] = {}
    if not ok:
        return out
    Vs = np.stack([V @ quat_to_rot(q).T + x for x, q in zip(X, Q)])
    _, face = rasterize_batch(Vs, F, model.cam)
    # face k of box b: 12 triangles per box in _BOX_FACES order: -z,-z,+z,+z,-y,-y,+y,+y,+x,+x,-x,-x
    dirs = ["-z", "-z", "+z", "+z", "-y", "-y", "+y", "+y", "+x", "+x", "-x", "-x"]
    for i, k in enumerate(frames):
        fmap = face[i]
        sim = fmap >= 0
        A = obs[k] > 0.5
        extra = sim & ~A
        missing = A & ~sim
        if sim.any() and missing.any():
            _, lab = cv2.distanceTransformWithLabels((~sim).astype(np.uint8), cv2.DIST_L2, 5,
                                                     labelType=cv2.DIST_LABEL_PIXEL)
            ys, xs_ = np.nonzero(sim)
            lut = np.full(lab.max() + 1, -1, np.int64)
            lut[lab[ys, xs_]] = fmap[ys, xs_]
            f_missing = lut[lab[missing]]
        else:
            f_missing = np.zeros(0, np.int64)
        for fid in np.concatenate([fmap[extra], f_missing]):
            if fid < 0:
                continue
            b, t = divmod(int(fid), 12)
            out[f"box{b}"] = out.get(f"box{b}", 0.0) + 1.0
            out[f"face{dirs[t]}"] = out.get(f"face{dirs[t]}", 0.0) + 1.0
    s = 1.0 / model.scale ** 2
    return {k: v * s for k, v in sorted(out.items())}


# ----------------------------------------------------------------------------- driver
@dataclass
class RigidDiagnosis:
    """Result of :func:`diagnose_rigid` (``to_dict`` is the diagnosis.json content)."""

    named: list[str]
    verdict: str
    frames: np.ndarray
    train: np.ndarray
    test: np.ndarray
    gap_per_frame: np.ndarray
    floor_test: np.ndarray
    screen: dict[str, dict]
    refits: dict[str, dict]
    where: dict
    heatmap: np.ndarray
    signed_heatmap: np.ndarray
    theta_base: np.ndarray
    seconds: float
    n_renders: int
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """Plain, JSON-friendly dictionary."""
        return {
            "verdict": self.verdict,
            "named": list(self.named),
            "frames": self.frames.tolist(),
            "train_frames": self.train.tolist(),
            "heldout_frames": self.test.tolist(),
            "gap_per_frame_px": self.gap_per_frame.tolist(),
            "noise_floor_heldout_px": float(self.floor_test.mean()),
            "noise_floor_per_frame_px": self.floor_test.tolist(),
            "screen": self.screen,
            "refits": self.refits,
            "where": self.where,
            "seconds": self.seconds,
            "n_renders": self.n_renders,
            **self.extra,
        }


def _white_fraction(t: np.ndarray, x: np.ndarray) -> float:
    """Fraction of the variance of ``x(t)`` that a cubic in time does not explain (white noise
    keeps ~(n - 4)/n of it, the smooth drift a missing force leaves keeps little)."""
    x = np.asarray(x, float) - np.mean(x)
    d = float(x @ x)
    if d <= 0 or len(x) < 8:
        return 0.0
    tt = (t - t.mean()) / max(np.ptp(t), 1e-9)
    A = np.vander(tt, 4)
    res = x - A @ np.linalg.lstsq(A, x, rcond=None)[0]
    return float(res @ res / d)


def _lag1(x: np.ndarray) -> float:
    x = np.asarray(x, float) - np.mean(x)
    d = float(x @ x)
    return float(x[1:] @ x[:-1] / d) if d > 0 and len(x) > 2 else 1.0


def blur_threshold_refit(prob, theta0: np.ndarray, refit_fn, thresholds) -> tuple[np.ndarray, dict]:
    """``refit_fn(prob, theta0)`` once per segmentation threshold when the model has motion blur
    (else, or with no thresholds, once with the model's own); the lowest training cost wins, its
    threshold is left on the model and returned in ``info["blur_threshold"]``. The threshold is
    set by the footage's segmentation and contrast, which the diagnosis does not see, so it is
    chosen on the training frames."""
    m = prob.model
    if "motion_blur" not in m.slices or not thresholds:
        th, info = refit_fn(prob, theta0)
        return th, {**info, "blur_threshold": getattr(m, "blur_threshold", None)}
    best = None
    for c in thresholds:
        m.blur_threshold = float(c)
        th, info = refit_fn(prob, theta0)
        if best is None or info["cost"] < best[1]["cost"]:
            best = (th, {**info, "blur_threshold": float(c)})
    m.blur_threshold = best[1]["blur_threshold"]
    return best


def joint_pair_search(pool: list[str], singles: dict[str, dict], judge, supported, cfg, note, floor: float,
                      library=None) -> tuple[list[str], dict | None, dict[str, dict]]:
    """Joint refits of every pair of ``pool`` (time jitter and stated aliases excluded: jitter is
    judged on training frames, an alias pair is one effect twice). A pair is named when it passes
    the single-effect rule (``supported``) as a whole and its held-out closure exceeds each
    member's own by ``pair_min_gain``; of several, the one that closes most. Returns (named, in
    the order of their single closures, largest first; the pair's refit, also stored in ``singles``
    under ``"first+second"`` with the second's share of what the first alone left (the suite's
    scoring and the figures read it there), or None; every pair's refit). ``floor``: the held-out
    noise floor; ``library``: the effect specifications (aliases), :data:`RIGID_EFFECTS` by default."""
    lib = RIGID_EFFECTS if library is None else library
    out: dict[str, dict] = {}
    best, best_c, best_key = [], -np.inf, ""
    for i, a in enumerate(pool):
        for b in pool[i + 1:]:
            if "time_jitter" in (a, b) or a in lib[b].alias or b in lib[a].alias or a not in singles \
                    or b not in singles:
                continue
            res = judge((a, b))
            c_pair = res["heldout_closure"]
            c_a, c_b = (singles[e]["heldout_closure"] for e in (a, b))
            res["single_closures"] = {a: c_a, b: c_b}
            res["supported"] = ok = bool(supported(res, b, None)
                                         and c_pair - max(c_a, c_b) >= cfg.pair_min_gain)
            out[f"{a}+{b}"] = res
            note(f"joint refit {a}+{b}")
            if ok and c_pair > best_c:
                best, best_c, best_key = sorted((a, b), key=lambda e: -res["single_closures"][e]), c_pair, f"{a}+{b}"
    if not best:
        return [], None, out
    prev = dict(out[best_key])
    ho1 = singles[best[0]]["heldout_after_px"]
    # None, as in the forward selection's strength, when the first effect left no excess above the
    # naming margin (a fraction of nothing)
    prev["closure_of_remaining"] = ((ho1 - prev["heldout_after_px"]) / (ho1 - floor)
                                    if ho1 - floor > cfg.min_excess * floor else None)
    prev["named_jointly"] = True
    singles["+".join(best)] = prev
    return best, prev, out


def forward_select(ranked: list[str], cands: list[str], judge, supported, strength, gap_left, run_screen, cfg, note,
                   heldout: np.ndarray, library=None, polish=None
                   ) -> tuple[list[str], dict | None, dict[str, dict], dict[str, dict]]:
    """Forward selection (both domains): refit the ``cfg.top_k`` screened candidates one at a time
    and name the supported one that leaves the least held-out gap (:func:`pick_supported`); then,
    with ``cfg.pairs`` and while a gap beyond the floor remains, screen the other candidates again
    with the named effect in the model (a conditional score test) and refit the ``top_k`` of them
    together with it, judged by the same rule on what the named one left.

    Args:
        ranked: the candidates, best screened first.
        cands: every candidate (the conditional screen takes those not named and no stated alias
            of a named one, in this order).
        judge: ``judge(effects, start)``: the refit of the base with ``effects`` from ``start``
            (None: the base refit), a result dictionary.
        supported: ``supported(res, added, prev)``: the refit's ``"supported"`` entry (the whole
            rule, a gap present included), ``prev`` the refit of the effects named before
            ``added`` (None: the base model).
        strength: ``strength(res, added, prev)``: its ``"closure_of_remaining"`` entry.
        gap_left: ``gap_left(prev)``: whether what the named effects left is worth a second step.
        run_screen: ``run_screen(current, theta_cur, names, blur_threshold)``: the ranked
            conditional screen of ``names`` at ``theta_cur`` with ``current`` in the model.
        cfg: reads ``top_k`` and ``pairs``.
        note: ``note(text)`` after each conditional screen and refit.
        heldout: the held-out frames the named refit is compared on with the other supported
            candidates of its step (:func:`as_good_on_heldout`, :func:`heldout_comparison`,
            stored in the named refit under those names).
        library: the effect specifications (aliases), :data:`RIGID_EFFECTS` by default.
        polish: optional ``polish(effects, res, prev)``: a named refit continued from where it
            stopped, which replaces it (not one named jointly); the comparison is made before it
            (the other candidates had the same budget).

    Returns:
        (the named effects; the refit that named the last of them, or None; every refit by its
        effects joined with "+"; the conditional screens by ``"after a"``).
    """
    lib = RIGID_EFFECTS if library is None else library
    refits: dict[str, dict] = {}
    conditional: dict[str, dict] = {}
    named: list[str] = []
    prev: dict | None = None
    for step in range(2 if cfg.pairs else 1):
        if step == 0:
            pool = ranked
        else:
            rest = [c for c in cands if c not in named
                    and not any(c in lib[k].alias or k in lib[c].alias for k in named)]
            if not rest or not gap_left(prev):
                break
            scr = run_screen(tuple(named), np.asarray(prev["theta"]), rest,
                             prev["params"].get("motion_blur", {}).get("segmentation_threshold"))
            pool = sorted(rest, key=lambda c: scr[c]["rank"])
            note("conditional screen")
            conditional[f"after {'+'.join(named)}"] = {c: scr[c] for c in pool}
        step_res: dict[str, dict] = {}
        for c in pool[: cfg.top_k]:
            effs = tuple(named) + (c,)
            res = judge(effs, None if prev is None else np.asarray(prev["theta"]))
            res["supported"] = supported(res, c, prev)
            res["closure_of_remaining"] = strength(res, c, prev)
            refits["+".join(effs)] = step_res[c] = res
            note(f"refit {'+'.join(effs)}")
        best = pick_supported(step_res)
        if best is None:
            break
        before = prev
        named.append(best)
        prev = refits["+".join(named)]
        # compared before any polish (the other candidates had the same budget); a polish keeps the
        # unpolished per-frame gaps, so the comparison can be checked
        alike, cmp = as_good_on_heldout(step_res, best, heldout), heldout_comparison(step_res, best, heldout)
        if polish is not None and not prev.get("named_jointly"):
            prev = polish(tuple(named), prev, before)
            refits["+".join(named)] = prev
        prev["as_good_on_heldout"], prev["heldout_comparison"] = alike, cmp
    return named, prev, refits, conditional


def diagnose_rigid(masks: np.ndarray, times: np.ndarray, cam: PinholeCamera, body: BoxBody, fit: dict,
                   cfg: DiagnoseConfig | None = None, progress=None,
                   checkpoint: str | os.PathLike | None = None) -> RigidDiagnosis:
    """Diagnose the gap between a rigid fit and its footage (blind: no truth).

    Args:
        masks: (N, H, W) bool silhouettes of the clip (background frames allowed).
        times: (N,) frame times, seconds.
        cam: the calibrated camera (full resolution).
        body: the known body.
        fit: the fit's summary (``position, quaternion, velocity, omega_world, tilt, roll, t0``).
        cfg: settings.
        progress: optional callable ``progress(note)`` called after each step.
        checkpoint: a folder where each finished step (base refit, noise floor, screens, each
            candidate's refit) is kept (:class:`vidsim.optim.cache.StepMemo`, keyed by a
            fingerprint of the inputs, the settings and the source): a killed diagnosis rerun with
            the same folder replays its finished steps, with the same result. None: no checkpoint.

    Returns:
        :class:`RigidDiagnosis`.
    """
    t_start = time.perf_counter()
    cfg = cfg or DiagnoseConfig()
    cfg.validate()
    masks = np.asarray(masks, bool)
    times = np.asarray(times, float)
    if masks.ndim != 3 or masks.shape[0] != times.shape[0]:
        raise GapError(f"masks must be (N, H, W) with N = len(times); got {masks.shape} and {times.shape}")
    if masks.shape[1:] != (cam.height, cam.width):
        raise GapError(f"masks are {masks.shape[2]}x{masks.shape[1]} but the camera is {cam.width}x{cam.height}")
    for k in ("position", "quaternion", "velocity", "omega_world", "tilt", "roll", "t0"):
        if k not in fit:
            raise GapError(f"fit: missing field {k!r} (expected the summary of a rigid fit)")
    note = progress or (lambda s: None)
    frames = visible_frames(masks)
    if len(frames) < 8:
        raise GapError(f"masks: the object is visible in only {len(frames)} consecutive frames (need >= 8)")
    T = len(frames)
    if cfg.split == "end":
        n_test = max(3, int(round(cfg.holdout * T)))
        train = np.arange(T - n_test)
        test = np.arange(T - n_test, T)
    else:  # interleaved: every k-th frame, never the first or last, is held out
        k_step = max(2, int(round(1.0 / cfg.holdout)))
        is_test = (np.arange(T) % k_step == k_step // 2) & (np.arange(T) > 0) & (np.arange(T) < T - 1)
        test = np.flatnonzero(is_test)
        train = np.flatnonzero(~is_test)
    ft = times[frames]
    p0 = np.r_[fit["position"], [0, 0, 0], fit["velocity"], fit["omega_world"], fit["tilt"], fit["roll"]].astype(float)
    qb = np.asarray(fit["quaternion"], float)
    t0 = float(fit["t0"])
    # the fit's own gravity magnitude (fit.yaml: gravity_magnitude, the footage's meta): a base model
    # with another one would start with a mismatch that gravity_scale or time_rate could be named for
    g_fit = float(fit.get("gravity_magnitude", G_EARTH))
    if not (np.isfinite(g_fit) and g_fit > 0):
        raise GapError(f"fit: gravity_magnitude {g_fit!r} must be a finite magnitude > 0 m/s^2")
    hmax = 1.0 / 120.0  # the gap model's own step bound (RigidGapModel's default), finer than the fit's
    base = RigidGapModel(body, cam, ft, t0, qb, (), cfg.scale, cfg.ramp, hmax, g_fit)
    obs, roi = residual_region(base, masks[frames], p0, cfg.roi_px)

    def problem(effects: tuple[str, ...], fr: np.ndarray) -> Problem:
        return Problem(RigidGapModel(body, cam, ft, t0, qb, effects, cfg.scale, cfg.ramp, hmax, g_fit), obs, roi, fr)

    # every costly step below is a pure function of the inputs: kept as it finishes, replayed on resume
    memo = StepMemo(checkpoint, fingerprint("rigid diagnosis", masks, times, cam, body, fit, cfg,
                                            vidsim.SOURCE_DIGEST) if checkpoint is not None else "")
    n_renders = 0
    # 2. base refit on training frames
    pb = problem((), train)

    def base_refit():
        th, _ = refit(pb, p0, cfg.max_nfev)
        return th, pb.n_evals, pb.gap_per_frame(th, np.arange(T))

    theta_b, n_base, gap_all = memo("base", (), base_refit)
    n_renders += n_base
    note("base refit")
    before = float(gap_all[test].mean())
    # 3. floor
    floor, floor_train = memo("floor", (), lambda: (
        _free_pose_gap(base, obs, roi, theta_b, test),
        _free_pose_gap(base, obs, roi, theta_b, train[:: max(1, len(train) // 8)])))
    note("noise floor")
    # 4. screen: score test on all frames at the base refit (interleaved training frames make it
    # nearly the all-frame optimum; the base parameters are projected out to first order)
    cands = [c for c in cfg.candidates]
    allf = np.arange(T)
    floor_mean = float(floor.mean())
    floor_train_mean = float(floor_train.mean())

    def run_screen(current: tuple[str, ...], theta_cur: np.ndarray, names: list[str],
                   blur_threshold: float | None = None) -> dict[str, dict]:
        """Score test of each of ``names`` at ``theta_cur`` (base + the ``current`` effects, whose
        parameters are projected out with the base's), all frames, ranked best first
        (``blur_threshold``: the segmentation threshold ``theta_cur`` was fitted with)."""
        nonlocal n_renders

        def compute():
            pall = problem(tuple(current) + tuple(names), allf)
            if blur_threshold is not None:
                pall.model.blur_threshold = blur_threshold
            theta_ext = np.r_[theta_cur, np.zeros(pall.model.n_params - len(theta_cur))]
            Jall = pall.jacobian(theta_ext) * pall.model.x_scale()
            r = pall.residual(theta_ext)
            k_base = len(theta_cur)
            blocks = {c: Jall[:, pall.model.slices[c]] for c in names}
            one_sided = {c: RIGID_EFFECTS[c].lower is not None for c in names}
            if "time_jitter" in blocks:
                blocks["placebo_jitter"] = pall.placebo_jacobian(theta_ext) * RIGID_EFFECTS["time_jitter"].scale
            return rank_screen(score_screen(Jall[:, :k_base], blocks, r, one_sided), names), pall.n_evals

        ranked_screen, n = memo("screen", (list(current), np.asarray(theta_cur, float), list(names), blur_threshold),
                                compute)
        n_renders += n
        return ranked_screen

    screen = run_screen((), theta_b, cands)
    ranked = sorted(cands, key=lambda c: screen[c]["rank"])
    note("screen")
    excess = before - floor_mean
    gap_present = excess > cfg.min_excess * floor_mean
    tr_before = float(gap_all[train].mean())

    def judge(effects: tuple[str, ...], start: np.ndarray | None = None) -> dict:
        """Refit the base with ``effects`` on the training frames (from ``start``: theta_b and
        zeros by default); held-out gap after, closures, parameters and intervals."""
        nonlocal n_renders
        th0 = theta_b if start is None else start
        res, n = memo("judge", (list(effects), np.asarray(th0, float)), lambda: _judge(effects, th0))
        n_renders += n
        return res

    def _judge(effects: tuple[str, ...], th0: np.ndarray) -> tuple[dict, int]:
        pe = problem(effects, train)
        th0 = np.r_[th0, np.zeros(pe.model.n_params - len(th0))]
        th, info = blur_threshold_refit(pe, th0, lambda p, t: refit(p, t, cfg.max_nfev), cfg.blur_thresholds)
        g = pe.gap_per_frame(th, np.arange(T))
        if "time_jitter" in effects:
            # the model claims every frame its own time error, and a held-out frame's is not in
            # the refit: fit that one number on the frame itself (the floor frees six) so that
            # other effects in the model are judged on held-out frames at their right times
            g[test] = _heldout_time_fit(pe.model, th, obs, roi, test, train)
            # the same one number per held-out frame as a shift across its motion (the placebo):
            # jitter must beat it on frames the refit did not see (see ``supported``)
            placebo_after = float(_heldout_time_fit(pe.model, th, obs, roi, test, train, placebo=True).mean())
        after = float(g[test].mean())
        tr_after = float(g[train].mean())
        res = {"effects": list(effects), "heldout_before_px": before, "heldout_after_px": after,
               "heldout_closure": (before - after) / excess if excess > 0 else 0.0,
               "train_before_px": tr_before, "train_after_px": tr_after,
               "train_closure": ((tr_before - tr_after)
                                 / max(tr_before - floor_train_mean, 0.05 * floor_train_mean)),
               "heldout_times_fitted": "time_jitter" in effects,
               "gap_per_frame_after_px": g.tolist(), "params": {}, "theta": th.tolist()}
        if "time_jitter" in effects:
            res["heldout_placebo_after_px"] = placebo_after
        sd = np.sqrt(np.clip(np.diag(info["cov"]), 0, None))
        for e in effects:
            sl = pe.model.slices[e]
            v = th[sl]
            if e == "time_jitter":
                vt = v[train]
                res["params"][e] = {"std_s": float(np.std(vt)), "lag1_autocorr": _lag1(vt),
                                    "white_fraction": _white_fraction(ft[train], vt),
                                    "values_s": v.tolist()}
            else:
                res["params"][e] = {"value": v.tolist(), "ci95": [(v - 1.96 * sd[sl]).tolist(),
                                                                   (v + 1.96 * sd[sl]).tolist()],
                                    "units": RIGID_EFFECTS[e].units}
        if "motion_blur" in effects:
            res["params"]["motion_blur"]["segmentation_threshold"] = info["blur_threshold"]
        return res, pe.n_evals

    def supported(res: dict, added: str, prev: dict | None) -> bool:
        """The named-effect rule, relative to the model before ``added`` was added (``prev``:
        None for the base model): the held-out gap must still exceed the floor by min_excess,
        and ``added`` must close min_closure of that remaining held-out excess; time jitter,
        whose held-out values are not identified, must close half the remaining training excess
        with white time errors instead, and on the held-out frames, each with its own time error
        fitted on itself, it must beat the same fit of a per-frame placebo (a shift across the
        motion, :func:`_heldout_time_fit`) by ``min_closure`` of the held-out excess (since
        5 Dec 2026, session 35: before, jitter's held-out gap was fitted on the held-out frames
        with nothing to compare it with, so an overfitting per-frame parameter passed there)."""
        ho0 = before if prev is None else prev["heldout_after_px"]
        tr0 = tr_before if prev is None else prev["train_after_px"]
        if ho0 - floor_mean <= cfg.min_excess * floor_mean:
            return False
        if added == "time_jitter":
            tr_clos = (tr0 - res["train_after_px"]) / max(tr0 - floor_train_mean, 0.05 * floor_train_mean)
            return bool(tr_clos >= 0.5 and res["params"][added]["white_fraction"] >= cfg.jitter_min_white
                        and beats_placebo(res["heldout_after_px"], res["heldout_placebo_after_px"], ho0, floor_mean,
                                          cfg.min_closure))
        return bool((ho0 - res["heldout_after_px"]) / (ho0 - floor_mean) >= cfg.min_closure)

    def strength(res: dict, c: str, prev: dict | None) -> float | None:
        """How much ``c`` closes of what the model before it left (held-out; training for jitter);
        None when that left no held-out excess above the naming margin (a fraction of nothing:
        dividing by a vanishing excess had reported closures of +-1e7)."""
        if c == "time_jitter":
            tr0 = tr_before if prev is None else prev["train_after_px"]
            return (tr0 - res["train_after_px"]) / max(tr0 - floor_train_mean, 0.05 * floor_train_mean)
        ho0 = before if prev is None else prev["heldout_after_px"]
        if ho0 - floor_mean <= cfg.min_excess * floor_mean:
            return None
        return (ho0 - res["heldout_after_px"]) / (ho0 - floor_mean)

    def supported_gap(prev: dict) -> bool:
        return prev["heldout_after_px"] - floor_mean > cfg.min_excess * floor_mean

    # 5. forward selection (forward_select, shared with the cloth diagnosis): refit the top_k
    # screened candidates one at a time and name the supported one that leaves the least held-out
    # gap; then, while a gap beyond the floor remains, screen again with the named effects in the
    # model (a conditional score test) and refit the top_k of the rest together with them, judged
    # by the same rule on what the named ones left
    named, prev, refits, conditional = forward_select(
        ranked, cands, judge, lambda res, c, p: gap_present and supported(res, c, p), strength, supported_gap,
        run_screen, cfg, note, test)
    joint: dict[str, dict] = {}
    if not named and gap_present and cfg.pairs and cfg.joint_pairs:
        named, prev, joint = joint_pair_search(ranked[: cfg.top_k], refits, judge, supported, cfg, note, floor_mean)
    verdict = ("no gap beyond the noise floor" if not gap_present else
               ("explained by " + ", ".join(named)) if named else "none of the candidates explains the gap")
    # where
    X, _, _ = base.poses(theta_b, base.capture_times(theta_b))
    phases = motion_phases(X, cam, ft)
    rimg, _ = problem((), np.arange(T)).residual_images(theta_b)
    where = {
        "per_phase_px": {k: float(gap_all[v].mean()) if v.any() else None for k, v in phases.items()},
        "per_part_px": face_attribution(base, theta_b, obs, np.arange(T)),
        "split_heldout_px": {"total": before, "rendering_and_noise (floor)": float(floor.mean()),
                             "dynamics": max(excess, 0.0)},
        "extra_vs_missing_px": {"model_covers_footage_not": float(np.clip(rimg, 0, None).sum() / cfg.scale ** 2 / T),
                                "footage_covers_model_not": float(np.clip(-rimg, 0, None).sum() / cfg.scale ** 2 / T)},
    }
    return RigidDiagnosis(named, verdict, frames, train, test, gap_all, floor, screen, refits, where,
                          np.abs(rimg).sum(0), rimg.sum(0), theta_b, time.perf_counter() - t_start, n_renders,
                          {"gap_present": bool(gap_present), "heldout_excess_px": excess,
                           "base_params": theta_b.tolist(), "conditional_screens": conditional,
                           "joint_pairs": joint})
