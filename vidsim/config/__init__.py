"""Hydra structured configs: registration in the ConfigStore, validation, camera building."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, ListConfig, OmegaConf

from vidsim.config.schema import GROUPS, VidsimConfig
from vidsim.errors import ConfigError
from vidsim.video.camera import PinholeCamera, intrinsics, look_at

CONF_DIR = str(Path(__file__).resolve().parents[2] / "conf")


def register() -> None:
    """Register the schemas: ``base_config`` and ``<group>/base_<group>``."""
    cs = ConfigStore.instance()
    cs.store(name="base_config", node=VidsimConfig)
    for group, node in GROUPS.items():
        cs.store(group=group, name=f"base_{group}", node=node)


register()


def _check(cond: bool, key: str, value: Any, expected: str) -> None:
    if not cond:
        raise ConfigError(f"config value {key} = {value!r} is not valid: expected {expected}")


def _finite(x: Any) -> bool:
    try:
        return all(math.isfinite(float(v)) for v in (x if isinstance(x, (list, tuple)) else [x]))
    except (TypeError, ValueError):
        return False


def validate(cfg: DictConfig) -> None:
    """Reject non-physical values (NaN, negative sizes, zero-length vectors) naming the key."""
    c = cfg.camera
    _check(c.width > 0 and c.height > 0, "camera.width/height", f"{c.width}x{c.height}", "positive image size")
    _check(_finite(c.fx) and c.fx > 0, "camera.fx", c.fx, "a focal length > 0 in pixels")
    _check(len(c.dist) == 5 and _finite(list(c.dist)), "camera.dist", list(c.dist), "5 finite coefficients k1 k2 p1 p2 k3")
    for k in ("eye", "target", "up"):
        _check(len(c[k]) == 3 and _finite(list(c[k])), f"camera.{k}", list(c[k]), "3 finite numbers (metres)")
    _check(np.linalg.norm(np.subtract(c.target, c.eye)) > 1e-6, "camera.target", list(c.target), "a point different from camera.eye")
    r = cfg.reality
    _check(r.n_frames > 0, "reality.n_frames", r.n_frames, "> 0")
    _check(_finite(r.fps) and r.fps > 0, "reality.fps", r.fps, "> 0 frames per second")
    _check(_finite(r.lead_in_s) and r.lead_in_s >= 0, "reality.lead_in_s", r.lead_in_s, "a finite time >= 0 s")
    rd = cfg.render
    _check(rd.backend in ("pyrender", "raster"), "render.backend", rd.backend, "'pyrender' or 'raster'")
    _check(_finite(rd.noise_sigma) and rd.noise_sigma >= 0, "render.noise_sigma", rd.noise_sigma, ">= 0")
    _check(0 <= rd.jpeg_quality <= 100, "render.jpeg_quality", rd.jpeg_quality, "0 (off) to 100")
    _check(_finite(rd.blur_sigma_px) and rd.blur_sigma_px >= 0, "render.blur_sigma_px", rd.blur_sigma_px, ">= 0 px (0: off)")
    _check(_finite(rd.light_intensity) and rd.light_intensity >= 0, "render.light_intensity", rd.light_intensity, ">= 0")
    for key, v in _leaves_named(cfg, "jpeg_quality"):  # every family's
        _check(0 <= v <= 100, key, v, "0 (off) to 100")
    for key, v in _leaves_named(cfg, "frame_stride"):
        _check(isinstance(v, int) and v >= 1, key, v, "a whole number >= 1 (every k-th footage frame)")
    for key, v in _leaves_named(cfg, "max_frames"):
        _check(v is None or (isinstance(v, int) and v >= 0), key, v, "a whole number >= 0 (0: all frames)")
    d = cfg.effects.dynamics
    for k in ("air_drag", "angular_drag", "magnus"):
        _check(_finite(d[k]) and d[k] >= 0, f"effects.dynamics.{k}", d[k], ">= 0")
    im = cfg.effects.imaging
    for k in ("exposure_s", "rolling_shutter_s", "time_jitter_s"):
        _check(_finite(im[k]) and im[k] >= 0, f"effects.imaging.{k}", im[k], ">= 0 s")
    _check(cfg.calibrate.n_views >= 3, "calibrate.n_views", cfg.calibrate.n_views, ">= 3 views")
    for key, v in _leaves_named(cfg, "noise_sigma"):  # every family's sensor noise
        _check(_finite(v) and v >= 0, key, v, ">= 0 (sensor noise, grey levels)")
    _validate_cloth_params(cfg)
    for key, v in _float_leaves(cfg):  # no setting means anything as NaN: a `< 0` check lets it through
        _check(not math.isnan(v), key, v, "a number (NaN given)")
    _check(cfg.calibrate.max_rms_px > 0, "calibrate.max_rms_px", cfg.calibrate.max_rms_px, "> 0 px (the gate on the "
           "calibration's reprojection error; .inf: no gate)")
    _check(cfg.calibrate.n_projector_views >= 3, "calibrate.n_projector_views", cfg.calibrate.n_projector_views, ">= 3 views")


def _leaves_named(node: Any, name: str, prefix: str = "") -> list[tuple[str, Any]]:
    """``(dotted key, value)`` of every leaf called ``name`` in a config tree."""
    found: list[tuple[str, Any]] = []
    if isinstance(node, DictConfig):
        for k in node.keys():
            if OmegaConf.is_missing(node, k):
                continue
            try:
                v = node[k]
            except Exception:  # an interpolation that only resolves elsewhere (e.g. ${hydra:...})
                continue
            key = f"{prefix}{k}"
            if k == name and not isinstance(v, (DictConfig, ListConfig)):
                found.append((key, v))
            elif isinstance(v, DictConfig):
                found += _leaves_named(v, name, key + ".")
    return found


def _float_leaves(node: Any, prefix: str = "") -> list[tuple[str, float]]:
    """``(dotted key, value)`` of every float leaf of a config tree (lists included)."""
    out: list[tuple[str, float]] = []
    if isinstance(node, DictConfig):
        items = []
        for k in node.keys():
            if OmegaConf.is_missing(node, k):
                continue
            try:
                items.append((f"{prefix}{k}", node[k]))
            except Exception:  # an interpolation that only resolves elsewhere (e.g. ${hydra:...})
                continue
    elif isinstance(node, ListConfig):
        items = [(f"{prefix.rstrip('.')}[{i}]", v) for i, v in enumerate(node)]
    else:
        return out
    for key, v in items:
        if isinstance(v, float):
            out.append((key, v))
        elif isinstance(v, (DictConfig, ListConfig)):
            out += _float_leaves(v, key + ".")
    return out


def _validate_cloth_params(cfg: DictConfig) -> None:
    """The cloth twin's known parameters: finite and non-negative, each named by its key."""
    tp = OmegaConf.select(cfg, "cloth.reality.twin_params")
    if tp is None:
        return
    from vidsim.cloth.params import PARAM_UNITS, ClothParams

    for k, v in tp.items():
        where = f"cloth.reality.twin_params.{k}"
        _check(k in PARAM_UNITS, where, k, f"one of {sorted(PARAM_UNITS)}")
        _check(isinstance(v, (int, float)) and _finite(v) and v >= 0, where, v, f">= 0 [{PARAM_UNITS[k]}]")
    try:
        ClothParams(**{k: v for k, v in tp.items() if k != "gravity"})
    except ValueError as e:
        raise ConfigError(f"cloth.reality.twin_params: {e}") from None


