"""Posterior of a thrown rigid body's initial state and gravity direction from its silhouettes.

Parameters (14, the fit's own vector, :data:`vidsim.rigid.dynamics.PARAM_NAMES`): initial position
``x y z`` (m), a rotation vector ``rx ry rz`` (rad, body axes) applied to the fitted orientation,
initial velocity ``vx vy vz`` (m/s), initial angular velocity in world axes ``wx wy wz`` (rad/s)
and the gravity angles ``tilt roll`` (rad). Reports show the angles in degrees.

Likelihood. The data are the per-frame silhouette mismatches ``E_k(theta)`` (seed eq. 3, full
resolution pixels, the fit's own metric without its distance term). Silhouette pixels are not
independent measurements: the mismatch lives on a thin band along the outline and neighbouring
pixels move together, so a per-pixel Gaussian (model ``iid_pixel``, kept for comparison) is wildly
overconfident. We use a generalised (loss-based) posterior

    p(theta | footage) ∝ prior(theta) exp(-w (L(theta) - L*)),   L = sum_k E_k,

whose learning rate ``w`` (1/pixel) comes from the footage at the optimum: frames are the
independent units (sensor noise and segmentation errors are independent between frames), so the
sampling covariance of the minimiser is the sandwich ``H^-1 J H^-1`` with ``H`` the Hessian of
``L`` and ``J = sum_k g_k g_k^T`` the spread of the per-frame scores ``g_k = dE_k/dtheta`` at
the optimum. ``w = D / tr(J H^-1)`` matches the posterior's covariance ``(w H)^-1`` to it (the
"magnitude adjustment" of composite likelihoods; exact when ``J ∝ H``, as for a true likelihood).
``H`` and ``g_k`` are read from per-frame quadratic response surfaces fitted on a random local
design around the optimum (the mismatch is only piecewise smooth at the pixel scale, so the
surface, refitted at the posterior's own scale, is more reliable than pointwise derivatives).

Model discrepancy (``sandwich_hac``, ``sandwich_holdout``): when the model lacks an effect of reality (air drag), the
per-frame scores are no longer independent but drift smoothly over the throw. A Newey-West
(Bartlett kernel) long-run covariance of the scores over a lag window of ``hac_bandwidth`` frames
replaces ``J``, which widens the posterior by what the temporally structured misfit implies.
``sandwich_holdout`` compares the modes of the first and second half of the frames (held out from
each other) and inflates the posterior variance by their chi-square disagreement per parameter.

Structured discrepancy (``discrepancy: [quadratic_drag]``): the effects of the gap library
(:mod:`vidsim.gap.rigid_model`, zero = off) named there are sampled with the 14 parameters as
nuisance parameters, with a uniform prior on ``[0, upper]`` (:data:`DISCREPANCY_UPPER`), so that a
missing force is absorbed by its own coefficient instead of by the initial state. The mode is first
refitted with the nuisance free (the gap package's least-squares refit, from the drag-free fit),
then the noise scale is calibrated in the extended space as above; the reported intervals of the 14
parameters are marginal over the nuisance.

Multimodality: a distinct alternative solution of the fit (e.g. the flipped orientation) whose
posterior density is within ``multimodal_ratio`` of the mode, or walkers whose orientations split
by more than ``distinct_deg``, raise the ``multimodal`` flag.
"""

from __future__ import annotations

import time
from pathlib import Path
from dataclasses import dataclass, field

import numpy as np

from vidsim.gap.rigid_diagnose import Problem, refit, residual_region
from vidsim.gap.rigid_model import RIGID_EFFECTS, RigidGapModel
from vidsim.posterior.sampler import Chain, PosteriorError, SamplerConfig, correlation, sample, summarize
from vidsim.rigid.body import BoxBody
from vidsim.rigid.dynamics import (G_EARTH, N_PARAM, PARAM_NAMES, quat_exp, quat_mul, quat_to_rot, rot_to_rotvec,
                                   simulate)
from vidsim.rigid.fit import SilhouetteObjective, orientation_error_deg
from vidsim.rigid.silhouette import sequence_costs
from vidsim.video.camera import PinholeCamera

ANGLE_IDX = (3, 4, 5, 12, 13)
"""Indices of the angular parameters (reported in degrees)."""

UNITS = ("m",) * 3 + ("deg",) * 3 + ("m/s",) * 3 + ("rad/s",) * 3 + ("deg",) * 2
"""Units of the reported (natural) parameters, in :data:`PARAM_NAMES` order."""

DESIGN_SCALE0 = np.array([0.002] * 3 + [0.005] * 3 + [0.01] * 3 + [0.05] * 3 + [0.002] * 2)
"""First local-design step per parameter (m, rad, m/s, rad/s, rad), refined to the posterior's scale."""

NOISE_MODELS = ("sandwich", "sandwich_hac", "sandwich_holdout", "iid_pixel")

DISCREPANCY_UPPER: dict[str, float] = {"quadratic_drag": 5.0, "linear_drag": 1.0, "angular_drag": 1.0}
"""Effects that may be sampled as nuisance parameters and the upper end of their uniform prior
(the lower end is 0: the effect off). ``quadratic_drag`` c2 = rho C / 2 (kg/m^3): air at 1.2 kg/m^3
and a face-pressure coefficient C <= 8, four or more times a bluff body's (~1-2; the bound leaves room
for the benchmark's reality with 3 x physical air drag, whose fitted c2 is ~2); ``linear_drag``
c1 (1/s): a speed decay of at most 1/e per second (far above air on a hand-sized body);
``angular_drag`` k (1/s): spin decaying by at most 1/e per second."""

