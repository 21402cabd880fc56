"""The cloth footage's motion blur: an exposure centred on the frame's time (as the rigid reality's
and the gap diagnosis's motion-blur candidate are), so blurred footage carries no time offset."""

from __future__ import annotations

import numpy as np
from omegaconf import OmegaConf

from vidsim.clothfit.film import FilmSettings, film_cloth
from vidsim.config import camera_from_config, projector_from_config
from vidsim.config.cloth import ClothConfig
from vidsim.render.projector import Projector


def _centroid_x(img: np.ndarray) -> float:
    m = img.astype(float).sum(axis=2) > 30  # the lit swatch against the dark backdrop
    return float(np.nonzero(m)[1].mean())


def test_blur_is_centred_on_the_frame_time():
    cfg = OmegaConf.structured(ClothConfig())
    cam = camera_from_config(cfg.camera)
    pc = projector_from_config(cfg.projector)
    proj = Projector(pc, period_px=cfg.projector.period_px, power=cfg.projector.power, ambient=cfg.projector.ambient)
    # a flat 0.3 m square (two triangles) at the swatch's place, moving sideways 2 cm per frame: a
    # one-sided exposure of 0.8 frame would shift the blurred silhouette by 0.4 of a frame's step
    sq = np.array([[-0.15, 0.0, 0.85], [0.15, 0.0, 0.85], [0.15, 0.0, 1.15], [-0.15, 0.0, 1.15]])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    shift = np.array([[0.02 * k, 0.0, 0.0] for k in range(6)])
    V = sq[None] + shift[:, None, :]
    quiet = dict(n_background=3, noise_sigma=0.0, blur_sigma_px=0.0)
    sharp = film_cloth(V, F, cam, proj, np.random.default_rng(0), FilmSettings(**quiet))[3:]
    blur = film_cloth(V, F, cam, proj, np.random.default_rng(0), FilmSettings(motion_blur=5, exposure=0.8, **quiet))[3:]
    step = _centroid_x(sharp[3]) - _centroid_x(sharp[2])  # about 3 px per frame at this distance
    assert abs(step) > 2.0
    for k in range(6):  # interior frames and both ends (extrapolated there) alike
        assert abs(_centroid_x(blur[k]) - _centroid_x(sharp[k])) < 0.1 * abs(step), k
    # and it is blurred: its edge spreads over about 0.8 of the step
    assert not np.array_equal(blur[3], sharp[3])
