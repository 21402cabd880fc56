"""Stage-level drivers of the rigid-body pipeline (pure: arrays and dictionaries in, results out).

``reality -> footage -> segment -> fit -> report``: the CLI/Snakemake layer reads and writes the
files (:mod:`vidsim.io.footage`) and calls these with what it read.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vidsim.rigid.body import BoxBody, RigidBodyError
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
            ``initial_guess`` (the user's approximate initial state, see :func:`fit_throw`).
        guess: overrides ``meta['initial_guess']``.
        fit_cfg: optimiser settings; seg_cfg: segmentation settings.
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
    res = fit_throw(masks, times, cam, body, guess, fit_cfg)
    return ThrowEstimate(res, np.asarray(masks, bool))
