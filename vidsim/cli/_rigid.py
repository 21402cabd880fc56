"""Shared pieces of the rigid family's stages: config -> settings, reading the family's files.

File reading lives here (the CLI edge), never below ``vidsim/rigid``. Every error names the file.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from vidsim.errors import FootageError, VidsimError
from vidsim.rigid.body import BoxBody, RigidBodyError
from vidsim.rigid.fit import FitConfig, FitResult, Stage
from vidsim.rigid.outputs import fit_from_dict, masks_from_npz
from vidsim.video.segment import SegmentConfig


class RigidStageError(VidsimError):
    """A rigid stage's input is missing or malformed; the message names the file and field."""


def plain(node: Any) -> Any:
    """A Hydra node as plain Python containers."""
    return OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else node


def fit_config(f: DictConfig | dict, gravity: float) -> FitConfig:
    """The optimiser's :class:`FitConfig` from ``rigid.fit`` (pyramid capped at ``max_scale``,
    iteration counts times ``iter_scale``) and the known gravity magnitude (m/s^2)."""
    f = plain(f)
    base = FitConfig()

    def cap(stages: list[Stage]) -> list[Stage]:
        return [Stage(min(s.scale, float(f["max_scale"])), s.frames, max(1, int(round(s.maxiter * f["iter_scale"]))),
                      s.lam, s.ramp) for s in stages]

    return FitConfig.from_dict({
        "screen": cap(base.screen), "screen_keep": [int(k) for k in f["screen_keep"]],
        "refine": cap(base.refine), "final": cap(base.final), "final_ratio": float(f["final_ratio"]),
        "multistart": f["multistart"], "hmax": float(f["hmax"]), "distinct_deg": float(f["distinct_deg"]),
        "tie_iou": float(f["tie_iou"]), "dist_scale": float(f["dist_scale"]), "gravity": float(gravity)})


def segment_config(s: DictConfig | dict) -> SegmentConfig:
    """:class:`SegmentConfig` from ``rigid.segment`` (validated)."""
    sc = SegmentConfig(**plain(s))
    sc.validate()
    return sc


def ball_video(cfg: DictConfig, error: type[Exception]) -> Path:
    """The video file of the ball stages (``rigid_ball``, ``gap_ball``): ``rigid.paths.video``, else
    the shared data's ``rigid.ball.video``. They read one video (and fit the focal length themselves);
    a footage folder given as ``paths.footage`` was silently ignored, and one given as the video was
    reported missing."""
    from vidsim.io.paths import shared_data_dir

    if str(cfg.paths.get("footage") or ""):
        raise error(f"paths.footage = {cfg.paths.footage!r}: this stage reads a video file given as rigid.paths.video "
                    "(not a footage folder; its calibration is not used, the focal length is fitted)")
    video = Path(cfg.rigid.paths.video) if cfg.rigid.paths.video else shared_data_dir() / cfg.rigid.ball.video
    if video.is_dir():
        raise error(f"rigid.paths.video = {str(video)!r} is a folder: expected a video file (webm, mp4, ...)")
    if not video.is_file():
        raise error(f"{video}: the real toss clip is missing (rigid.paths.video / rigid.ball.video)")
    return video


def load_yaml(path: str | Path) -> Any:
    """A YAML file's content; a one-line error naming the file when missing or invalid."""
    from vidsim.io.footage import load_yaml as _load

    return _load(path, RigidStageError)


def read_masks(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(masks (N, H, W) bool, times (N,) s) of a segment stage's ``masks.npz``."""
    path = Path(path)
    if not path.is_file():
        raise RigidStageError(f"{path}: file is missing")
    try:
        with np.load(path) as z:
            return masks_from_npz({k: z[k] for k in z.files}, where=str(path))
    except RigidBodyError as e:
        raise RigidStageError(str(e)) from e
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as e:
        raise RigidStageError(f"{path}: not a readable .npz, truncated or not written by segment ({e})") from None


def read_fit(path: str | Path) -> tuple[FitResult, BoxBody]:
    """The fit and its body from a ``fit.yaml``."""
    d = load_yaml(path)
    try:
        res = fit_from_dict(d, where=str(path))
        body = BoxBody.from_meta(d.get("object"), where=f"{path}: object")
    except RigidBodyError as e:
        raise RigidStageError(str(e)) from e
    return res, body


def body_from_meta(meta: dict, where: str) -> tuple[BoxBody, float]:
    """The known body and gravity magnitude (m/s^2) from a footage's ``meta.yaml``."""
    if "object" not in meta:
        raise FootageError(f"{where}: missing field 'object' (shape, mass and inertia of the thrown body)")
    try:
        body = BoxBody.from_meta(meta["object"], where=f"{where}: object")
    except RigidBodyError as e:
        raise FootageError(str(e)) from e
    g = meta.get("gravity_magnitude", 9.81)
    try:
        g = float(g)
    except (TypeError, ValueError):
        raise FootageError(f"{where}: field 'gravity_magnitude' = {g!r} is not a number (m/s^2)") from None
    if not (np.isfinite(g) and g > 0):
        raise FootageError(f"{where}: field 'gravity_magnitude' = {g!r} is not physical: expected a finite "
                           "magnitude > 0 m/s^2 (9.81 on Earth)")
    return body, g


def log_image(lg: Any, entity: str, img: np.ndarray, jpeg_quality: int = 85) -> None:
    """Log an RGB image JPEG-compressed when recording for real (frames would make the .rrd huge)."""
    if type(lg).__name__ == "RerunLogger":
        rr = lg._rr
        lg.rec.log(entity, rr.Image(np.ascontiguousarray(img)).compress(jpeg_quality=jpeg_quality))
    else:
        lg.image(entity, img)