DISCREPANCY_DESIGN0 = {"quadratic_drag": 0.02, "linear_drag": 0.005, "angular_drag": 0.005}
"""First local-design step of each nuisance parameter (its units), as :data:`DESIGN_SCALE0`."""


@dataclass
class RigidPriorConfig:
    """Uniform prior box.

    Attributes:
        position_m: half-width around the fitted initial position, metres.
        rotation_deg: largest rotation away from the fitted orientation, degrees.
        velocity_mps: half-width around the fitted velocity, m/s.
        omega_radps: half-width around the fitted angular velocity, rad/s.
        gravity_deg: largest |tilt| and |roll| of gravity (absolute, from the camera's mounting), degrees.
    """

    position_m: float = 0.5
    rotation_deg: float = 45.0
    velocity_mps: float = 2.0
    omega_radps: float = 5.0
    gravity_deg: float = 20.0

    def validate(self) -> None:
        for k, v in vars(self).items():
            if not (np.isfinite(v) and v > 0):
                raise PosteriorError(f"prior.{k} = {v}: must be a finite half-width > 0")


@dataclass
class NoiseConfig:
    """Noise model of the silhouette likelihood.

    Attributes:
        model: ``sandwich`` (frames independent), ``sandwich_holdout`` (discrepancy-aware: variance
            inflated by the disagreement of the two halves of the throw), ``sandwich_hac`` (scores
            correlated over ``hac_bandwidth`` frames) or ``iid_pixel`` (every pixel independent;
            overconfident, for comparison).
        n_design: local-design evaluations per refinement (quadratic surfaces need > 120).
        design_iters: refinements of the design scale to the posterior's width.
        design_width: design standard deviation in posterior standard deviations.
        hac_bandwidth: Newey-West lag window, frames (0: ``T / 4``).
        holdout_blocks: consecutive blocks compared by ``sandwich_holdout`` (2: the two halves;
            :func:`holdout_inflation`).
        holdout_confidence: 0: the inflation is the point estimate ``chi2 / D``; c in (0, 1): its
            upper c-confidence bound (:func:`holdout_inflation`).
    """

    model: str = "sandwich"
    n_design: int = 400
    design_iters: int = 2
    design_width: float = 1.5
    hac_bandwidth: int = 0
    holdout_blocks: int = 2
    holdout_confidence: float = 0.0

    def validate(self) -> None:
        if self.model not in NOISE_MODELS:
            raise PosteriorError(f"noise.model = {self.model!r}: expected one of {NOISE_MODELS}")
        if int(self.holdout_blocks) < 2:
            raise PosteriorError(f"noise.holdout_blocks = {self.holdout_blocks}: need >= 2 consecutive blocks")
        if not (0 <= float(self.holdout_confidence) < 1) or (self.holdout_confidence and int(self.holdout_blocks) != 2):
            raise PosteriorError(f"noise.holdout_confidence = {self.holdout_confidence}: need 0 (point estimate) or "
                                 "0 < c < 1 with holdout_blocks = 2")
        if self.n_design < 150:
            raise PosteriorError(f"noise.n_design = {self.n_design}: need >= 150 for 14-D quadratic surfaces")
        if self.design_iters < 1 or not (self.design_width > 0) or self.hac_bandwidth < 0:
            raise PosteriorError("noise: design_iters >= 1, design_width > 0 and hac_bandwidth >= 0 expected; got "
                                 f"{self.design_iters}, {self.design_width}, {self.hac_bandwidth}")


@dataclass
class DiscrepancyConfig:
    """Structured model discrepancy: gap-library effects sampled as nuisance parameters.

    Attributes:
        effects: names from :data:`DISCREPANCY_UPPER` (empty: none, the 14-parameter model).
        upper: prior upper bounds overriding :data:`DISCREPANCY_UPPER` (same names, effect units).
        refit_nfev: budget of the least-squares refit of the mode with the nuisance free.
        refit_scale: image scale of that refit (0.5: half resolution).
        signed: the prior is ``[-upper, upper]`` instead of ``[0, upper]``: the coefficient is then a
            discrepancy term, not a physical drag (negative values speed the body up), and a truth of
            0 is no longer on the prior's bound.
    """

    effects: tuple[str, ...] = ()
    upper: dict[str, float] = field(default_factory=dict)
    signed: bool = False
    refit_nfev: int = 15
    refit_scale: float = 0.5

    def validate(self) -> None:
        for e in self.effects:
            if e not in DISCREPANCY_UPPER:
                raise PosteriorError(f"discrepancy: unknown effect {e!r}; expected a subset of "
                                     f"{sorted(DISCREPANCY_UPPER)}")
        if len(set(self.effects)) != len(self.effects):
            raise PosteriorError(f"discrepancy: {list(self.effects)} names an effect twice")
        for k, v in self.upper.items():
            if k not in self.effects:
                raise PosteriorError(f"discrepancy_upper: {k!r} is not in discrepancy {list(self.effects)}")
            if not (np.isfinite(v) and v > 0):
                raise PosteriorError(f"discrepancy_upper.{k} = {v}: must be a finite bound > 0")
        if self.refit_nfev < 1 or not (0 < self.refit_scale <= 1):
            raise PosteriorError(f"discrepancy: refit_nfev >= 1 and 0 < refit_scale <= 1 expected; got "
                                 f"{self.refit_nfev}, {self.refit_scale}")

    def bounds(self) -> np.ndarray:
        """(n, 2) prior interval ``[0, upper]`` (``signed``: ``[-upper, upper]``) of each nuisance parameter."""
        up = [float(self.upper.get(e, DISCREPANCY_UPPER[e])) for e in self.effects]
        return np.array([[-u if self.signed else 0.0, u] for u in up]).reshape(-1, 2)


