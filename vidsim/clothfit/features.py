"""Silhouettes and angle maps of striped cloth footage (what the metric compares).

Silhouettes come from the footage itself: a per-pixel background model learnt on the clip's
empty-scene frames (:mod:`vidsim.video.segment`), never from truth. Angle maps, their validity
and the gradient mask of seed eq. 11 come from :func:`vidsim.video.anglemap.angle_map`, tuned
to the stripe period seen by the camera. The same :func:`angle_features` is applied to the
estimator's simulated images, so footage and simulation are measured alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vidsim.errors import VidsimError
from vidsim.video.anglemap import SteerableBank, angle_map
from vidsim.video.segment import SegmentConfig, segment

__all__ = ["FeatureError", "FeatureSettings", "ClothFeatures", "angle_features", "extract_features"]


class FeatureError(VidsimError):
    """Bad input to feature extraction (names the field)."""


@dataclass(frozen=True)
class FeatureSettings:
    """Angle-map and segmentation settings.

    Attributes:
        period_px: stripe period the G2/H2 bank is tuned to, camera pixels (>= 3).
        tau: gradient-mask threshold, rad/px (> 0).
        min_strength: validity threshold relative to the frame's 99th-percentile strength.
        min_orientedness: validity threshold on strength / C1.
        k_sigma: segmentation threshold in robust noise scales.
        min_diff: segmentation threshold in digital numbers.
    """

    period_px: float = 6.5
    tau: float = 0.04
    min_strength: float = 0.03
    min_orientedness: float = 0.2
    k_sigma: float = 5.0
    min_diff: float = 12.0

    def __post_init__(self) -> None:
        if not self.period_px >= 3:
            raise FeatureError(f"features.period_px must be >= 3 camera pixels, got {self.period_px}")
        if not self.tau > 0:
            raise FeatureError(f"features.tau must be > 0 rad/px, got {self.tau}")
        if not (np.isfinite(self.min_strength) and self.min_strength >= 0):
            raise FeatureError(f"features.min_strength must be a fraction >= 0, got {self.min_strength}")
        if not (np.isfinite(self.min_orientedness) and 0 <= self.min_orientedness <= 1):
            raise FeatureError(f"features.min_orientedness must be in [0, 1], got {self.min_orientedness}")

    def bank(self) -> SteerableBank:
        return SteerableBank.for_period(self.period_px)


@dataclass
class ClothFeatures:
    """Per-frame features of a clip.

    Attributes:
        theta: (T, H, W) float32 stripe orientation, radians, NaN where undefined.
        mask: (T, H, W) bool gradient mask (eq. 11) inside the silhouette.
        sil: (T, H, W) bool silhouettes.
    """

    theta: np.ndarray
    mask: np.ndarray
    sil: np.ndarray

    def __post_init__(self) -> None:
        shapes = {self.theta.shape, self.mask.shape, self.sil.shape}
        if len(shapes) != 1 or self.theta.ndim != 3:
            raise FeatureError(f"theta, mask and sil must share one (T, H, W) shape, got {sorted(shapes)}")

    @property
    def n_frames(self) -> int:
        return int(self.theta.shape[0])

    def subset(self, idx: np.ndarray) -> "ClothFeatures":
        """The frames ``idx``."""
        return ClothFeatures(self.theta[idx], self.mask[idx], self.sil[idx])

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Compact arrays for :func:`vidsim.io.atomic.write_npz` (theta as float16)."""
        return {"theta": self.theta.astype(np.float16), "mask": np.packbits(self.mask, axis=-1),
                "sil": np.packbits(self.sil, axis=-1), "shape": np.array(self.theta.shape)}

    @classmethod
    def from_arrays(cls, d: dict) -> "ClothFeatures":
        """Inverse of :meth:`to_arrays`."""
        shape = tuple(int(x) for x in d["shape"])
        W = shape[2]
        return cls(np.asarray(d["theta"], np.float32), np.unpackbits(d["mask"], axis=-1, count=W).astype(bool),
                   np.unpackbits(d["sil"], axis=-1, count=W).astype(bool))


def angle_features(images: np.ndarray, sil: np.ndarray, settings: FeatureSettings
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Angle maps and gradient masks of striped images inside given silhouettes.

    Args:
        images: (T, H, W) grey or (T, H, W, 3) colour images (any linear or 8-bit scale).
        sil: (T, H, W) bool silhouettes (angles outside are undefined).
        settings: bank, thresholds.

    Returns:
        ``(theta (T, H, W) float32 rad, mask (T, H, W) bool)``.
    """
    imgs = np.asarray(images)
    if imgs.ndim == 4:
        imgs = imgs.astype(np.float32).mean(axis=3)
    if imgs.ndim != 3 or imgs.shape != np.asarray(sil).shape:
        raise FeatureError(f"images {np.asarray(images).shape} and silhouettes {np.asarray(sil).shape} do not match")
    bank = settings.bank()
    theta = np.empty(imgs.shape, np.float32)
    mask = np.zeros(imgs.shape, bool)
    for k in range(imgs.shape[0]):
        if not sil[k].any():
            theta[k] = np.nan
            continue
        am = angle_map(imgs[k], bank, min_strength=settings.min_strength,
                       min_orientedness=settings.min_orientedness, region=sil[k])
        theta[k] = am.theta
        mask[k] = am.mask(settings.tau) & sil[k]
    return theta, mask


def extract_features(frames: np.ndarray, background_frames: np.ndarray, settings: FeatureSettings
                     ) -> ClothFeatures:
    """Silhouettes (background model of the empty frames) and angle maps of the cloth frames.

    Args:
        frames: (T_all, H, W, 3) uint8 footage, the empty-scene frames included.
        background_frames: indices of the empty-scene frames (>= 3); features are returned for
            all other frames, in order.
        settings: thresholds.

    Returns:
        :class:`ClothFeatures` of the cloth frames.
    """
    f = np.asarray(frames)
    bg = np.asarray(background_frames, int)
    if f.ndim != 4 or f.dtype != np.uint8:
        raise FeatureError(f"frames must be (T, H, W, 3) uint8, got {f.dtype} {f.shape}")
    if bg.size < 3 or bg.min() < 0 or bg.max() >= f.shape[0]:
        raise FeatureError(f"meta.yaml background_frames must list >= 3 frame indices < {f.shape[0]}, got {bg.tolist()}")
    cloth = np.setdiff1d(np.arange(f.shape[0]), bg)
    cfg = SegmentConfig(k_sigma=settings.k_sigma, min_diff=settings.min_diff, keep="largest", gain=False,
                        mixed_fraction=0.5, open_px=1, close_px=2)
    sil_all = segment(f, cfg=cfg, background_frames=bg)
    sil = sil_all[cloth]
    theta, mask = angle_features(f[cloth], sil, settings)
    return ClothFeatures(theta, mask, sil)
