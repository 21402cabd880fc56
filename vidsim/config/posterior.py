"""Hydra schema of the ``posterior`` config group (conf/posterior/*.yaml extend it)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class PosteriorRigidConfig:
    """Rigid-body posterior (:mod:`vidsim.posterior.rigid`).

    Attributes:
        noise: likelihood noise model: ``sandwich`` (frames independent, scale from the per-frame
            residual scores at the optimum), ``sandwich_holdout`` (discrepancy-aware: variance inflated
            by the disagreement of the first and second half of the frames), ``sandwich_hac`` (scores correlated
            over ``hac_bandwidth`` frames), ``iid_pixel`` (every pixel independent; overconfident).
        n_design: local-design evaluations per refinement of the noise calibration.
        design_iters: refinements of the design to the posterior's scale.
        hac_bandwidth: Newey-West lag window, frames (0: a quarter of the fitted frames).
        holdout_confidence: ``sandwich_holdout`` only: 0 inflates by the point estimate of the
            halves' disagreement (chi2 / D); c in (0, 1) by its upper c-confidence bound
            (chi2 / chi2_D quantile 1 - c), allowing for the estimate's scatter (docs/posterior.md).
        discrepancy: structured model discrepancy: effects of the gap library sampled with the 14
            parameters as nuisance parameters, each with a uniform prior from 0 (off) to its upper
            bound (``quadratic_drag`` 5 kg/m^3, ``linear_drag`` 1 1/s, ``angular_drag`` 1 1/s;
            :data:`vidsim.posterior.rigid.DISCREPANCY_UPPER`); the 14 parameters' intervals are then
            marginal over them. Empty: none. An unknown name is an error.
        discrepancy_upper: prior upper bounds overriding the defaults, e.g. ``{quadratic_drag: 2.0}``.
        discrepancy_refit_nfev: least-squares budget of the refit of the mode with the nuisance free.
        discrepancy_signed: prior ``[-upper, upper]`` instead of ``[0, upper]`` (a discrepancy term that
            may take unphysical signs, so that a truth of 0 is not on the prior's bound).
        prior_position_m: prior half-width around the fitted position, m.
        prior_rotation_deg: largest prior rotation away from the fitted orientation, degrees.
        prior_velocity_mps: prior half-width around the fitted velocity, m/s.
        prior_omega_radps: prior half-width around the fitted angular velocity, rad/s.
        prior_gravity_deg: largest |tilt|, |roll| of gravity, degrees.
        n_walkers: emcee walkers (>= 28 for the 14 parameters).
        chunk: steps between checkpoints of the chain file.
        min_steps / max_steps: chain length bounds, steps.
        min_tau_multiple: converged when the chain has this many autocorrelation times.
        seed: seed of the design and of the sampler.
        distinct_deg: orientation difference that makes a second mode, degrees.
        multimodal_ratio: density ratio (to the mode) above which a distinct solution is a mode.
    """

    noise: str = "sandwich"
    n_design: int = 400
    design_iters: int = 2
    hac_bandwidth: int = 0
    holdout_confidence: float = 0.0
    discrepancy: list[str] = field(default_factory=list)
    discrepancy_upper: dict[str, float] = field(default_factory=dict)
    discrepancy_refit_nfev: int = 15
    discrepancy_signed: bool = False
    prior_position_m: float = 0.5
    prior_rotation_deg: float = 45.0
    prior_velocity_mps: float = 2.0
    prior_omega_radps: float = 5.0
    prior_gravity_deg: float = 20.0
    n_walkers: int = 32
    chunk: int = 100
    min_steps: int = 300
    max_steps: int = 2000
    min_tau_multiple: float = 50.0
    seed: int = 0
    distinct_deg: float = 10.0
    multimodal_ratio: float = 0.01


@dataclass
class PosteriorClothConfig:
    """Cloth posterior (:mod:`vidsim.posterior.cloth`): a loss posterior sampled on a GP surrogate.

    Attributes:
        params: ``params.yaml`` of ``select_cloth`` (the point estimate and the candidates' true errors).
        fits: the fitted trials' ``fit.yaml`` files (their folders' ``evals.jsonl`` train the surrogate).
        footage: the fitted trials' footage folders, in the order of ``fits``.
        noise: ``sandwich`` (frames independent) or ``sandwich_hac`` (per-frame scores correlated over
            ``hac_bandwidth`` neighbouring frames, Newey-West).
        hac_bandwidth: Newey-West lag window, frames (used by ``sandwich_hac``).
        design_rounds: local-design rounds (the first at the estimate, later ones at the surrogate's mode
            with its Laplace covariance).
        n_pairs: antithetic pairs per design round (0: 2 x dimension + 2).
        design_scale: half-width of the first round in the unit cube.
        n_jitter: evaluations per design round at tiny offsets (``jitter``, unit cube) of its centre:
            they measure the roughness of the loss (chaotic folds).
        roughness_k: the roughness term of the likelihood scale, ``w_r = D / (2 roughness_k sd)``,
            combined with the sandwich scale as variances (0: sandwich only).
        determined_floor: the sandwich scale is calibrated only in the surrogate's eigen-directions
            with curvature >= this fraction of the largest (0: all directions, where flat directions
            can drive the scale to 0 for every direction; default 1e-5, measured in docs/posterior.md).
        max_cache: cached annealing evaluations per trial given to the surrogate (nearest informative first).
        clip_logp: targets clipped this many log-density units above the minimum.
        gp_restarts: random restarts of the GP hyperparameter fit.
        n_check: posterior draws at which the surrogate is compared with the true objective (>= 50).
        check_tol: largest offset-free surrogate error accepted, log-density units.
        refine_rounds: times the check points join the training set and the chain is redrawn when the
            check fails.
        max_true_evals: a refinement is skipped when it would take the stage's true evaluations
            (design, jitter and checks, replayed ones included) past this count (0: no cap). The
            per-fabric time budget in a form that resumes reproducibly: at the full setting a
            true evaluation costs 2.7-4.5 CPU-s, the design and first check take 144.
        n_walkers, chunk, min_steps, max_steps, min_tau_multiple: emcee settings (converged only at
            >= min_tau_multiple autocorrelation times).
        multimodal_ratio: density ratio (to the mode) above which a distinct minimum is a mode.
        distinct: unit-cube distance (max norm) that makes two solutions distinct.
        seed: seed of the design, the GP restarts, the sampler and the check draws.
    """

    params: str = ""
    fits: list[str] = field(default_factory=list)
    footage: list[str] = field(default_factory=list)
    noise: str = "sandwich"
    hac_bandwidth: int = 2
    design_rounds: int = 2
    n_pairs: int = 0
    design_scale: float = 0.05
    n_jitter: int = 6
    jitter: float = 1e-3
    roughness_k: float = 1.0
    determined_floor: float = 1e-5
    max_cache: int = 300
    clip_logp: float = 30.0
    gp_restarts: int = 2
    n_check: int = 50
    check_tol: float = 1.0
    refine_rounds: int = 2
    max_true_evals: int = 200
    n_walkers: int = 32
    chunk: int = 500
    min_steps: int = 1000
    max_steps: int = 20000
    min_tau_multiple: float = 50.0
    multimodal_ratio: float = 0.01
    distinct: float = 0.1
    seed: int = 0


@dataclass
class PosteriorPathsConfig:
    """Inputs of the posterior stages.

    Attributes:
        fit: ``fit.yaml`` of the rigid fit stage.
        masks: ``masks.npz`` (``masks``, ``times``) of the rigid segment stage.
    """

    fit: str = ""
    masks: str = ""


@dataclass
class PosteriorConfig:
    """Settings of the posterior stages.

    Attributes:
        enabled: the family's switch for Hydra users (Snakemake uses ``stages.posterior``).
        rigid: the rigid-body posterior; paths: its inputs.
        cloth: the cloth posterior (with its inputs).
        draws_logged: posterior draws whose silhouettes are averaged into the Rerun overlay.
    """

    enabled: bool = True
    rigid: PosteriorRigidConfig = field(default_factory=PosteriorRigidConfig)
    cloth: PosteriorClothConfig = field(default_factory=PosteriorClothConfig)
    paths: PosteriorPathsConfig = field(default_factory=PosteriorPathsConfig)
    draws_logged: int = 40
