"""The reality's sensor model (vidsim.reality.imaging.sensor): noise level, optical blur, JPEG and seeds,
against closed forms (review, 5 Dec 2026: it had no direct test)."""

from __future__ import annotations

import math

import numpy as np

from vidsim.reality.imaging import sensor


def test_noise_has_the_stated_level_and_follows_the_seed():
    img = np.full((300, 300, 3), 128, np.uint8)
    a = sensor(img, np.random.default_rng(5), noise_sigma=2.0, jpeg_quality=0)
    r = a.astype(float) - 128
    # rounding to whole digital numbers adds 1/12 DN^2 of variance: sqrt(4 + 1/12) = 2.02
    assert abs(r.mean()) < 0.02 and abs(r.std() - math.sqrt(4 + 1 / 12)) < 0.03
    assert np.array_equal(a, sensor(img, np.random.default_rng(5), noise_sigma=2.0, jpeg_quality=0))
    assert not np.array_equal(a, sensor(img, np.random.default_rng(6), noise_sigma=2.0, jpeg_quality=0))
    # no noise, no JPEG, no blur: the image itself
    assert np.array_equal(sensor(img, np.random.default_rng(0), noise_sigma=0.0, jpeg_quality=0), img)


def test_optical_blur_of_a_step_is_the_gaussian_cdf():
    w, sigma = 200, 3.0
    img = np.zeros((40, w, 3), np.uint8)
    img[:, w // 2:] = 255  # the edge lies between columns 99 and 100
    out = sensor(img, np.random.default_rng(0), noise_sigma=0.0, jpeg_quality=0, blur_sigma_px=sigma)[20, :, 0]
    for col in (90, 97, 100, 103, 110):
        d = col - (w // 2 - 0.5)  # distance of the pixel centre from the edge
        want = 255 * 0.5 * (1 + math.erf(d / (sigma * math.sqrt(2))))
        assert abs(out[col] - want) <= 1.5, (col, out[col], want)


def test_jpeg_loses_more_at_lower_quality():
    rng = np.random.default_rng(1)
    img = (rng.random((64, 64, 3)) * 255).astype(np.uint8)
    err = {q: np.abs(sensor(img, np.random.default_rng(0), 0.0, q).astype(float) - img).mean() for q in (95, 60, 20)}
    assert 0 < err[95] < err[60] < err[20]
