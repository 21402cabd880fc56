"""Silhouettes of moving objects against a static background learnt from the footage itself.

Background model (per pixel, per channel): the temporal median of the clip (or of frames known to
be empty) and a robust noise scale, 1.4826 x the median absolute deviation, floored by
``min_sigma``. A moving object covers any one pixel in only a minority of frames, so both
statistics ignore it (this replaces the seed's autoregressive filters with an equally local but
outlier-proof model). A global gain per frame (the median ratio of frame to background) absorbs
webcam auto-exposure. A pixel is foreground when its difference from the gain-corrected
background exceeds ``k_sigma`` noise scales in some channel and ``min_diff`` digital numbers in
some channel (the two largest over the channels are tested, so they may come from different
channels).
Pixels on the rim of a mask are mixtures of object and background (a real sensor integrates over
the pixel): a rim pixel is kept only when its difference is at least half the object's contrast
seen in the nearby core (``mixed_fraction``), so that the silhouette boundary lies where the
object covers half the pixel. Masks are cleaned by a morphological opening and closing, holes are filled, and connected
components smaller than ``min_area`` pixels are dropped (``keep="largest"`` keeps only the
biggest one, for a single thrown object).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


class SegmentError(ValueError):
    """Bad input to the segmentation; the message names the field or value."""


@dataclass
class SegmentConfig:
    """Segmentation settings.

    Attributes:
        k_sigma: threshold in robust noise scales.
        min_diff: minimum absolute difference, digital numbers (0-255).
        min_sigma: floor of the per-pixel noise scale, digital numbers.
        open_px: radius of the opening (removes specks), pixels (0: none).
        close_px: radius of the closing (joins fragments), pixels (0: none).
        min_area: smallest kept component, pixels.
        keep: "largest" (one object) or "all".
        gain: compensate a global brightness gain per frame.
        mixed_fraction: rim pixels need this fraction of the nearby core contrast (0: off).
        clutter_fraction: pixels that are foreground in more than this fraction of the frames
            (vibrating edges, flicker) are treated as background clutter (1: off). A thrown
            object crosses any pixel in only a few frames.
        clutter_dilate: clutter is grown by this radius, pixels.
        max_area: components larger than this are dropped (0: no limit), pixels.
        max_model_frames: the background statistics use at most this many evenly spaced frames.
    """

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

    def validate(self) -> None:
        """Raise :class:`SegmentError` naming the field when a setting is unusable."""
        for name in ("k_sigma", "min_diff", "min_sigma"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise SegmentError(f"segment: '{name}' must be finite and >= 0, got {getattr(self, name)}")
        for name in ("open_px", "close_px", "min_area"):
            if int(getattr(self, name)) < 0:
                raise SegmentError(f"segment: '{name}' must be >= 0, got {getattr(self, name)}")
        if self.keep not in ("largest", "all"):
            raise SegmentError(f"segment: 'keep' must be 'largest' or 'all', got {self.keep!r}")
        if int(self.max_model_frames) < 3:
            raise SegmentError(f"segment: 'max_model_frames' must be >= 3, got {self.max_model_frames}")
        if not 0 < self.clutter_fraction <= 1:
            raise SegmentError(f"segment: 'clutter_fraction' must be in (0, 1], got {self.clutter_fraction}")


@dataclass
class BackgroundModel:
    """Per-pixel background: ``mean`` (H, W, C) and robust noise ``sigma`` (H, W, C), float32 DN."""

    mean: np.ndarray
    sigma: np.ndarray


def _check_frames(frames: np.ndarray) -> np.ndarray:
    f = np.asarray(frames)
    if f.ndim == 3:
        f = f[..., None]
    if f.ndim != 4 or f.shape[0] < 3:
        raise SegmentError(f"frames must be (T, H, W[, C]) with T >= 3, got shape {np.asarray(frames).shape}")
    return f


def fit_background(frames: np.ndarray, background_frames: np.ndarray | None = None,
                   cfg: SegmentConfig | None = None) -> BackgroundModel:
    """Learn the background from the clip.

    Args:
        frames: (T, H, W[, C]) uint8 footage.
        background_frames: optional indices of frames known to show only the background; by
            default all frames are used (the object moves, so the median ignores it).
        cfg: settings (``min_sigma``).

    Returns:
        :class:`BackgroundModel`.
    """
    cfg = cfg or SegmentConfig()
    f = _check_frames(frames)
    if background_frames is not None:
        idx = np.asarray(background_frames, int)
        if idx.size < 3 or idx.min() < 0 or idx.max() >= f.shape[0]:
            raise SegmentError(f"background_frames must hold >= 3 valid frame indices, got {idx.tolist()}")
        f = f[idx]
    if f.shape[0] > cfg.max_model_frames:  # evenly spaced subset: same statistics, less work
        f = f[np.linspace(0, f.shape[0] - 1, cfg.max_model_frames).round().astype(int)]
    med = np.median(f, axis=0).astype(np.float32)
    if cfg.gain:
        # the frames' exposure gains against a provisional median, divided out before the statistics: a
        # drifting auto-exposure otherwise counts as noise (half the frames at gain 1.15 gave sigma 16 DN
        # instead of the 2 DN floor, and a 100-DN object lost 12 % of its area; review, 5 Dec 2026)
        x = f.astype(np.float32)  # (T, H, W, C): _check_frames adds the channel axis
        g = np.array([_gain(x[k], med) for k in range(x.shape[0])], np.float32)
        if np.any(np.abs(g - 1.0) > 1e-3):
            fc = x / g[:, None, None, None]
            med = np.median(fc, axis=0).astype(np.float32)
            mad = np.median(np.abs(fc - med), axis=0).astype(np.float32)
            return BackgroundModel(med, np.maximum(1.4826 * mad, cfg.min_sigma).astype(np.float32))
    mad = np.median(np.abs(f.astype(np.int16) - med.round().astype(np.int16)), axis=0).astype(np.float32)
    return BackgroundModel(med, np.maximum(1.4826 * mad, cfg.min_sigma).astype(np.float32))


def _gain(x: np.ndarray, bg: np.ndarray) -> float:
    """A frame's exposure gain against the background: the median ratio over bright background pixels
    (every 4th row and column); 1 when there are none."""
    sub = (slice(None, None, 4), slice(None, None, 4))
    xs, bs = x[sub], bg[sub]
    sel = bs > 20
    return float(np.median(xs[sel] / bs[sel])) if np.any(sel) else 1.0


def _clean(mask: np.ndarray, cfg: SegmentConfig) -> np.ndarray:
    m = mask.astype(np.uint8)
    if cfg.open_px > 0:
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * cfg.open_px + 1,) * 2)
        m = cv2.morphologyEx(m, cv2.MORPH_OPEN, k)
    if cfg.close_px > 0:
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * cfg.close_px + 1,) * 2)
        m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, k)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
    areas = stats[1:, cv2.CC_STAT_AREA].copy()
    if cfg.max_area > 0:
        areas[areas > cfg.max_area] = 0
    keep = np.zeros(n, bool)
    if n > 1:
        if cfg.keep == "largest":
            j = int(np.argmax(areas))
            keep[1 + j] = areas[j] >= max(cfg.min_area, 1)
        else:
            keep[1:] = areas >= max(cfg.min_area, 1)
    out = keep[lab].astype(np.uint8)
    # fill holes: background not reachable from the border
    if out.any():
        inv = (1 - out).astype(np.uint8)
        n2, lab2 = cv2.connectedComponents(inv, connectivity=4)
        border = np.unique(np.concatenate([lab2[0], lab2[-1], lab2[:, 0], lab2[:, -1]]))
        holes = ~np.isin(lab2, border) & (inv > 0)
        out[holes] = 1
    return out.astype(bool)


def foreground_score(frame: np.ndarray, model: BackgroundModel, gain: bool = True) -> np.ndarray:
    """(H, W) largest per-channel |difference| / sigma and the (H, W) absolute difference, stacked (2, H, W)."""
    x = np.asarray(frame, np.float32)
    if x.ndim == 2:
        x = x[..., None]
    if x.shape != model.mean.shape:
        raise SegmentError(f"frame shape {x.shape} does not match the background model {model.mean.shape}")
    bg = model.mean
    if gain:
        bg = bg * _gain(x, bg)
    d = np.abs(x - bg)
    z = d / model.sigma
    zmax, dmax = z[..., 0], d[..., 0]
    for c in range(1, d.shape[-1]):
        zmax = np.maximum(zmax, z[..., c])
        dmax = np.maximum(dmax, d[..., c])
    return np.stack([zmax, dmax])


def segment(frames: np.ndarray, model: BackgroundModel | None = None, cfg: SegmentConfig | None = None,
            background_frames: np.ndarray | None = None) -> np.ndarray:
    """Binary silhouettes of the moving object(s).

    Args:
        frames: (T, H, W[, C]) uint8 footage.
        model: a background model (default: learnt from ``frames``).
        cfg: settings.
        background_frames: passed to :func:`fit_background` when ``model`` is None.

    Returns:
        (T, H, W) bool masks.
    """
    cfg = cfg or SegmentConfig()
    cfg.validate()
    f = _check_frames(frames)
    model = model or fit_background(f, background_frames, cfg)
    raw = np.zeros(f.shape[:3], bool)
    for k in range(f.shape[0]):
        z, d = foreground_score(f[k], model, cfg.gain)
        raw[k] = (z > cfg.k_sigma) & (d > cfg.min_diff)
    clutter = np.zeros(f.shape[1:3], bool)
    if cfg.clutter_fraction < 1.0:
        clutter = raw.mean(0) > cfg.clutter_fraction
        if cfg.clutter_dilate > 0:
            k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * cfg.clutter_dilate + 1,) * 2)
            clutter = cv2.dilate(clutter.astype(np.uint8), k) > 0
    out = np.zeros(f.shape[:3], bool)
    for k in range(f.shape[0]):
        m = _clean(raw[k] & ~clutter, cfg)
        if cfg.mixed_fraction > 0 and m.any():
            m = _rim_test(m, f[k], model, cfg)
        out[k] = m
    return out


def _rim_test(m: np.ndarray, frame: np.ndarray, model: BackgroundModel, cfg: SegmentConfig) -> np.ndarray:
    """Drop rim pixels covered by less than ``mixed_fraction`` of the object (by contrast)."""
    x = np.asarray(frame, np.float32)
    if x.ndim == 2:
        x = x[..., None]
    bg = model.mean * _gain(x, model.mean) if cfg.gain else model.mean  # the exposure foreground_score used
    mag = np.linalg.norm(x - bg, axis=-1)
    k3 = np.ones((3, 3), np.uint8)
    core = cv2.erode(m.astype(np.uint8), k3) > 0
    rim = m & ~core
    local = cv2.dilate(np.where(core, mag, 0).astype(np.float32), np.ones((5, 5), np.uint8))
    drop = rim & (local > 0) & (mag < cfg.mixed_fraction * local)
    out = m & ~drop
    return out


def mask_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-frame intersection over union of (T, H, W) bool masks; 1 where both are empty."""
    a = np.asarray(a, bool)
    b = np.asarray(b, bool)
    if a.shape != b.shape:
        raise SegmentError(f"mask shapes differ: {a.shape} vs {b.shape}")
    inter = (a & b).reshape(len(a), -1).sum(1)
    union = (a | b).reshape(len(a), -1).sum(1)
    return np.where(union > 0, inter / np.maximum(union, 1), 1.0)


def centroids(masks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel centroids (T, 2) (u, v; NaN where empty) and areas (T,) of (T, H, W) masks."""
    m = np.asarray(masks, bool)
    T = m.shape[0]
    c = np.full((T, 2), np.nan)
    area = m.reshape(T, -1).sum(1).astype(float)
    vv, uu = np.mgrid[0:m.shape[1], 0:m.shape[2]]
    for k in range(T):
        if area[k] > 0:
            c[k] = (uu[m[k]].mean(), vv[m[k]].mean())
    return c, area
