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
        draws_logged: posterior draws whose silhouettes are averaged into the Rerun overlay.
    """

    enabled: bool = True
    rigid: PosteriorRigidConfig = field(default_factory=PosteriorRigidConfig)
    paths: PosteriorPathsConfig = field(default_factory=PosteriorPathsConfig)
    draws_logged: int = 40
