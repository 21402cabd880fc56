"""Hydra schema of the ``rigid`` config group (conf/rigid/*.yaml extend it).

The rigid family's stages (``reality_rigid -> segment -> fit_rigid -> score_rigid``, plus
``rigid_summary`` and the real ``rigid_ball``) read their settings from ``cfg.rigid``; the reality
effects of a throw come from the project's ``effects`` group (``effects.dynamics.air_drag=1``
...). Units are SI unless a name says otherwise (``_deg``, ``_px``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from vidsim.errors import ConfigError


@dataclass
class RigidSceneConfig:
    """The synthetic throw reality films (see :class:`vidsim.reality.rigid.RigidRealityConfig`).

    Attributes:
        n_frames: frames of the throw; n_background: background-only frames before it.
        fps: nominal frame rate, Hz.
        width, height: image size, pixels; focal: focal length, pixels.
        distance: camera to the middle of the trajectory, metres.
        max_tilt_deg, max_roll_deg: camera pitch and roll relative to gravity, uniform in +-, degrees.
        spin_min, spin_max: range of the initial spin magnitude, rad/s.
        noise_sigma: sensor noise, digital numbers; jpeg_quality: 0 disables compression.
    """

    n_frames: int = 40
    n_background: int = 30
    fps: float = 30.0
    width: int = 640
    height: int = 480
    focal: float = 640.0
    distance: float = 3.2
    max_tilt_deg: float = 8.0
    max_roll_deg: float = 8.0
    spin_min: float = 4.0
    spin_max: float = 10.0
    noise_sigma: float = 2.0
    jpeg_quality: int = 90


@dataclass
class RigidGuessConfig:
    """Protocol that makes ``meta.initial_guess`` from the truth: the stand-in for the user's rough guess.

    Each quantity is moved from the truth by the stated amount in a random direction (generator
    seeded by ``rigid.seed + 1000003``, independent of the throw's own randomness).

    Attributes:
        orient_deg: rotation of the orientation, degrees.
        omega_rel: angular velocity error, fraction of |omega|.
        vel_rel: linear velocity error, fraction of |v|.
        pos_m: position error, metres.
        grav_deg: gravity direction error, degrees.
    """

    orient_deg: float = 30.0
    omega_rel: float = 0.3
    vel_rel: float = 0.2
    pos_m: float = 0.1
    grav_deg: float = 10.0


@dataclass
class RigidSegmentConfig:
    """Segmentation settings (:class:`vidsim.video.segment.SegmentConfig`, same names and units)."""

    k_sigma: float = 5.0
    min_diff: float = 18.0
    min_sigma: float = 2.0
    open_px: int = 1
    close_px: int = 2
    min_area: int = 20
    keep: str = "largest"
    gain: bool = True
    mixed_fraction: float = 0.5
    clutter_fraction: float = 1.0
    clutter_dilate: int = 2
    max_area: int = 0
    max_model_frames: int = 35


@dataclass
class RigidFitConfig:
    """Optimiser settings (:class:`vidsim.rigid.fit.FitConfig`) with two coarse knobs for budgets.

    Attributes:
        multistart: "icosahedral" (orientations of the icosahedral group around the guess) or "none".
        screen_keep: starts kept after each screening stage (two stages).
        final_ratio: candidates within this factor of the best cost get the full-resolution polish.
        hmax: RK4 step bound, seconds.
        distinct_deg: two solutions differing by more than this (modulo symmetry) are distinct, degrees.
        tie_iou: solutions whose mean IoU differ by less than this are equally good.
        dist_scale: distance normaliser of the smoothed silhouette term, pixels.
        max_scale: finest pyramid level used (1 = full resolution; 0.5 halves the cost of the polish).
        iter_scale: multiplies every stage's iteration count.
    """

    multistart: str = "icosahedral"
    screen_keep: list[int] = field(default_factory=lambda: [8, 3])
    final_ratio: float = 1.3
    hmax: float = 1.0 / 60.0
    distinct_deg: float = 10.0
    tie_iou: float = 0.01
    dist_scale: float = 20.0
    max_scale: float = 1.0
    iter_scale: float = 1.0


@dataclass
class RigidBallConfig:
    """The real ball toss (``rigid_ball`` stage): segmentation and tracking of a small ball.

    Attributes:
        video: path of the clip relative to the shared data folder.
        nominal_fps: the constant frame rate compared with the container's timestamps, Hz.
        min_area, max_area: blob area range, pixels; min_fill: blob area / circle of its box.
        max_jump: largest centroid step per frame, pixels.
        min_flight: fewest detections of one free flight.
        focal_guess: initial focal length of the perspective fit, pixels.
        segment: segmentation of the small ball (no opening, clutter map on, all components kept).
    """

    video: str = "tracklab_physics/verticalToss.webm"
    nominal_fps: float = 30.0
    min_area: int = 15
    max_area: int = 600
    min_fill: float = 0.6
    max_jump: float = 90.0
    min_flight: int = 6
    focal_guess: float = 600.0
    segment: RigidSegmentConfig = field(default_factory=lambda: RigidSegmentConfig(
        min_area=4, open_px=0, close_px=1, mixed_fraction=0.0, clutter_fraction=0.1, keep="all", max_area=600))


@dataclass
class RigidPathsConfig:
    """Extra inputs of the rigid stages (empty: the stage's default named below).

    Attributes:
        masks: ``masks.npz`` of the segment stage (default ``<paths.out>/masks.npz``).
        fit: ``fit.yaml`` of the fit stage (default ``<paths.out>/fit.yaml``).
        scores: ``score.yaml`` files collected by ``rigid_summary`` (space separated).
        video: the real clip of ``rigid_ball`` (default ``<shared data>/<rigid.ball.video>``).
    """

    masks: str = ""
    fit: str = ""
    scores: str = ""
    video: str = ""


@dataclass
class RigidConfig:
    """Settings of the rigid stages.

    Attributes:
        enabled: the family's switch for Hydra users (Snakemake uses ``stages.rigid``).
        seed: the throw's seed (truth, texture, noise); one case of the study.
        reality: the synthetic scene; guess: the initial-guess protocol.
        segment: silhouettes; fit: the optimiser; ball: the real toss; paths: extra inputs.
        overlay: format of the fit's overlay animation, "mp4" (H.264) or "gif".
    """

    enabled: bool = True
    seed: int = 0
    reality: RigidSceneConfig = field(default_factory=RigidSceneConfig)
    guess: RigidGuessConfig = field(default_factory=RigidGuessConfig)
    segment: RigidSegmentConfig = field(default_factory=RigidSegmentConfig)
    fit: RigidFitConfig = field(default_factory=RigidFitConfig)
    ball: RigidBallConfig = field(default_factory=RigidBallConfig)
    paths: RigidPathsConfig = field(default_factory=RigidPathsConfig)
    overlay: str = "mp4"


def _bad(key: str, value: Any, expected: str) -> ConfigError:
    return ConfigError(f"config value rigid.{key} = {value!r} is not valid: expected {expected}")


def _pos(v: Any) -> bool:
    try:
        return math.isfinite(float(v)) and float(v) > 0
    except (TypeError, ValueError):
        return False


def validate_rigid(r: Any) -> None:
    """Reject non-physical ``rigid.*`` values (a DictConfig or a :class:`RigidConfig`), naming the key."""
    sc = r.reality
    for k in ("n_frames", "fps", "width", "height", "focal", "distance", "spin_max"):
        if not _pos(getattr(sc, k)):
            raise _bad(f"reality.{k}", getattr(sc, k), "> 0")
    if sc.n_background < 0:
        raise _bad("reality.n_background", sc.n_background, ">= 0 frames")
    if not 0 <= sc.spin_min <= sc.spin_max:
        raise _bad("reality.spin_min", sc.spin_min, f"0 <= spin_min <= spin_max ({sc.spin_max}) rad/s")
    g = r.guess
    for k in ("orient_deg", "omega_rel", "vel_rel", "pos_m", "grav_deg"):
        v = getattr(g, k)
        if not (math.isfinite(float(v)) and float(v) >= 0):
            raise _bad(f"guess.{k}", v, ">= 0")
    f = r.fit
    if f.multistart not in ("icosahedral", "none"):
        raise _bad("fit.multistart", f.multistart, "'icosahedral' or 'none'")
    if len(f.screen_keep) != 2 or min(f.screen_keep) < 1:
        raise _bad("fit.screen_keep", list(f.screen_keep), "two counts >= 1")
    for k in ("hmax", "max_scale", "iter_scale", "final_ratio", "dist_scale"):
        if not _pos(getattr(f, k)):
            raise _bad(f"fit.{k}", getattr(f, k), "> 0")
    if f.max_scale > 1:
        raise _bad("fit.max_scale", f.max_scale, "<= 1 (full resolution)")
    if r.overlay not in ("gif", "mp4"):
        raise _bad("overlay", r.overlay, "'gif' or 'mp4'")
    if not _pos(r.ball.nominal_fps):
        raise _bad("ball.nominal_fps", r.ball.nominal_fps, "> 0 Hz")
