"""Pictures of flow fields: the colour-wheel coding of optical flow and arrow grids.

Colour coding (as in the Middlebury benchmark's figures, here in HSV form): hue is the flow
direction (0 deg = +x, i.e. to the right; image y points down), saturation the speed relative
to ``max_speed``, value 1. Pure arrays in, arrays out; figures are drawn by the stages.
"""

from __future__ import annotations

import cv2
import numpy as np


def flow_to_color(flow: np.ndarray, max_speed: float | None = None) -> np.ndarray:
    """Colour-code a flow field.

    Args:
        flow: ``(H, W, 2)`` px/frame; entries with ``|value| > 1e9`` (unknown) are drawn black.
        max_speed: speed of full saturation (px/frame); default the 99th percentile speed.

    Returns:
        ``(H, W, 3)`` uint8 RGB.
    """
    f = np.asarray(flow, dtype=np.float64)
    if f.ndim != 3 or f.shape[-1] != 2:
        raise ValueError(f"flow shape {f.shape}, expected (H, W, 2)")
    unknown = ~np.all(np.abs(f) < 1e9, axis=-1)
    f = np.where(unknown[..., None], 0.0, f)
    sp = np.hypot(f[..., 0], f[..., 1])
    if max_speed is None:
        max_speed = float(np.percentile(sp[~unknown], 99)) if (~unknown).any() else 1.0
    max_speed = max(float(max_speed), 1e-9)
    ang = (np.degrees(np.arctan2(f[..., 1], f[..., 0])) % 360.0) / 2.0  # OpenCV hue in [0, 180)
    hsv = np.stack([ang, np.clip(sp / max_speed, 0, 1) * 255.0, np.full_like(sp, 255.0)], -1).astype(np.uint8)
    rgb = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)
    rgb[unknown] = 0
    return rgb


def color_wheel(size: int = 64) -> np.ndarray:
    """``(size, size, 3)`` uint8 legend: the colour of each flow vector inside the unit disc
    (speed 1 = full saturation at the rim), white-black outside."""
    c = (size - 1) / 2.0
    yy, xx = np.mgrid[0:size, 0:size]
    f = np.stack([(xx - c) / c, (yy - c) / c], -1)
    img = flow_to_color(f, 1.0)
    img[np.hypot(f[..., 0], f[..., 1]) > 1.0] = 255
    return img


def arrow_grid(field: np.ndarray, step: int, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Arrows of a field sampled every ``step`` pixels (cell centres).

    Args:
        field: ``(H, W, 2)`` px/frame.
        step: spacing in pixels (>= 1).
        scale: arrow length per px/frame.

    Returns:
        origins ``(N, 2)`` (x, y) px and vectors ``(N, 2)`` px.
    """
    if step < 1:
        raise ValueError(f"step={step}, expected >= 1")
    H, W = field.shape[:2]
    ys, xs = np.mgrid[step // 2:H:step, step // 2:W:step]
    o = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    v = np.asarray(field, np.float64)[ys.ravel(), xs.ravel()] * scale
    return o, v
