"""Stage-level drivers of the rigid-body pipeline (pure: arrays and dictionaries in, results out).

``reality -> footage -> segment -> fit -> report``: the CLI/Snakemake layer reads and writes the
files (:mod:`vidsim.io.footage`) and calls these with what it read.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from vidsim.rigid.body import BoxBody, RigidBodyError
from vidsim.rigid.dynamics import G_EARTH
from vidsim.rigid.fit import FitConfig, FitResult, fit_throw
from vidsim.video.camera import PinholeCamera
from vidsim.video.segment import SegmentConfig, segment


@dataclass
class ThrowEstimate:
    """Result of :func:`estimate_throw`: the fit and the silhouettes it was fitted to."""

    fit: FitResult
    masks: np.ndarray


def estimate_throw(frames: np.ndarray, times: np.ndarray, cam: PinholeCamera, meta: dict,
                   guess: dict | None = None, fit_cfg: FitConfig | dict | None = None,
                   seg_cfg: SegmentConfig | dict | None = None, masks: np.ndarray | None = None
                   ) -> ThrowEstimate:
    """Segment a throw's footage and fit the free-flight model to its silhouettes.

    Args:
        frames: (N, H, W, 3) uint8 footage (ignored when ``masks`` is given).
        times: (N,) frame times, seconds.
        cam: the calibrated camera (the world frame of the estimate).
        meta: the footage's ``meta.yaml``: ``object`` (body description, required) and optionally
            ``initial_guess`` (the user's approximate initial state, see :func:`fit_throw`) and
            ``gravity_magnitude`` (m/s^2: the fit's known ``|g|``; absent: ``fit_cfg``'s, 9.81 by default).
        guess: overrides ``meta['initial_guess']``.
        fit_cfg: optimiser settings; seg_cfg: segmentation settings. Their ``gravity`` is set
            from ``meta['gravity_magnitude']``; giving a different one in ``fit_cfg`` is an error
            (a :class:`FitConfig` still holding the default 9.81 counts as not giving one).
        masks: precomputed silhouettes (the output of the segment stage), (N, H, W) bool.

    Returns:
        :class:`ThrowEstimate`.
    """
    if not isinstance(meta, dict) or "object" not in meta:
        raise RigidBodyError("meta: field 'object' (shape, mass, inertia of the thrown body) is missing")
    body = BoxBody.from_meta(meta["object"], where="meta.object")
    guess = guess if guess is not None else meta.get("initial_guess")
    if guess is None:
        raise RigidBodyError("no initial guess: give 'initial_guess' in meta.yaml or the guess argument "
                             "(position, quaternion, velocity, omega_world, tilt, roll, t0)")
    if masks is None:
        sc = seg_cfg if isinstance(seg_cfg, SegmentConfig) else SegmentConfig(**(seg_cfg or {}))
        masks = segment(frames, cfg=sc)
    res = fit_throw(masks, times, cam, body, guess, _with_meta_gravity(fit_cfg, meta))
    return ThrowEstimate(res, np.asarray(masks, bool))


def _with_meta_gravity(fit_cfg: FitConfig | dict | None, meta: dict) -> FitConfig:
    """``fit_cfg`` as a :class:`FitConfig` whose ``gravity`` is the footage's ``gravity_magnitude``
    (it was ignored: a Moon throw was fitted with 9.81 m/s^2)."""
    cfg = fit_cfg if isinstance(fit_cfg, FitConfig) else FitConfig.from_dict(fit_cfg)
    if "gravity_magnitude" not in meta:
        return cfg
    g = meta["gravity_magnitude"]
    try:
        if isinstance(g, bool):
            raise TypeError
        g = float(g)
    except (TypeError, ValueError):
        raise RigidBodyError(f"meta: 'gravity_magnitude' must be a number (m/s^2), got {g!r}") from None
    if not (np.isfinite(g) and g > 0):
        raise RigidBodyError(f"meta: 'gravity_magnitude' must be a finite magnitude > 0 m/s^2 (9.81 on Earth), got {g}")
    if isinstance(fit_cfg, FitConfig):
        given = None if fit_cfg.gravity == G_EARTH else fit_cfg.gravity
    else:
        given = None if not fit_cfg or "gravity" not in fit_cfg else cfg.gravity
    if given is not None and given != g:
        raise RigidBodyError(f"fit config: 'gravity' = {given} m/s^2 contradicts meta 'gravity_magnitude' = {g} m/s^2 "
                             "(the footage's known value): give one of them")
    return replace(cfg, gravity=g)
