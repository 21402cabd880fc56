"""Angle maps (G2/H2 steerable filters) and the cloth metric against known answers."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.video.anglemap import (
    AngleMapError,
    SteerableBank,
    angle_gradient,
    angle_map,
    cloth_metric,
    energy_coefficients,
    gradient_mask,
    wrap_half_pi,
)

H, W = 120, 160
YY, XX = np.mgrid[0:H, 0:W].astype(float)


def stripes(phi: float, period: float, rng: np.random.Generator, noise: float = 0.1) -> np.ndarray:
    """Sinusoidal stripes running at angle phi (counter-clockwise on screen from +x)."""
    u = XX * np.sin(phi) + YY * np.cos(phi)  # distance across the stripes, pixels
    return 0.5 + 0.4 * np.sin(2 * np.pi * u / period) + rng.normal(0.0, noise, (H, W))


@pytest.mark.parametrize("phi_deg", [0.0, 12.0, 37.0, -45.0, 63.0, 88.0, -89.5])
@pytest.mark.parametrize("period", [6.0, 8.0, 11.0])
def test_planar_stripes_orientation_within_2deg(phi_deg, period, rng):
    phi = np.deg2rad(phi_deg)
    am = angle_map(stripes(phi, period, rng))
    inner = am.theta[15:-15, 15:-15]
    assert np.isfinite(inner).all(), "planar lit stripes must be valid everywhere inside"
    err = np.rad2deg(np.abs(wrap_half_pi(inner - phi)))
    assert err.max() < 2.0, f"max error {err.max():.2f} deg at phi={phi_deg}, period={period}"


def test_tuned_bank_handles_coarse_stripes(rng):
    phi = np.deg2rad(20.0)
    am = angle_map(stripes(phi, 16.0, rng), bank=SteerableBank.for_period(16.0))
    err = np.rad2deg(np.abs(wrap_half_pi(am.theta[25:-25, 25:-25] - phi)))
    assert err.max() < 2.0


def test_energy_coefficients_match_steered_energy(rng):
    """C1, C2, C3 are the 0th and 2nd Fourier coefficients of the steered G2/H2 energy."""
    r = tuple(rng.normal(size=50) for _ in range(7))
    ga, gb, gc, ha, hb, hc, hd = r
    t = np.linspace(0, 2 * np.pi, 720, endpoint=False)[:, None]
    c, s = np.cos(t), np.sin(t)
    g2 = c**2 * ga - 2 * c * s * gb + s**2 * gc
    h2 = c**3 * ha - 3 * c**2 * s * hb + 3 * c * s**2 * hc - s**3 * hd
    e = g2**2 + h2**2
    c1, c2, c3 = energy_coefficients(r)
    np.testing.assert_allclose(c1, e.mean(0), atol=1e-10)
    np.testing.assert_allclose(c2, 2 * (e * np.cos(2 * t)).mean(0), atol=1e-10)
    np.testing.assert_allclose(c3, 2 * (e * np.sin(2 * t)).mean(0), atol=1e-10)


def folded(rng: np.random.Generator, kink_x: float = 80.0, bend_deg: float = 30.0) -> np.ndarray:
    """Horizontal stripes on a surface with a straight vertical fold at x = kink_x."""
    u = YY + np.where(XX > kink_x, np.tan(np.deg2rad(bend_deg)) * (XX - kink_x), 0.0)  # rises to the right
    return 0.5 + 0.4 * np.sin(2 * np.pi * u / 7.0) + rng.normal(0.0, 0.05, (H, W))


def test_fold_gives_mask_along_fold_only(rng):
    am = angle_map(folded(rng))
    mask = am.mask(0.02)
    rows = slice(15, H - 15)
    along = mask[rows, 70:91]
    assert along.any(axis=1).all(), "every row must have fold pixels near the fold"
    assert not mask[rows, 10:45].any(), "planar left region must have an empty mask"
    assert not mask[rows, 125:150].any(), "planar right region must have an empty mask"
    # the two planes keep their orientations
    assert abs(np.rad2deg(np.nanmedian(am.theta[rows, 10:45]))) < 1.0
    assert abs(np.rad2deg(np.nanmedian(am.theta[rows, 125:150])) - 30.0) < 1.5
    # eq. 11 from the angle map alone agrees with the mask computed inside angle_map
    agree = (gradient_mask(am.theta, 0.02) == mask)[rows, 10:150].mean()
    assert agree > 0.99


def test_gradient_respects_pi_periodicity():
    theta = np.full((20, 20), np.deg2rad(89.0))
    theta[:, 10:] = np.deg2rad(-89.0)  # 2 degrees apart through the wrap, not 178
    g = angle_gradient(theta)
    assert g.max() == pytest.approx(np.deg2rad(2.0) / 2, rel=1e-3)  # central difference
    naive = np.abs(np.diff(theta, axis=1)).max()
    assert naive > 3.0  # the naive difference would flag a false fold
    assert not gradient_mask(theta, 0.05).any()


def test_background_is_invalid(rng):
    img = stripes(0.3, 8.0, rng, noise=0.0)
    img[:, :60] = 0.02 * rng.random((H, 60))  # unlit background: faint noise only
    am = angle_map(img)
    assert not am.valid[:, :40].any()
    assert am.valid[10:-10, 80:-10].all()
    assert np.isnan(am.theta[:, :40]).all()


def test_metric_known_values():
    T = 3
    th_r = np.zeros((T, 10, 10))
    th_s = np.zeros((T, 10, 10))
    m = np.zeros((T, 10, 10), bool)
    s_r = np.zeros((T, 10, 10), bool)
    s_r[:, 2:8, 2:8] = True
    s_s = s_r.copy()
    assert cloth_metric(th_r, m, s_r, th_s, s_s)[0] == 0.0
    # frame 1: one masked pixel with orientations 89 deg vs -89 deg -> (2 deg)^2
    m[1, 4, 4] = True
    th_r[1, 4, 4], th_s[1, 4, 4] = np.deg2rad(89.0), np.deg2rad(-89.0)
    # a masked pixel outside the simulated silhouette does not count in the fold term
    m[1, 3, 3] = True
    th_s[1, 3, 3] = 1.0
    s_s[1, 3, 3] = False
    # frame 2: simulated silhouette has 5 extra pixels
    s_s[2, 0, :5] = True
    e, ef, es = cloth_metric(th_r, m, s_r, th_s, s_s, alpha=0.1)
    np.testing.assert_allclose(ef, [0.0, np.deg2rad(2.0) ** 2, 0.0], atol=1e-12)
    np.testing.assert_allclose(es, [0.0, 1.0, 5.0])
    assert e == pytest.approx((ef.sum() + 0.1 * es.sum()) / T)
    e_sum, _, _ = cloth_metric(th_r, m, s_r, th_s, s_s, alpha=0.1, reduce="sum")
    assert e_sum == pytest.approx(T * e)
    # unmasked pixels do not contribute to the fold term
    th_s[0] = 0.7
    assert cloth_metric(th_r, m, s_r, th_s, s_s)[1][0] == 0.0


def test_metric_ranks_closer_orientation_lower(rng):
    """A simulated angle map nearer to the real one scores lower."""
    real = angle_map(folded(rng, bend_deg=30.0))
    near = angle_map(folded(rng, bend_deg=26.0))
    far = angle_map(folded(rng, bend_deg=10.0))
    sil = np.ones((H, W), bool)
    m = real.mask(0.02)
    e_near = cloth_metric(real.theta, m, sil, near.theta, sil)[0]
    e_far = cloth_metric(real.theta, m, sil, far.theta, sil)[0]
    assert 0 < e_near < e_far


def test_bad_inputs_raise_clear_errors():
    with pytest.raises(AngleMapError, match="ksize"):
        SteerableBank(ksize=12)
    with pytest.raises(AngleMapError, match="image"):
        angle_map(np.zeros((4, 5, 6, 7)))
    with pytest.raises(AngleMapError, match="tau"):
        gradient_mask(np.zeros((5, 5)), 0.0)
    z = np.zeros((2, 5, 5))
    with pytest.raises(AngleMapError, match="same"):
        cloth_metric(z, z, z, np.zeros((2, 5, 6)), z)
    with pytest.raises(AngleMapError, match="equal shapes"):
        energy_coefficients(tuple(np.zeros((4, 4 + (k == 3)), np.float32) for k in range(7)))
    with pytest.raises(AngleMapError, match="region"):
        angle_map(np.zeros((20, 20)), region=np.ones((20, 21), bool))
    with pytest.raises(AngleMapError, match="alpha"):
        cloth_metric(z, z, z, z, z, alpha=-1.0)
    with pytest.raises(AngleMapError, match="min_orientedness"):
        angle_map(np.zeros((20, 20)), min_orientedness=1.5)
    with pytest.raises(AngleMapError, match="min_strength"):
        angle_map(np.zeros((20, 20)), min_strength=float("nan"))


def test_zero_thresholds_leave_flat_pixels_invalid(rng):
    """With both validity thresholds at 0 a flat (zero-strength) pixel is still invalid: the angle
    gradient divides by the strength (numba raised ZeroDivisionError on a half-black stripe image)."""
    img = stripes(0.3, 8.0, rng, noise=0.0)
    img[:, : W // 2] = 0.0
    am = angle_map(img, min_strength=0.0, min_orientedness=0.0, crop=False)
    assert not am.valid[:, : W // 4].any() and am.valid[:, W // 2 + 10:].mean() > 0.9
    assert np.all(np.isfinite(am.gradient))


def test_fused_coefficients_equal_reference_formulas(rng):
    """The numba kernel used on float32 images computes the same C1..C3 as the NumPy formulas."""
    r32 = tuple(rng.normal(size=(17, 23)).astype(np.float32) for _ in range(7))
    fused = energy_coefficients(r32)  # 2-D float32: numba path
    ref = energy_coefficients(tuple(x.astype(np.float64) for x in r32))  # NumPy path
    for a, b in zip(fused, ref):
        assert a.dtype == np.float32
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("shift", [(0, 0), (37, -51), (-60, 95), (71, 120)])
def test_cropped_angle_map_equals_the_full_frame_bit_for_bit(shift):
    """A rendered object on a black background is filtered in a box only; the result must be the
    whole-frame result exactly (the estimator's simulated footage takes this path)."""
    from omegaconf import OmegaConf

    from vidsim.cloth import swatch
    from vidsim.config import camera_from_config, projector_from_config
    from vidsim.config.cloth import ClothConfig
    from vidsim.render.projector import Projector, render_stripes_batch

    cfg = OmegaConf.structured(ClothConfig())
    cam = camera_from_config(cfg.camera)
    proj = Projector(projector_from_config(cfg.projector), period_px=cfg.projector.period_px,
                     power=cfg.projector.power, ambient=cfg.projector.ambient)
    m = swatch(12, 12, 0.3, 0.3, origin=(-0.15, 0.0, 1.0), axis_u=(1.0, 0.0, 0.0), axis_v=(0.0, 0.0, -1.0))
    V = m.rest_positions.copy()
    V[:, 1] += 0.03 * np.sin(9 * V[:, 0]) * np.cos(7 * V[:, 2])  # folds
    # move the swatch in the image (the box's parity, and boxes touching the frame's border)
    V[:, 0] += shift[0] * 1.6 / 560
    V[:, 2] -= shift[1] * 1.6 / 560
    img, depth = render_stripes_batch(V[None], m.triangles, cam, proj)
    img, sil = img[0], np.isfinite(depth[0])
    assert sil.sum() > 500
    bank = SteerableBank.for_period(6.5)
    a = angle_map(img, bank, region=sil)
    b = angle_map(img, bank, region=sil, crop=False)
    for name in ("theta", "strength", "orientedness", "valid", "gradient"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert np.isfinite(a.theta).sum() > 0.5 * sil.sum()