# ----------------------------------------------------------------------------- likelihood
class FrameLoss:
    """Per-frame silhouette mismatch (T,) of the fit's parameter vector (full resolution pixels).

    Args:
        body: the known body; cam: full-resolution camera.
        times: (T,) fitted frame times, s; masks: (T, H, W) bool observed silhouettes.
        t0: time of the initial state, s; q_base: (4,) base orientation of the parameters.
        hmax: RK4 step bound, s; gravity: known magnitude, m/s^2.
        effects: gap-library effects appended to the parameter vector (nuisance parameters, in
            this order, one per effect); empty: the 14-parameter free flight.
    """

    def __init__(self, body: BoxBody, cam: PinholeCamera, times: np.ndarray, masks: np.ndarray, t0: float,
                 q_base: np.ndarray, hmax: float = 1.0 / 60.0, gravity: float = G_EARTH,
                 effects: tuple[str, ...] = ()) -> None:
        self.gravity = float(gravity)
        self.obj = SilhouetteObjective(body, cam, times, masks, t0, 1.0, 0.0, 1.0, 20.0, hmax)
        self.q_base = np.asarray(q_base, float)
        self.n_pixels = int(np.asarray(masks).size)
        self.n_evals = 0
        self.effects = tuple(effects)
        self.model = (RigidGapModel(body, cam, self.obj.times, t0, self.q_base, self.effects, 1.0, 1.0, hmax, gravity)
                      if self.effects else None)
        if self.model is not None and self.model.n_params != N_PARAM + len(self.effects):
            raise PosteriorError(f"discrepancy effects {self.effects}: one parameter per effect expected")

    @property
    def n_frames(self) -> int:
        return len(self.obj.times)

    @property
    def n_params(self) -> int:
        """14 + the number of nuisance parameters."""
        return N_PARAM + len(self.effects)

    def trajectory(self, p: np.ndarray, q_base: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | None:
        """Positions (T, 3) and quaternions (T, 4) at the frame times, or None when the simulation fails."""
        o = self.obj
        qb = self.q_base if q_base is None else q_base
        p = np.asarray(p, float)
        if self.model is None:
            tr = simulate(p, qb, o.body.inertia, o.times, o.t0, o.hmax, sensitivities=False, g=self.gravity)
            if not tr.ok:
                return None
            return tr.states[:, 0:3], tr.states[:, 3:7]
        X, Q, ok = self.model.poses(p, o.times, qb)
        return (X, Q) if ok else None

    def __call__(self, p: np.ndarray, q_base: np.ndarray | None = None) -> np.ndarray | None:
        """(T,) mismatches in pixels, or None when the simulation fails / leaves the view."""
        o = self.obj
        self.n_evals += 1
        tq = self.trajectory(p, q_base)
        if tq is None:
            return None
        X, Q = tq
        if np.any((X @ o.cam.R.T + o.cam.t)[:, 2] < 0.05):
            return None
        c, _ = sequence_costs(X, Q, o.corners, o.cam, o.W, o.base, o.ramp, 0.5, False)
        return c if np.all(np.isfinite(c)) else None


def refit_discrepancy(masks: np.ndarray, loss: FrameLoss, p0: np.ndarray, cfg: DiscrepancyConfig,
                      roi_px: int = 6) -> np.ndarray:
    """Mode of the extended model: all parameters refitted with the nuisance free, from ``p0``.

    The gap package's bounded least-squares refit (:func:`vidsim.gap.rigid_diagnose.refit`, soft
    silhouettes at ``cfg.refit_scale``) on all frames, the nuisance inside its prior interval.
    Used because a withheld drag biases the drag-free fit by many posterior
    standard deviations, further than the local designs of :func:`calibrate_noise` travel.

    Args:
        masks: (T, H, W) bool observed silhouettes of the fitted frames.
        loss: the extended per-frame loss (its effects are the nuisance).
        p0: (14,) or (14 + n,) starting point (nuisance 0 when only 14 are given).
        cfg: discrepancy settings; roi_px: residual region around both silhouettes, pixels at scale.

    Returns:
        (14 + n,) refitted parameters (the refit's result is kept only when it lowers the loss).
    """
    o = loss.obj
    p0 = np.asarray(p0, float)
    theta0 = np.r_[p0, np.zeros(loss.n_params - p0.size)]
    model = RigidGapModel(o.body, o.cam, o.times, o.t0, loss.q_base, loss.effects, cfg.refit_scale, 1.0, o.hmax,
                          loss.gravity)
    obs, roi = residual_region(model, masks, theta0, roi_px)
    b = cfg.bounds()
    upper = np.r_[np.full(N_PARAM, np.inf), b[:, 1]]
    lower = np.r_[np.full(N_PARAM, -np.inf), b[:, 0]]
    theta, _ = refit(Problem(model, obs, roi, np.arange(len(o.times))), theta0, cfg.refit_nfev, upper, lower)
    e0, e1 = loss(theta0), loss(theta)
    if e1 is None or (e0 is not None and np.sum(e1) >= np.sum(e0)):
        return theta0
    return theta


@dataclass
class NoiseModel:
    """Calibrated likelihood scale.

    Attributes:
        model: noise model name; w: learning rate, 1/pixel.
        center: (D,) minimiser of the fitted quadratic surface (the mode used by the sampler); D is 14
            plus the nuisance parameters (the same below).
        loss_min: total mismatch at ``center``, pixels.
        H: (D, D) Hessian of the total mismatch, pixels per parameter unit squared.
        J: (D, D) score covariance used (iid or HAC).
        cov: (D, D) approximate posterior covariance ``(w H)^-1``.
        scale: (D,) final design step.
        bandwidth: HAC lag window used (0: none).
        r2: coefficient of determination of the total-loss surface on its design.
        n_evals: evaluations spent.
        inflation: variance inflation of ``sandwich_holdout`` (1: none).
    """

    model: str
    w: float
    center: np.ndarray
    loss_min: float
    H: np.ndarray
    J: np.ndarray
    cov: np.ndarray
    scale: np.ndarray
    bandwidth: int
    r2: float
    n_evals: int
    inflation: float = 1.0

    def to_dict(self) -> dict:
        return {"model": self.model, "w_per_pixel": float(self.w), "loss_min_pixels": float(self.loss_min),
                "posterior_sd_laplace": np.sqrt(np.diag(self.cov)).tolist(), "hac_bandwidth": int(self.bandwidth),
                "surface_r2": float(self.r2), "n_evals": int(self.n_evals),
                "holdout_inflation": float(self.inflation)}


class _PointLog:
    """A :class:`FrameLoss` whose evaluations go through an :class:`~vidsim.optim.cache.EvalCache`
    (keyed by the exact point; the per-frame mismatches logged, ``None`` for a failed simulation):
    the checkpoint of :func:`calibrate_logged`'s designs. Every other attribute is the loss's."""

    def __init__(self, loss: FrameLoss, log) -> None:
        self._loss = loss
        self._log = log

    def __getattr__(self, name: str):
        return getattr(self._loss, name)

    def __call__(self, p: np.ndarray, q_base: np.ndarray | None = None) -> np.ndarray | None:
        if q_base is not None:
            return self._loss(p, q_base)

        def fn(u: np.ndarray) -> tuple[float, dict]:
            return 0.0, {"e": self._loss(u)}

        _, info = self._log.evaluate(np.asarray(p, float), fn)
        e = info.get("e")  # absent: a numerical fault, logged as a failure (a failed simulation)
        return None if e is None else np.asarray(e, float)


def calibrate_logged(masks: np.ndarray, loss: FrameLoss, p_fit: np.ndarray, noise: NoiseConfig,
                     disc: DiscrepancyConfig, seed: int, path: str | None = None, context: str | None = None
                     ) -> tuple[np.ndarray, NoiseModel]:
    """The posterior's start and noise calibration: ``(p_start, noise model)``, where ``p_start`` is
    the fit refitted with the nuisance effects free (:func:`refit_discrepancy`; ``p_fit`` without
    effects) and the model is :func:`calibrate_noise` around it (its design drawn from ``seed``).

    With ``path`` the result is logged as one record of an :class:`~vidsim.optim.cache.EvalCache`
    whose ``context`` fingerprints every input (the caller's :func:`rigid_posterior` does): a
    resumed run (its chain killed while sampling) replays it instead of recomputing its
    ``n_design * (design_iters + 1)`` simulations, bit for bit (floats round-trip exactly through
    the log); a log of other inputs is moved aside. While the calibration runs, each of its loss
    evaluations is logged too (``<path stem>_points.jsonl`` beside ``path``, same context): a run
    killed during the calibration replays the design points it had evaluated and computes only the
    rest, with the same result (the designs are drawn from ``seed``, so the points recur exactly).
    The discrepancy refit's own least-squares steps (with ``disc.effects``) are not logged.
    """
    from dataclasses import fields

    from vidsim.optim.cache import EvalCache

    def run(_u: np.ndarray) -> tuple[float, dict]:
        points = None if path is None else EvalCache(lambda x: None, Path(path).with_name(f"{Path(path).stem}_points.jsonl"),
                                                     context)
        ls = loss if points is None else _PointLog(loss, points)
        try:
            p_start = refit_discrepancy(masks, ls, p_fit, disc) if disc.effects else p_fit
            nm = calibrate_noise(ls, p_start, noise, np.random.default_rng(seed))
        finally:
            if points is not None:
                points.close()
        return 0.0, {"p_start": p_start, "noise": {f.name: getattr(nm, f.name) for f in fields(nm)}}

    u = np.asarray(p_fit, float)
    with EvalCache(run, path, context) as log:
        _, info = log.evaluate(u)
    if "noise" not in info:  # the calibration raised a floating-point error (EvalCache's failed score)
        raise PosteriorError(f"noise calibration failed: {info.get('failure', 'floating-point error')}")
    rec = info["noise"]
    nm = NoiseModel(**{f.name: (np.asarray(rec[f.name], float) if f.type in ("np.ndarray", np.ndarray) else rec[f.name])
                       for f in fields(NoiseModel)})
    return np.asarray(info["p_start"], float), nm


def _quad_features(z: np.ndarray) -> np.ndarray:
    n, D = z.shape
    iu = np.triu_indices(D)
    return np.hstack([np.ones((n, 1)), z, (z[:, :, None] * z[:, None, :])[:, iu[0], iu[1]]])


def _unpack(coef: np.ndarray, D: int) -> tuple[np.ndarray, np.ndarray]:
    """Linear (D,) and Hessian (D, D) of one quadratic surface's coefficients."""
    g = coef[1:1 + D]
    iu = np.triu_indices(D)
    Hm = np.zeros((D, D))
    Hm[iu] = coef[1 + D:]
    Hm = Hm + Hm.T
    return g, Hm


def _pd(H: np.ndarray, floor: float = 1e-6) -> np.ndarray:
    e, V = np.linalg.eigh(0.5 * (H + H.T))
    e = np.maximum(e, floor * max(float(e.max()), 1e-12))
    return (V * e) @ V.T


def hac_covariance(scores: np.ndarray, bandwidth: int) -> np.ndarray:
    """Newey-West long-run covariance (D, D) of (T, D) per-frame scores (sum, not mean)."""
    G = np.asarray(scores, float)
    J = G.T @ G
    for lag in range(1, int(bandwidth) + 1):
        Gl = G[lag:].T @ G[:-lag]
        J += (1.0 - lag / (bandwidth + 1.0)) * (Gl + Gl.T)
    return J


def holdout_inflation(scores: np.ndarray, hessians: np.ndarray, w: float, blocks: int = 2,
                      confidence: float = 0.0) -> float:
    """Variance inflation from held-out frames: do consecutive blocks of the throw agree?

    The frames are cut into ``blocks`` consecutive blocks. Each block ``b`` has its own mode
    ``z_b = -H_b^-1 g_b`` and the rest of the throw its mode ``z_-b``, with covariances
    ``(w H_b)^-1`` and ``(w H_-b)^-1`` under the calibrated likelihood. Without model discrepancy the
    statistic ``chi2_b = d_b^T (C_b + C_-b)^-1 d_b`` of ``d_b = z_b - z_-b`` is about ``D``; a missing
    effect (air drag) makes early and late frames disagree. Returns ``max(1, mean_b chi2_b / D)``,
    the point estimate of ``lambda`` in ``chi2 ~ lambda chi2_D``; with ``confidence`` c in (0, 1) the
    upper c-confidence bound ``chi2 / chi2_D.ppf(1 - c)`` instead (two blocks only), which allows
    for the estimate's own scatter (relative sd ``sqrt(2 / D)``, 37 % for D = 15). With two blocks (the default) this is the comparison of the first and the second half; more
    blocks average more comparisons (a less noisy estimate of the same inflation, each held-out
    block shorter).

    Args:
        scores: (T, D) per-frame score at the joint mode; hessians: (T, D, D) per-frame Hessians.
        w: calibrated learning rate, 1/pixel.
        blocks: number of consecutive blocks (2 <= blocks <= T).
        confidence: 0 for the point estimate, else the one-sided confidence of the upper bound.
    """
    T, D = scores.shape
    if not 2 <= int(blocks) <= T:
        raise PosteriorError(f"noise.holdout_blocks = {blocks}: need 2 <= blocks <= {T} (the fitted frames)")
    edges = np.linspace(0, T, int(blocks) + 1).round().astype(int)
    chi2 = []
    for b in range(int(blocks)):
        lo, hi = edges[b], edges[b + 1]
        Hin = _pd(hessians[lo:hi].sum(0), 1e-3)
        Hout = _pd(hessians[:lo].sum(0) + hessians[hi:].sum(0), 1e-3)
        g_in, g_out = scores[lo:hi].sum(0), scores[:lo].sum(0) + scores[hi:].sum(0)
        d = -np.linalg.solve(Hin, g_in) + np.linalg.solve(Hout, g_out)
        C = np.linalg.inv(w * Hin) + np.linalg.inv(w * Hout)
        chi2.append(float(d @ np.linalg.solve(C, d)))
        if int(blocks) == 2:  # the two comparisons are the same one
            break
    if confidence:
        from scipy.stats import chi2 as chi2_dist

        if not (0 < confidence < 1) or int(blocks) != 2:
            raise PosteriorError(f"noise.holdout_confidence = {confidence}: need 0 < c < 1 (with holdout_blocks = 2)")
        return max(1.0, chi2[0] / float(chi2_dist.ppf(1.0 - confidence, D)))
    return max(1.0, float(np.mean(chi2)) / D)


def calibrate_noise(loss: FrameLoss, p0: np.ndarray, cfg: NoiseConfig | None = None,
                    rng: np.random.Generator | None = None) -> NoiseModel:
    """Fit per-frame quadratic surfaces around the optimum and derive the likelihood's scale.

    Args:
        loss: per-frame mismatch.
        p0: (14 + n,) the optimiser's estimate (n nuisance parameters of ``loss.effects``).
        cfg: noise settings; rng: design randomness (seeded by the caller).

    Returns:
        :class:`NoiseModel` (reads only the footage and the model, never a truth).
    """
    cfg = cfg or NoiseConfig()
    cfg.validate()
    rng = rng or np.random.default_rng(0)
    p0 = np.asarray(p0, float)
    effects = tuple(getattr(loss, "effects", ()))  # any per-frame loss of (14 + nuisance) parameters
    D = N_PARAM + len(effects)
    if p0.shape != (D,):
        raise PosteriorError(f"p0 must have {D} entries (14 + the nuisance {list(effects)}), got {p0.shape}")
    T = loss.n_frames
    E0 = loss(p0)
    if E0 is None:
        raise PosteriorError("the fitted parameters do not simulate (the fit is invalid): cannot build a posterior")
    # design map dp = A z; whitened by the fitted curvature below
    A = np.diag(np.r_[DESIGN_SCALE0, [DISCREPANCY_DESIGN0[e] for e in effects]] * 0.1)
    n_evals = 1
    center = p0.copy()
    rise0 = max(float(np.sum(E0)) * 0.02, float(T))  # first whitened design: ~2 % loss increase
    kappa_prev = None
    for it in range(cfg.design_iters + 1):
        z = rng.normal(size=(cfg.n_design, D))
        rows, ok = [], []
        for zi in z:
            e = loss(center + A @ zi)
            n_evals += 1
            if e is not None:
                rows.append(e)
                ok.append(zi)
        need = max(150, (D + 1) * (D + 2) // 2 + 16)  # quadratic surface: (D + 1)(D + 2) / 2 coefficients
        if len(ok) < need:
            raise PosteriorError(f"local design: only {len(ok)} of {cfg.n_design} points simulate (need {need})")
        z = np.asarray(ok)
        E = np.asarray(rows)
        F = _quad_features(z)
        coef, *_ = np.linalg.lstsq(F, E, rcond=None)  # (120, T)
        tot = coef.sum(1)
        y = E.sum(1)
        r2 = float(1 - np.sum((y - F @ tot) ** 2) / max(np.sum((y - y.mean()) ** 2), 1e-300))
        g_tot, H_tot = _unpack(tot, D)
        H = _pd(H_tot, 1e-3)
        zs = -np.linalg.solve(H, g_tot)
        nz = np.linalg.norm(zs)
        if nz > 2.0:
            zs *= 2.0 / nz
        gk = np.empty((T, D))
        Hks = np.empty((T, D, D))
        for k in range(T):
            g, Hks[k] = _unpack(coef[:, k], D)
            gk[k] = g + Hks[k] @ zs
        if cfg.model == "sandwich_hac":
            bw = cfg.hac_bandwidth or max(1, T // 4)
            J = hac_covariance(gk, bw)
        else:
            bw = 0
            J = gk.T @ gk
        J = 0.5 * (J + J.T)
        if T > D:
            # small-sample correction (HC1): the per-frame scores are taken at the fitted minimum, where
            # they sum to zero, so their outer product underestimates J by about (T - D) / T (35 % at the
            # throws' T = 40, D = 14: intervals 1.24x too narrow; found in review, 5 Dec 2026)
            J *= T / (T - D)
        if cfg.model == "iid_pixel":
            w = 1.0 / (2.0 * max(float(y.min()), 1e-9) / loss.n_pixels)
        else:
            w = D / float(np.trace(np.linalg.solve(H, J)))
        inflation = 1.0
        if cfg.model == "sandwich_holdout":
            inflation = holdout_inflation(gk, Hks, w, cfg.holdout_blocks, cfg.holdout_confidence)
            w /= inflation
        A_used = A.copy()
        center = center + A @ zs
        Hinv = np.linalg.inv(H)
        cov = A @ (Hinv / w) @ A.T
        if it == cfg.design_iters:
            break
        # next design: N(0, kappa H^-1) in these coordinates, kappa giving the wanted loss rise
        kappa = 2.0 * rise0 / D if it == 0 else cfg.design_width ** 2 / w
        if kappa_prev is not None:
            kappa = float(np.clip(kappa, kappa_prev / 10.0, kappa_prev * 10.0))
        kappa_prev = kappa
        A = A @ np.linalg.cholesky(kappa * Hinv)
    Lc = loss(center)
    n_evals += 1
    if Lc is None:
        raise PosteriorError("the quadratic surface's minimum does not simulate")
    # Hessian and score covariance in parameter units (the last design's dp = A_used z)
    Ai = np.linalg.inv(A_used)
    Hp = Ai.T @ H @ Ai
    Jp = Ai.T @ J @ Ai
    s = np.sqrt(np.diag(A_used @ A_used.T))
    return NoiseModel(cfg.model, float(w), center, float(np.sum(Lc)), Hp, Jp, cov, s, bw, r2, n_evals, inflation)


# ----------------------------------------------------------------------------- posterior
class RigidLogPosterior:
    """``log prior + (-w (L(theta) - L*))``; ``-inf`` outside the prior or for a failed simulation.

    ``bounds`` (n, 2): the uniform prior interval of each nuisance parameter (after the 14).
    """

    def __init__(self, loss: FrameLoss, noise: NoiseModel, p_fit: np.ndarray, prior: RigidPriorConfig,
                 bounds: np.ndarray | None = None) -> None:
        self.loss = loss
        self.noise = noise
        self.p_fit = np.asarray(p_fit, float)
        self.prior = prior
        self.bounds = np.zeros((0, 2)) if bounds is None else np.asarray(bounds, float).reshape(-1, 2)
        if N_PARAM + len(self.bounds) != loss.n_params:
            raise PosteriorError(f"{len(self.bounds)} nuisance bounds for the loss's {loss.n_params - N_PARAM} "
                                 "nuisance parameters")

    def in_prior(self, p: np.ndarray) -> bool:
        pr, d = self.prior, p[:N_PARAM] - self.p_fit
        nu = p[N_PARAM:]
        return bool(np.all((nu >= self.bounds[:, 0]) & (nu <= self.bounds[:, 1]))
                    and np.all(np.abs(d[0:3]) <= pr.position_m)
                    and np.degrees(np.linalg.norm(p[3:6])) <= pr.rotation_deg
                    and np.all(np.abs(d[6:9]) <= pr.velocity_mps)
                    and np.all(np.abs(d[9:12]) <= pr.omega_radps)
                    and np.all(np.degrees(np.abs(p[12:14])) <= pr.gravity_deg))

    def __call__(self, p: np.ndarray) -> float:
        if not np.all(np.isfinite(p)) or not self.in_prior(p):
            return -np.inf
        e = self.loss(p)
        if e is None:
            return -np.inf
        return -self.noise.w * (float(np.sum(e)) - self.noise.loss_min)


def laplace_samples(noise: NoiseModel, bounds: np.ndarray | None = None, n: int = 20000,
                    rng: np.random.Generator | None = None) -> np.ndarray:
    """(n, D) draws of the Laplace approximation ``N(center, (w H)^-1)`` truncated to the nuisance prior.

    The nuisance parameters (the last ``len(bounds)`` coordinates) are kept inside their interval
    by rejection, so the 14 parameters' draws are their marginal under the truncated Gaussian (a
    mode on the bound ``0`` of a drag coefficient keeps only the physical half). Without bounds:
    the plain Gaussian. Raises :class:`PosteriorError` when almost nothing (< 0.1 %) is inside.
    """
    rng = rng or np.random.default_rng(0)
    b = np.zeros((0, 2)) if bounds is None else np.asarray(bounds, float).reshape(-1, 2)
    D = noise.center.size
    L = np.linalg.cholesky(noise.cov + 1e-300 * np.eye(D))
    out, n_drawn = [], 0
    while sum(len(x) for x in out) < n:
        Z = noise.center + rng.normal(size=(n, D)) @ L.T
        n_drawn += n
        nu = Z[:, D - len(b):]
        keep = np.all((nu >= b[:, 0]) & (nu <= b[:, 1]), axis=1) if len(b) else np.ones(n, bool)
        out.append(Z[keep])
        if n_drawn >= 20 * n and sum(len(x) for x in out) < 0.001 * n_drawn:
            raise PosteriorError("the Laplace approximation puts < 0.1 % of its mass inside the nuisance prior")
    return np.concatenate(out)[:n]


def to_natural(P: np.ndarray) -> np.ndarray:
    """Parameters (..., 14 [+ nuisance]) with angles converted to degrees (rotation offset, tilt, roll)."""
    out = np.array(P, float, copy=True)
    out[..., list(ANGLE_IDX)] = np.degrees(out[..., list(ANGLE_IDX)])
    return out


def truth_params(truth: dict, q_base: np.ndarray, symmetries: np.ndarray) -> np.ndarray:
    """(14,) the truth of a synthetic throw in the posterior's coordinates (evaluation only).

    The rotation part is the rotation vector from ``q_base`` to the true orientation, for the body
    symmetry that makes it smallest.
    """
    Rb = quat_to_rot(np.asarray(q_base, float))
    Rt = quat_to_rot(np.asarray(truth["quaternion"], float))
    best = min((rot_to_rotvec(Rb.T @ Rt @ S) for S in symmetries), key=lambda d: float(np.linalg.norm(d)))
    return np.concatenate([truth["position"], best, truth["velocity"], truth["omega_world"],
                           [truth["tilt"], truth["roll"]]]).astype(float)


@dataclass
class RigidPosterior:
    """Result of :func:`rigid_posterior`.

    Attributes:
        names: parameter names (the 14, then the nuisance effects); units: their (natural) units.
        p_fit: (14,) the optimiser's estimate; q_base: (4,) its orientation (rotation offsets refer to it).
        noise: the calibrated noise model.
        chain: the sampled chain (parameter units: radians).
        summary: per-parameter rows in natural units (angles in degrees) with point estimate,
            5/50/95 % quantiles, mean and sd.
        corr: (D, D) posterior correlation matrix (D = 14 + nuisance).
        multimodal: True when a distinct solution is nearly as probable or the walkers split.
        multimodal_reasons: what raised the flag.
        seconds: total wall time (noise calibration + sampling).
        discrepancy: the nuisance effects, their prior bounds and the refitted mode's values.
    """

    names: list[str]
    units: list[str]
    p_fit: np.ndarray
    q_base: np.ndarray
    noise: NoiseModel
    chain: Chain
    summary: list[dict]
    corr: np.ndarray
    multimodal: bool
    multimodal_reasons: list[str] = field(default_factory=list)
    seconds: float = 0.0
    discrepancy: dict = field(default_factory=dict)

    def samples(self, natural: bool = True) -> np.ndarray:
        """(N, D) post-burn-in samples (angles in degrees when ``natural``; nuisance last)."""
        S = self.chain.samples()
        return to_natural(S) if natural else S

    def diagnostics(self) -> dict:
        c = self.chain
        return {"converged": bool(c.converged), "n_steps": int(c.n_steps), "n_walkers": int(c.chain.shape[1]),
                "burn_in": int(c.burn), "tau": c.tau.tolist(), "tau_max": float(np.max(c.tau)),
                "steps_per_tau": float(c.n_steps / np.max(c.tau)), "acceptance": float(c.acceptance),
                "ess": float(c.ess), "sampling_seconds": float(c.seconds), "seconds": float(self.seconds),
                "ess_per_minute": float(c.ess / max(self.seconds, 1e-9) * 60.0),
                "multimodal": bool(self.multimodal), "multimodal_reasons": list(self.multimodal_reasons),
                "noise": self.noise.to_dict(), "discrepancy": dict(self.discrepancy)}


def _orientation_split(samples: np.ndarray, distinct_deg: float, frac: float) -> float:
    """Fraction of samples whose rotation offset is > ``distinct_deg`` from the median offset."""
    d = np.degrees(samples[:, 3:6])
    dev = np.linalg.norm(d - np.median(d, axis=0), axis=1)
    return float(np.mean(dev > distinct_deg))


def rigid_posterior(masks: np.ndarray, times: np.ndarray, cam: PinholeCamera, body: BoxBody, p_fit: np.ndarray,
                    q_base: np.ndarray, t0: float, alternatives: list[dict] | None = None,
                    noise: NoiseConfig | None = None, prior: RigidPriorConfig | None = None,
                    sampler: SamplerConfig | None = None, chain_path: str | None = None,
                    progress=None, distinct_deg: float = 10.0, multimodal_ratio: float = 0.01,
                    hmax: float = 1.0 / 60.0, gravity: float = G_EARTH,
                    discrepancy: DiscrepancyConfig | None = None, calibration_path: str | None = None
                    ) -> RigidPosterior:
    """Sample the posterior of a fitted throw.

    Args:
        masks: (T, H, W) bool observed silhouettes of the fitted frames.
        times: (T,) their times, s; t0: time of the initial state, s.
        cam: full-resolution calibrated camera; body: the known body.
        p_fit: (14,) fitted parameters (rotation part folded, so ``p_fit[3:6] = 0``).
        q_base: (4,) fitted initial orientation (w, x, y, z).
        alternatives: the fit's distinct solutions ``{"params": (14,), "quaternion": (4,)}``
            (params may be omitted: the fit's other parameters are then used).
        noise, prior, sampler: settings.
        chain_path: resumable chain file (``.npz``) or None.
        progress: callback per sampling chunk (see :func:`vidsim.posterior.sampler.sample`).
        distinct_deg: orientation split that counts as a second mode, degrees.
        multimodal_ratio: an alternative whose density is above this fraction of the mode's is a mode.
        hmax: RK4 step bound, s; gravity: known gravity magnitude, m/s^2.
        discrepancy: nuisance effects sampled with the 14 parameters (default: none).
        calibration_path: log of the start refit and noise calibration (:func:`calibrate_logged`,
            fingerprinted by every input here and the package's source digest), replayed when a run
            is resumed; None: computed every time.

    Returns:
        :class:`RigidPosterior` (with a discrepancy, the 14 parameters' summaries are marginal over
        the nuisance, whose own rows follow them).
    """
    t_start = time.perf_counter()
    noise = noise or NoiseConfig()
    prior = prior or RigidPriorConfig()
    sampler = sampler or SamplerConfig()
    disc = discrepancy or DiscrepancyConfig()
    prior.validate()
    disc.validate()
    masks = np.asarray(masks, bool)
    times = np.asarray(times, float)
    if masks.ndim != 3 or masks.shape[0] != times.shape[0] or masks.shape[0] < 5:
        raise PosteriorError(f"masks must be (T, H, W) with T = len(times) >= 5; got {masks.shape}, {times.shape}")
    if masks.shape[1:] != (cam.height, cam.width):
        raise PosteriorError(f"masks are {masks.shape[2]}x{masks.shape[1]}, camera is {cam.width}x{cam.height}")
    p_fit = np.asarray(p_fit, float)
    if p_fit.shape != (N_PARAM,) or not np.all(np.isfinite(p_fit)):
        raise PosteriorError(f"p_fit must be {N_PARAM} finite numbers {PARAM_NAMES}, got shape {p_fit.shape}")
    q_base = np.asarray(q_base, float)
    if np.linalg.norm(p_fit[3:6]) > 0:  # fold the rotation into the base orientation
        q_base = quat_mul(q_base, quat_exp(p_fit[3:6]))
        p_fit = p_fit.copy()
        p_fit[3:6] = 0.0
    q_base = q_base / np.linalg.norm(q_base)
    loss = FrameLoss(body, cam, times, masks, t0, q_base, hmax, gravity, tuple(disc.effects))
    bounds = disc.bounds()
    context = None
    if calibration_path is not None:
        import vidsim
        from vidsim.optim.cache import fingerprint

        context = fingerprint("rigid_posterior.calibration", np.packbits(masks), masks.shape, times, cam, body, p_fit,
                              q_base, float(t0), float(hmax), float(gravity), noise, disc, int(sampler.seed),
                              vidsim.SOURCE_DIGEST)
    p_start, nm = calibrate_logged(masks, loss, p_fit, noise, disc, int(sampler.seed), calibration_path, context)
    logp = RigidLogPosterior(loss, nm, p_fit, prior, bounds)
    start = nm.center.copy()
    if disc.effects:  # the walkers' ball must start inside the nuisance prior (a mode may sit below 0)
        sd = np.sqrt(np.diag(nm.cov))[N_PARAM:]
        margin = np.minimum(0.2 * sd, 0.05 * (bounds[:, 1] - bounds[:, 0]))
        start[N_PARAM:] = np.clip(start[N_PARAM:], bounds[:, 0] + margin, bounds[:, 1] - margin)
    ch = sample(logp, start, nm.cov, sampler, chain_path, progress)
    S = ch.samples()
    nat = to_natural(S)
    names = list(PARAM_NAMES) + list(disc.effects)
    units = list(UNITS) + [RIGID_EFFECTS[e].units for e in disc.effects]
    summ = summarize(nat, names, np.r_[to_natural(p_fit), p_start[N_PARAM:]])
    for row, u in zip(summ, units):
        row["unit"] = u
    reasons = []
    for i, alt in enumerate(alternatives or []):
        pa = np.asarray(alt.get("params", p_fit), float).copy()[:N_PARAM]
        qa = np.asarray(alt["quaternion"], float)
        if "omega_world" in alt:
            pa[9:12] = alt["omega_world"]
        pa = np.r_[pa, nm.center[N_PARAM:]]  # the alternative at the mode's nuisance
        e = loss(pa, qa)
        if e is None:
            continue
        ratio = float(np.exp(-nm.w * (np.sum(e) - nm.loss_min)))
        dist = orientation_error_deg(quat_to_rot(qa), quat_to_rot(q_base), body.symmetries)
        if dist > distinct_deg and ratio > multimodal_ratio:
            reasons.append(f"alternative {i} ({dist:.0f} deg away) has density ratio {ratio:.3g} to the mode")
    split = _orientation_split(S, distinct_deg, 0.01)
    if split > 0.01:
        reasons.append(f"{100 * split:.1f} % of samples are > {distinct_deg:g} deg from the median orientation")
    dd = {"effects": list(disc.effects), "bounds": bounds.tolist(), "refit": p_start[N_PARAM:].tolist()}
    return RigidPosterior(names, units, p_fit, q_base, nm, ch, summ, correlation(nat),
                          bool(reasons), reasons, time.perf_counter() - t_start, dd)
