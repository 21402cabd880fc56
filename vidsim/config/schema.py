"""Hydra structured-config schemas.

Every YAML file under ``conf/`` extends one of these dataclasses, so a misspelt key or a
value of the wrong type is an error that names the key (Hydra/OmegaConf struct mode), and
:func:`validate` rejects non-physical values with a :class:`~vidsim.errors.ConfigError`
naming the key. Units are SI unless a name says otherwise (``_px``, ``_deg``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional

from omegaconf import MISSING

from vidsim.config.cloth import ClothConfig
from vidsim.config.fluid import FluidConfig
from vidsim.config.gap import GapConfig
from vidsim.config.posterior import PosteriorConfig
from vidsim.config.rigid import RigidConfig


def _v3(*x: float):
    return field(default_factory=lambda: list(x))


@dataclass
class CameraConfig:
    """The (reality's) camera: intrinsics in pixels, pose by eye/target/up in metres.

    ``roll_deg`` rolls the camera about its optical axis; with ``eye``/``target`` it sets the
    camera's orientation relative to gravity, which the estimators do not know.
    """

    width: int = 640
    height: int = 480
    fx: float = 700.0
    fy: Optional[float] = None
    cx: Optional[float] = None
    cy: Optional[float] = None
    dist: list[float] = _v3(0.0, 0.0, 0.0, 0.0, 0.0)
    eye: list[float] = _v3(0.0, -3.5, 1.0)
    target: list[float] = _v3(0.0, 0.0, 1.0)
    up: list[float] = _v3(0.0, 0.0, 1.0)
    roll_deg: float = 0.0


@dataclass
class ProjectorConfig:
    """Structured-light projector (a second pinhole) casting horizontal stripes."""

    enabled: bool = False
    width: int = 800
    height: int = 600
    fx: float = 900.0
    eye: list[float] = _v3(0.4, -2.0, 1.3)
    target: list[float] = _v3(0.0, 0.0, 1.0)
    up: list[float] = _v3(0.0, 0.0, 1.0)
    period_px: float = 16.0
    power: float = 1.0
    ambient: float = 0.15


@dataclass
class DynamicsEffects:
    """Physical effects reality can switch on (0 = off). The models never contain them by default."""

    # rigid reality: multiplier of MuJoCo's blunt, slender and Kutta fluid coefficients (1 = its defaults); the
    # air itself (1.2 kg/m^3, with its added mass) is on whenever air_drag, angular_drag or magnus is above 0
    air_drag: float = 0.0
    angular_drag: float = 0.0  # multiplier of MuJoCo's rotational fluid drag
    magnus: float = 0.0  # multiplier of the Magnus lift coefficient
    wind: list[float] = _v3(0.0, 0.0, 0.0)  # m/s, world frame
    com_offset: list[float] = _v3(0.0, 0.0, 0.0)  # m, body frame, vs. what meta.yaml says
    gravity_tilt_deg: float = 0.0  # not made by the rigid reality (refused there when not 0)


@dataclass
class ImagingEffects:
    """Camera imperfections reality can switch on (0 = off), unknown to the calibration."""

    lens_k1: float = 0.0  # extra radial distortion the calibration does not know
    exposure_s: float = 0.0  # finite exposure -> motion blur
    rolling_shutter_s: float = 0.0  # readout time top -> bottom row
    time_jitter_s: float = 0.0  # std. dev. of frame-time jitter
    time_offset_s: float = 0.0  # constant offset of the frame clock (demo scene; refused by the rigid reality)


@dataclass
class EffectsConfig:
    dynamics: DynamicsEffects = field(default_factory=DynamicsEffects)
    imaging: ImagingEffects = field(default_factory=ImagingEffects)


@dataclass
class RenderConfig:
    """How footage is imaged: sensor noise (digital numbers, 0-255), compression, blur."""

    backend: str = "pyrender"  # pyrender | raster
    noise_sigma: float = 2.0
    jpeg_quality: int = 92  # 0 disables compression
    blur_sigma_px: float = 0.0
    light_intensity: float = 3.0


@dataclass
class LogConfig:
    rerun: bool = True
    progress: bool = True
    level: str = "INFO"


@dataclass
class RealityConfig:
    """What the stand-in for the real world films."""

    kind: str = "demo"  # demo | rigid | cloth | fluid
    n_frames: int = 40
    fps: float = 30.0
    lead_in_s: float = 1.0  # background-only frames before the action
    seed: int = 0


@dataclass
class RealChessboardConfig:
    """``calibrate_real``: a folder of real chessboard photos. The defaults are OpenCV's sample set
    (``left*`` images, 9x6 inner corners, 25 mm squares, the aspect ratio fixed as in OpenCV's
    reference run), which is then compared with OpenCV's reference result."""

    glob: str = "left*"  # which images of paths.footage (jpg/png/bmp/tif among them)
    board: list[int] = field(default_factory=lambda: [9, 6])  # inner corners per row, per column
    square_size: float = 0.025  # m
    fix_aspect: bool = True  # CALIB_FIX_ASPECT_RATIO (fx = fy)
    compare_reference: Optional[bool] = None  # None: only for OpenCV's own set (the defaults above)


@dataclass
class CalibrateConfig:
    """Calibration stage: a planar target filmed at several poses."""

    n_views: int = 12  # camera views besides the reference view
    n_projector_views: int = 16  # views with the projector's pattern (when projector.enabled)
    noise_sigma: float = 2.0
    max_rms_px: float = 0.5  # the stage fails loudly above this
    # The printed target: square side (m; the board's blank projector area scales with it) and
    # the origin of the reference board in the world (m; board x along world x, rows down -z,
    # facing -y). The defaults suit the 3.5 m demo camera; a close-up scene needs its own.
    square_size: float = 0.08
    target_origin: list[float] = _v3(-0.9, 0.3, 1.6)
    projector_square_px: int = 28  # checker square the projector casts, projector pixels
    # where the projector casts its checker in each projector view: 0 always at the image's centre
    # (its intrinsics then poorly determined), > 0 a 3 x 3 grid of positions reaching this fraction
    # of the way to the image's edges (docs/cloth_study.md, "Studio design")
    projector_pattern_spread: float = 0.5
    target_blank_width: Optional[float] = None  # m, blank area right of the print (None: scaled default)
    # calibration stills taken at this multiple of the video resolution (a camera's still mode;
    # the result is scaled back to the video frames): small video frames cannot resolve the target
    still_scale: float = 1.0
    real: RealChessboardConfig = field(default_factory=RealChessboardConfig)


@dataclass
class CheckConfig:
    """``check_footage`` stage: what a footage folder must provide."""

    required_meta: list[str] = field(default_factory=list)


@dataclass
class PathsConfig:
    """Inputs and outputs of one stage invocation (Snakemake fills these in)."""

    results: str = "results"
    footage: str = ""
    calibration: str = ""
    out: str = MISSING


@dataclass
class VidsimConfig:
    """The whole configuration tree every stage sees."""

    camera: CameraConfig = field(default_factory=CameraConfig)
    projector: ProjectorConfig = field(default_factory=ProjectorConfig)
    reality: RealityConfig = field(default_factory=RealityConfig)
    effects: EffectsConfig = field(default_factory=EffectsConfig)
    render: RenderConfig = field(default_factory=RenderConfig)
    log: LogConfig = field(default_factory=LogConfig)
    calibrate: CalibrateConfig = field(default_factory=CalibrateConfig)
    rigid: RigidConfig = field(default_factory=RigidConfig)
    cloth: ClothConfig = field(default_factory=ClothConfig)
    fluid: FluidConfig = field(default_factory=FluidConfig)
    posterior: PosteriorConfig = field(default_factory=PosteriorConfig)
    gap: GapConfig = field(default_factory=GapConfig)
    check: CheckConfig = field(default_factory=CheckConfig)
    paths: PathsConfig = field(default_factory=PathsConfig)
    seed: int = 0


GROUPS = {
    "camera": CameraConfig,
    "projector": ProjectorConfig,
    "reality": RealityConfig,
    "effects": EffectsConfig,
    "render": RenderConfig,
    "log": LogConfig,
    "calibrate": CalibrateConfig,
    "rigid": RigidConfig,
    "cloth": ClothConfig,
    "fluid": FluidConfig,
    "posterior": PosteriorConfig,
    "gap": GapConfig,
}
