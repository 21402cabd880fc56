"""Shared plumbing of the cloth stages: footage folder -> :class:`~vidsim.clothfit.objective.Trial`,
config -> objective, parameter tables. File reading goes through :mod:`vidsim.io.footage` only.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from vidsim.cloth import ESTIMATED_NAMES, ClothParams
from vidsim.clothfit.features import FeatureSettings, extract_features
from vidsim.clothfit.objective import ClothObjective, ModelSettings, Trial, space_from_config
from vidsim.errors import VidsimError
from vidsim.io.footage import read_footage
from vidsim.render.projector import Projector

__all__ = ["ClothStageError", "feature_settings", "load_trial", "make_objective", "params_dict", "fixed_params"]

#: what a cloth footage folder's meta.yaml must give (known inputs)
REQUIRED_META = ("scene", "background_frames", "corner_paths", "size_m", "areal_density", "projector_pattern")


class ClothStageError(VidsimError):
    """A cloth stage's input is missing or inconsistent (names the file and field)."""


def feature_settings(cfg: DictConfig) -> FeatureSettings:
    """:class:`FeatureSettings` from ``cloth.features``."""
    return FeatureSettings(**OmegaConf.to_container(cfg.cloth.features, resolve=True))


def load_trial(folder: str | Path, cfg: DictConfig, name: str | None = None, with_frames: bool = False
               ) -> Trial | tuple[Trial, np.ndarray]:
    """Read a cloth footage folder and extract its features (silhouettes from the footage itself).

    Args:
        folder: footage folder written by ``reality_cloth`` (frames, times, calibration, meta).
        cfg: the stage config (``cloth.features``, ``cloth.model.frame_stride/max_frames``).
        name: trial label (default: the folder name).
        with_frames: also return the trial's (T, H, W, 3) uint8 footage frames (for logging).

    Returns:
        The (strided) trial with the *calibrated* camera and projector of the folder
        (and its frames with ``with_frames``).
    """
    fp = read_footage(folder, required_meta=REQUIRED_META)
    meta = fp.meta
    if meta["scene"] != "cloth":
        raise ClothStageError(f"{folder}/meta.yaml: scene = {meta['scene']!r}, expected 'cloth'")
    if "projector" not in fp.cameras:
        raise ClothStageError(f"{folder}/calibration.yaml: field 'projector' is missing (the cloth scene is lit by stripes)")
    bg = np.asarray(meta["background_frames"], int)
    cloth_idx = np.setdiff1d(np.arange(fp.frames.shape[0]), bg)
    cp = np.asarray(meta["corner_paths"], float)
    if cp.shape != (cloth_idx.size, 2, 3):
        raise ClothStageError(f"{folder}/meta.yaml: corner_paths has shape {cp.shape}, expected ({cloth_idx.size}, 2, 3)")
    pat = meta["projector_pattern"]
    proj = Projector(fp.cameras["projector"], period_px=float(pat["period_px"]), power=float(pat.get("power", 1.0)),
                     ambient=float(pat.get("ambient", 0.1)))
    fs = feature_settings(cfg)
    feats = extract_features(fp.frames, bg, fs)
    tr = Trial(name or Path(folder).name, feats, fp.times[cloth_idx], cp, fp.camera, proj, float(meta["size_m"]),
               float(meta["areal_density"]))
    stride, most = int(cfg.cloth.model.frame_stride), int(cfg.cloth.model.max_frames)
    if not with_frames:
        return tr.strided(stride, most)
    idx = np.arange(0, cloth_idx.size, max(1, stride))
    if most > 0:
        idx = idx[:most]
    return tr.strided(stride, most), fp.frames[cloth_idx[idx]]


def fixed_params(cfg: DictConfig) -> dict[str, float]:
    """``cloth.fit.fixed`` as floats."""
    return {k: float(v) for k, v in OmegaConf.to_container(cfg.cloth.fit.fixed, resolve=True).items()}


def make_objective(trials: list[Trial], cfg: DictConfig) -> ClothObjective:
    """The objective of ``cloth.fit``/``cloth.model`` over ``trials`` (errors summed)."""
    full = OmegaConf.to_container(cfg.cloth.fit.space, resolve=True)
    est = list(cfg.cloth.fit.estimate) or list(full)
    bad = [n for n in est if n not in full]
    if bad:
        raise ClothStageError(f"cloth.fit.estimate {bad} are not in cloth.fit.space {list(full)}")
    space = space_from_config({n: full[n] for n in est})
    m = cfg.cloth.model
    return ClothObjective(trials, space, fixed=fixed_params(cfg),
                          model=ModelSettings(resolution=int(m.resolution), settle_s=float(m.settle_s), integrator=str(m.integrator)),
                          features=feature_settings(cfg), alpha=float(cfg.cloth.fit.alpha))


def params_dict(p: ClothParams) -> dict[str, float]:
    """The nine estimated parameters (and the known density) of ``p`` as plain floats."""
    out = {n: float(getattr(p, n)) for n in ESTIMATED_NAMES}
    out["density"] = float(p.density)
    return out


def params_from_dict(d: dict[str, Any], where: str) -> ClothParams:
    """:class:`ClothParams` from a ``params`` mapping of a fit/params file (names the file)."""
    try:
        return ClothParams(**{k: float(v) for k, v in d.items()})
    except (TypeError, ValueError) as e:
        raise ClothStageError(f"{where}: params are not valid ({e})") from None
