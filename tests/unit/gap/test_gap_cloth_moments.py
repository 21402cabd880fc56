"""The cloth diagnosis's moment residual (``ClothDiagnoseConfig.residual = "moments"``).

Known answers: the moments of rectangles (area, centroid, the discrete uniform spreads
(n^2 - 1)/12, a shear's covariance), their exact response to a shift, and a model problem whose
observation is its own rendering (zero residual, a time-offset column that moves the centroid the
way the swatch moves). Small swatch as in test_gap_cloth_model.py: a few CPU seconds.
"""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.cloth import mid_range_params
from vidsim.gap.cloth_diagnose import (
    MOMENTS,
    ClothDiagnoseConfig,
    Problem,
    silhouette_moments,
)
from vidsim.gap.cloth_model import ClothGapError, ClothGapModel, ClothSetup
from vidsim.reality.cloth import corner_paths, swatch_motion
from vidsim.video.camera import PinholeCamera, intrinsics, look_at


def test_rectangle_moments_and_shift() -> None:
    a = np.zeros((2, 100, 200))
    a[0, 20:60, 50:150] = 1.0  # 40 rows x 100 columns
    a[1, 27:67, 41:141] = 1.0  # the same shifted by (-9, +7) px
    m = silhouette_moments(a, 0.5)
    s = 0.5
    assert m[0, 0] == pytest.approx(np.sqrt(4000) / s, rel=1e-12)
    assert m[0, 1] == pytest.approx(100.0 / s)  # pixel centres 50.5 .. 149.5
    assert m[0, 2] == pytest.approx(40.0 / s)
    assert m[0, 3] == pytest.approx(np.sqrt((100**2 - 1) / 12) / s, rel=1e-9)
    assert m[0, 4] == pytest.approx(np.sqrt((40**2 - 1) / 12) / s, rel=1e-9)
    assert m[0, 5] == pytest.approx(0.0, abs=1e-9)
    d = m[1] - m[0]
    np.testing.assert_allclose(d, [0.0, -9 / s, 7 / s, 0.0, 0.0, 0.0], atol=1e-9)


def test_sheared_parallelogram_has_positive_covariance_and_empty_frame_is_finite() -> None:
    a = np.zeros((2, 80, 80))
    for r in range(20, 60):
        a[0, r, 10 + (r - 20): 30 + (r - 20)] = 1.0  # rows shift right going down: x grows with y
    m = silhouette_moments(a, 1.0)
    assert m[0, 5] > 1.0
    assert np.all(np.isfinite(m[1])) and np.all(m[1] == 0.0)


def test_unknown_residual_is_named() -> None:
    with pytest.raises(ClothGapError, match="residual"):
        ClothDiagnoseConfig(residual="pixels").validate()


@pytest.fixture(scope="module")
def model() -> ClothGapModel:
    R, t = look_at(np.array([0.0, -1.6, 0.9]), np.array([0.0, 0.0, 0.85]), np.array([0.0, 0.0, 1.0]))
    cam = PinholeCamera(intrinsics(560.0, None, 159.5, 119.5), R, t, 320, 240, np.zeros(5))
    times = 0.37 + np.arange(12) / 30.0
    setup = ClothSetup(times, corner_paths(swatch_motion("exp1"), times), np.arange(0, 12, 2), cam, 0.3, 0.2,
                       resolution=6, settle_s=0.3)
    return ClothGapModel(setup, mid_range_params(density=0.2), ["bend", "stretch"], ("time_offset", "time_jitter"),
                         scale=0.5)


def test_moment_problem_on_its_own_rendering(model: ClothGapModel) -> None:
    th = np.zeros(model.n_params)
    th[: model.n_base] = model.theta0()[: model.n_base]
    obs, ok = model.render(th)
    assert ok
    roi = np.ones(obs.shape, bool)
    frames = np.arange(obs.shape[0])
    p = Problem(model, obs, roi, frames, {}, 1e-3, "moments")
    r = p.residual(th)
    assert r.shape == (len(frames) * len(MOMENTS),)
    assert np.max(np.abs(r)) < 1e-9
    assert np.max(p.gap_per_frame(th)) < 1e-9
    assert np.array_equal(p.row_frames(), np.repeat(frames, len(MOMENTS)))
    # a time offset moves each frame's centroid by the swatch's image velocity times the offset
    J = p.jacobian(th, r)
    col = J[:, model.slices["time_offset"].start].reshape(len(frames), len(MOMENTS))
    dt = 1e-3
    th2 = th.copy()
    th2[model.slices["time_offset"].start] = dt
    moved = p.residual(th2).reshape(len(frames), len(MOMENTS))
    # (first order: the soft outline's 1 px ramp bends the response over a 1 ms step, so a
    # tolerance of 5 % plus 2 % of the largest centroid motion)
    big = np.max(np.abs(moved[:, 1:3]))
    assert big > 0.1  # the swatch moves: the offset is visible
    np.testing.assert_allclose(col[:, 1:3] * dt, moved[:, 1:3], rtol=0.05, atol=0.02 * big)
    # time jitter: frame k's column only has frame k's rows
    jit = J[:, model.slices["time_jitter"]]
    for k in frames:
        rows = p.row_frames() != k
        assert np.all(jit[rows, k] == 0.0)