def camera_from_config(c: DictConfig | Any) -> PinholeCamera:
    """Build the reality's :class:`PinholeCamera` from a ``camera`` config node."""
    fy = c.fx if c.get("fy") is None else c.fy
    cx = (c.width - 1) / 2 if c.get("cx") is None else c.cx
    cy = (c.height - 1) / 2 if c.get("cy") is None else c.cy
    R, t = look_at(np.array(c.eye, float), np.array(c.target, float), np.array(c.up, float))
    roll = math.radians(c.get("roll_deg", 0.0) or 0.0)
    if roll:
        Rz = np.array([[math.cos(roll), -math.sin(roll), 0], [math.sin(roll), math.cos(roll), 0], [0, 0, 1]])
        R, t = Rz @ R, Rz @ t
    return PinholeCamera(intrinsics(c.fx, fy, cx, cy), R, t, c.width, c.height, np.array(c.dist, float))


def projector_from_config(p: DictConfig | Any) -> PinholeCamera:
    """The reality's projector (a pinhole, principal point at the centre) from a ``projector`` node."""
    R, t = look_at(np.array(p.eye, float), np.array(p.target, float), np.array(p.up, float))
    return PinholeCamera(intrinsics(p.fx, p.fx, (p.width - 1) / 2, (p.height - 1) / 2), R, t, p.width, p.height)


def to_plain(cfg: DictConfig) -> dict:
    """Resolved plain-python copy of a config node (for provenance in outputs)."""
    return OmegaConf.to_container(cfg, resolve=True)  # type: ignore[return-value]
