"""Hydra schema of the ``cloth`` config group (conf/cloth/*.yaml extend it).

The cloth stages (``vidsim/cli/cloth_*.py``) film a hanging swatch under a striped projector,
extract silhouettes and angle maps, and fit the nine Baraff-Witkin parameters (seed 4.3-4.5).
Units are SI unless a name says otherwise (``_px``, ``_deg``, ``_s``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional


def _l(*x: float):
    return field(default_factory=lambda: list(x))


@dataclass
class ClothCameraConfig:
    """The cloth scene's true camera (reality only; estimators read the calibration).

    Pixels for intrinsics, metres for eye/target/up (world z up, the swatch hangs in y = 0).
    The camera looks at the swatch from 40 degrees off its normal (eye at azimuth 40 degrees,
    1.6 m away): a camera on the normal sees the swatch's out-of-plane swing only through
    foreshortening, and the fabrics' footage differed less there (measured in
    docs/cloth_study.md, "Studio design").
    """

    width: int = 320
    height: int = 240
    fx: float = 560.0
    fy: Optional[float] = None
    cx: Optional[float] = None
    cy: Optional[float] = None
    dist: list[float] = _l(0.0, 0.0, 0.0, 0.0, 0.0)
    eye: list[float] = _l(1.03, -1.23, 0.82)
    target: list[float] = _l(0.0, 0.0, 0.82)
    up: list[float] = _l(0.0, 0.0, 1.0)
    roll_deg: float = 0.0


@dataclass
class ClothProjectorConfig:
    """The cloth scene's true projector: a pinhole casting horizontal stripes.

    ``period_px`` is the stripe period in projector pixels (the projected image is known to the
    estimator, like the seed's slide); ``power`` is the irradiance 1 m away on a bright stripe,
    ``ambient`` the irradiance everywhere (linear units, 1 = white at full exposure).
    It stands 0.53 m above the camera and turned with it (the rig at 40 degrees azimuth): the
    vertical baseline makes horizontal stripes bend over folds.
    """

    width: int = 800
    height: int = 600
    fx: float = 900.0
    eye: list[float] = _l(1.12, -0.95, 1.35)
    target: list[float] = _l(0.0, 0.0, 0.85)
    up: list[float] = _l(0.0, 0.0, 1.0)
    period_px: float = 10.0
    power: float = 1.6
    ambient: float = 0.15


@dataclass
class ClothCalibrationConfig:
    """Calibration of the cloth scene from rendered chessboard images (camera + projector).

    Used by ``calibrate_scene`` with ``camera=cloth projector=cloth calibrate=cloth`` (the
    ``conf/*/cloth.yaml`` files interpolate these values). ``target_origin``: where the reference
    board (which defines the world frame) hangs, metres; ``square_size``: printed square, metres.
    """

    n_views: int = 10
    n_projector_views: int = 10
    noise_sigma: float = 2.0
    square_size: float = 0.03  # m
    max_rms_px: float = 0.5
    target_origin: list[float] = _l(-0.2, 0.0, 1.0)  # m, reference board's first printed corner
    projector_square_px: int = 10  # checker square the projector casts, projector pixels
    projector_pattern_spread: float = 0.5  # checker positions over the projector image (calibrate.projector_pattern_spread)
    target_blank_width: float = 0.25  # m, blank board area right of the print (projector pattern)
    still_scale: float = 2.0  # calibration stills at 2x the video resolution (640x480)


@dataclass
class ClothRealityConfig:
    """What reality films: fabric x motion, engine, imaging and effects.

    ``kind``: ``mujoco`` (MuJoCo flex, the fabrics of :mod:`vidsim.reality.cloth`) or ``twin``
    (the estimator's own simulator at ``twin_resolution`` with the known ``twin_params``).
    ``object``: ``swatch`` (gripped by two corners along ``motion``) or ``skirt`` (on the skipping
    body of ``cloth.skirt``; MuJoCo only).
    ``effects``: ``{effect: {key: value}}`` over :data:`vidsim.reality.cloth.DEFAULT_EFFECTS`;
    by default only ``air_drag`` is on (cloth moves in air: in vacuum a swatch waved near its
    pendulum frequency swings at an amplitude set by the engine's numerical damping, which no
    model parameter describes); ``cloth.reality.effects.air_drag.on=false`` films in vacuum.
    ``fabric_effects``: per fabric extra effects merged on top.
    Imaging effects: ``motion_blur`` sub-samples per exposure (0 off) with ``exposure`` as a
    fraction of the frame interval, ``lens_k1`` radial distortion unknown to the calibration,
    ``projector_misalign_deg`` a rotation of the projector after calibration.
    ``settle_s``: rest before frame 0 (grips still); ``settle_bath``: viscous damping rate of that
    rest, 1/s, for swatches (0 = off: the swatch starts the motion still swinging from its flat start).
    """

    kind: str = "mujoco"
    object: str = "swatch"
    fabric: str = "linen"
    motion: str = "exp1"
    n_frames: int = 50
    fps: float = 30.0
    resolution: int = 15
    settle_s: float = 1.0
    settle_bath: float = 0.0
    n_background: int = 5
    albedo: float = 0.85
    noise_sigma: float = 2.0
    blur_sigma_px: float = 0.6
    jpeg_quality: int = 0
    motion_blur: int = 0
    exposure: float = 0.5
    lens_k1: float = 0.0
    projector_misalign_deg: float = 0.0
    effects: dict[str, Any] = field(default_factory=lambda: {"air_drag": {"on": True}})
    fabric_effects: dict[str, Any] = field(default_factory=dict)
    twin_resolution: int = 25
    twin_params: dict[str, float] = field(default_factory=lambda: {
        "bend": 3e-6, "stretch": 300.0, "shear": 40.0, "bend_damping": 3e-8, "stretch_damping": 3e-3,
        "shear_damping": 3e-3, "drag_linear": 0.4, "drag_quad": 0.8, "drag_degrade": 0.2, "density": 0.2,
    })
    seed: int = 0


@dataclass
class ClothFeaturesConfig:
    """Silhouettes and angle maps of footage (seed eq. 11).

    ``period_px``: stripe period the G2/H2 bank is tuned to, camera pixels; ``tau``: gradient-mask
    threshold, rad/px; ``min_strength``/``min_orientedness``: validity of an angle (see
    :func:`vidsim.video.anglemap.angle_map`); ``k_sigma``/``min_diff``: segmentation thresholds.
    """

    period_px: float = 6.5
    tau: float = 0.04
    min_strength: float = 0.03
    min_orientedness: float = 0.2
    k_sigma: float = 5.0
    min_diff: float = 12.0


@dataclass
class ClothModelConfig:
    """The estimator's simulator (:mod:`vidsim.cloth`) as used by the objective.

    ``resolution``: vertices per side of the swatch; ``settle_s``: rest time before frame 0
    (grips still); ``settle_bath``: viscous damping rate of that settle, 1/s (0 = off: the
    model starts the clip still swinging from its flat start); ``frame_stride``: use every k-th footage frame; ``max_frames``: 0 = all.
    ``multirate``: the fast scheme's bending kicks once per that many steps ("1", plain velocity
    Verlet: the default again since 5 Dec 2026; "auto", the default from 3 to 5 Dec 2026: the factor
    from the ratio of the bending's and the whole model's stable steps, up to 4; measured to move
    the model away from a plain-Verlet twin on soft fabrics: docs/cloth_parameters.md).
    ``damping``: how the fast scheme integrates the stretch, shear and bending dampings: "explicit"
    (as forces, the setting of every fit before 4 Dec 2026), "split" (as per-condition decays after
    each step, stable for any step) or "auto", the default since 4 Dec 2026 (split where that
    lengthens the step by more than 1.5x, else explicit; :func:`vidsim.cloth.simulate`,
    docs/cloth_parameters.md).
    ``chaos_members`` > 0: each swatch trial's error is the mean over that many copies of the
    parameters scaled by fixed draws of exp(N(0, ``chaos_sigma``)) (an experiment against the
    chaotic loss, off by default: docs/cloth_study.md, "Session 36").
    """

    resolution: int = 20
    settle_s: float = 0.5
    settle_bath: float = 0.0
    integrator: str = "fast"
    multirate: str = "1"
    damping: str = "auto"
    frame_stride: int = 1
    max_frames: int = 0
    chaos_members: int = 0
    chaos_sigma: float = 1e-4


def _default_space() -> dict[str, Any]:
    return {
        "bend": {"lo": 1e-7, "hi": 1e-4, "log": True},
        "stretch": {"lo": 20.0, "hi": 4000.0, "log": True},
        "shear": {"lo": 2.0, "hi": 500.0, "log": True},
        "bend_damping": {"lo": 1e-9, "hi": 1e-6, "log": True},
        "stretch_damping": {"lo": 1e-4, "hi": 0.1, "log": True},
        "shear_damping": {"lo": 1e-4, "hi": 0.1, "log": True},
        "drag_linear": {"lo": 0.0, "hi": 2.0, "log": False},
        "drag_quad": {"lo": 0.0, "hi": 3.0, "log": False},
        "drag_degrade": {"lo": 0.0, "hi": 1.0, "log": False},
    }


@dataclass
class ClothFitConfig:
    """Coarse grid + simulated annealing (or CMA-ES) over the estimated parameters.

    ``space``: ``{name: {lo, hi, log}}`` of the estimated parameters (a subset of the nine;
    the others stay at ``fixed``/their mid-range value). ``grid_params``: the "static"
    parameters of the coarse grid (``grid_levels`` values each). ``budget``: evaluations after
    the grid (annealing or CMA-ES). Annealing schedule: ``cooling`` per ``evals_per_T``
    simplex moves (1, 2 or n + 2 evaluations each, :mod:`vidsim.optim.anneal`), simplex ``step``/``min_step`` in the unit cube, reset at factor 3.
    ``method``: ``anneal`` or ``cmaes``; ``n_candidates``: best distinct points a fit hands to
    the cross-trial selection; ``estimate``: the names of ``space`` to estimate (empty = all; the
    rest stay at ``fixed`` or mid-range). Hydra merges dict overrides, so narrow the space with
    ``estimate=[...]`` and set known values with ``+cloth.fit.fixed.<name>=<value>``.
    """

    space: dict[str, Any] = field(default_factory=_default_space)
    fixed: dict[str, float] = field(default_factory=dict)
    grid_params: list[str] = field(default_factory=lambda: ["bend", "stretch", "shear"])
    grid_levels: int = 4
    budget: int = 600
    cooling: float = 0.9
    evals_per_T: int = 20
    step: float = 0.15
    min_step: float = 0.02
    cma_sigma0: float = 0.2
    alpha: float = 0.1
    seed: int = 0
    method: str = "anneal"
    n_candidates: int = 3
    estimate: list[str] = field(default_factory=list)
    footage: list[str] = field(default_factory=list)


@dataclass
class ClothSelectConfig:
    """``select_cloth``: inputs (Snakemake fills them: the trials' fit.yaml files and footage
    folders) and the optional joint polish of the selected set.

    ``polish_budget`` > 0: after the cross-trial selection, a short annealing on E1 + E2 (all trials
    at once) started at the selected set: temperature ``polish_t0`` times the selected E1 + E2,
    simplex edge ``polish_step`` in the unit cube, evaluations logged to ``polish_evals.jsonl`` in
    the output folder (a killed stage resumes). The polished set replaces the selection only if its
    E1 + E2 is lower. 0: the seed's procedure (selection only).
    """

    fits: list[str] = field(default_factory=list)
    footage: list[str] = field(default_factory=list)
    polish_budget: int = 0
    polish_t0: float = 0.02
    polish_step: float = 0.08


@dataclass
class ClothValidateConfig:
    """Inputs of ``validate_cloth``: per fabric its params.yaml and its held-out footage folder
    (same order), and the fabric names."""

    fabrics: list[str] = field(default_factory=list)
    params: list[str] = field(default_factory=list)
    footage: list[str] = field(default_factory=list)
    #: moved copies of every set (each of the nine parameters scaled by fixed draws of
    #: exp(N(0, chaos_sigma)), the same draws for every set: cloth.model.chaos_members' draws)
    #: scored beside the sets themselves: a column's win or loss is *decided* when the paired
    #: differences over the copies settle it, as the skirt matrix's fold-seeded starts do (0: no
    #: copies, every column undecided)
    chaos_draws: int = 8
    chaos_sigma: float = 1e-4


@dataclass
class ClothProfileConfig:
    """Error profiles (``profile_cloth``): ``points`` per parameter across its range; a parameter is
    *determined* when the range within ``tol`` (relative error rise) of the estimate is at most
    ``max_width`` of its range. ``reoptimise_evals``: 0 (the default) holds the other parameters at
    the estimate (a slice); > 0 re-optimises them at every grid point with that many annealing
    evaluations (a profile proper: a parameter another can make up for shows flat;
    :mod:`vidsim.clothfit.profile`), logged to ``evals.jsonl`` so a killed stage resumes.
    ``roughness_points`` (> 0; 8 by default, 0: off): the loss's roughness is measured at the
    estimate with that many evaluations 1e-3 away (unit cube), and "as good" widens to
    ``roughness_z`` of its standard deviations where that is more than ``tol``.
    ``params``/``footage``: inputs (Snakemake fills them)."""

    points: int = 7
    tol: float = 0.05
    max_width: float = 0.5
    reoptimise_evals: int = 0
    roughness_points: int = 8
    roughness_z: float = 2.0
    seed: int = 0
    params: str = ""
    footage: list[str] = field(default_factory=list)


@dataclass
class ClothTwinConfig:
    """Scoring of the twin reality (``score_cloth_twin``, reads the truth beside ``footage``): the
    twin's selected ``params.yaml`` (or a joint fit's ``fit.yaml``), its ``profile.yaml`` (optional:
    empty for none) and its held-out footage folder (Snakemake fills them).
    Targets (issue 5): held-out error within ``heldout_ratio`` of the true parameters' error,
    ``rel_tol`` relative error on the parameters named in ``rel_tol_params``.
    The scale of the held-out ratio on a chaotic motion: ``perturb_draws`` sets of the true
    parameters with every estimated one scaled by exp(N(0, ``perturb_sigma``)) (seed
    ``perturb_seed``) are scored the same way, and the estimate's ratio is compared with their
    90 % quantile (0 draws: off). The same ratio with each side averaged over its own chaos:
    ``chaos_draws`` copies of the estimate and of the truth, every estimated parameter scaled by
    the same draws of exp(N(0, ``chaos_sigma``)) (a change of 1e-4 is no change of fabric, but on
    the soft twin's held-out motion it moves the truth's own error by up to 13 %), the ratio of
    the two mean errors reported beside the single-run ratio (0 draws: off)."""

    params: str = ""
    profile: str = ""
    footage: str = ""
    heldout_ratio: float = 1.10
    chaos_sigma: float = 1e-4
    chaos_draws: int = 8
    rel_tol: float = 0.25
    rel_tol_params: list[str] = field(default_factory=lambda: ["bend", "shear"])
    perturb_sigma: float = 0.05
    perturb_draws: int = 50
    perturb_seed: int = 0


@dataclass
class ClothCompareConfig:
    """Inputs of ``compare_cloth`` (Snakemake fills them): per fabric its held-out footage, the
    annealing and CMA-ES selections (``params.yaml``), the joint fit (``fit.yaml``) and the fits'
    ``trace.csv`` files (per fabric its trials in order; one joint trace per fabric)."""

    fabrics: list[str] = field(default_factory=list)
    heldout: list[str] = field(default_factory=list)
    anneal: list[str] = field(default_factory=list)
    cmaes: list[str] = field(default_factory=list)
    joint: list[str] = field(default_factory=list)
    anneal_traces: list[str] = field(default_factory=list)
    cmaes_traces: list[str] = field(default_factory=list)
    joint_traces: list[str] = field(default_factory=list)
    #: moved copies of each method's estimate scored on the held-out footage (the fixed draws of
    #: cloth.model.chaos_members, the same for every method), to say whether the best method's lead
    #: is decided (paired t against every other method) or within the model's chaos (0: off)
    chaos_draws: int = 8
    chaos_sigma: float = 1e-4


@dataclass
class ClothSkirtConfig:
    """Skirt generalisation (seed Figure 9).

    Reality (``cloth.reality.object=skirt``) dresses the skipping body ``motion`` (a name of
    :data:`vidsim.reality.cloth.SKIRT_MOTIONS`) with a MuJoCo skirt of ``rings`` x ``around``
    vertices, filmed for ``n_frames`` at ``fps`` in the swatch's studio (same calibrated camera and
    projector). The estimator's skirt has ``model_rings`` x ``model_around`` vertices and the
    bending rest state ``model_rest_bend`` (``cone``: the sewn cone; ``flat``: the fabric's own flat
    rest state, the seam holding it in the cone). ``model_fold_members`` (> 0) fold-seeded starts
    with a radial seed of ``model_fold_amplitude`` m at the hem (seed ``model_fold_seed``): a skirt's
    error is the mean over them (the footage's fold pattern is a symmetry-breaking choice its known
    inputs do not give; :func:`vidsim.clothfit.rig.skirt_fold_starts`); 0: one start in the cone.
    ``video_frames``: frames of the side-by-side videos (0 = all). ``fabrics``/``params``/``footage``:
    inputs of ``skirt_cloth`` (Snakemake fills them): per fabric its ``params.yaml`` and skirt footage.
    """

    motion: str = "skip"
    n_frames: int = 40
    fps: float = 30.0
    rings: int = 9
    around: int = 28
    model_rings: int = 8
    model_around: int = 24
    model_rest_bend: str = "cone"
    model_fold_members: int = 8
    model_fold_amplitude: float = 0.02
    model_fold_seed: int = 0
    video_frames: int = 0
    fabrics: list[str] = field(default_factory=list)
    params: list[str] = field(default_factory=list)
    footage: list[str] = field(default_factory=list)


@dataclass
class ClothTable1Config:
    """Inputs of ``table1_cloth`` (Snakemake fills them): per fabric its selected ``params.yaml`` and
    its posterior ``summary.csv`` (same order as ``fabrics``)."""

    fabrics: list[str] = field(default_factory=list)
    params: list[str] = field(default_factory=list)
    summaries: list[str] = field(default_factory=list)


@dataclass
class ClothConfig:
    """Settings of the cloth stages."""

    enabled: bool = True
    camera: ClothCameraConfig = field(default_factory=ClothCameraConfig)
    projector: ClothProjectorConfig = field(default_factory=ClothProjectorConfig)
    calibration: ClothCalibrationConfig = field(default_factory=ClothCalibrationConfig)
    reality: ClothRealityConfig = field(default_factory=ClothRealityConfig)
    features: ClothFeaturesConfig = field(default_factory=ClothFeaturesConfig)
    model: ClothModelConfig = field(default_factory=ClothModelConfig)
    fit: ClothFitConfig = field(default_factory=ClothFitConfig)
    select: ClothSelectConfig = field(default_factory=ClothSelectConfig)
    validate: ClothValidateConfig = field(default_factory=ClothValidateConfig)
    skirt: ClothSkirtConfig = field(default_factory=ClothSkirtConfig)
    profile: ClothProfileConfig = field(default_factory=ClothProfileConfig)
    twin: ClothTwinConfig = field(default_factory=ClothTwinConfig)
    compare: ClothCompareConfig = field(default_factory=ClothCompareConfig)
    table1: ClothTable1Config = field(default_factory=ClothTable1Config)
