"""Structured model discrepancy of the rigid posterior: a drag coefficient sampled as a nuisance parameter.

Reality (MuJoCo) has 3 x physical air drag and angular drag; the 14-parameter model has none.
A reduced throw (320x240, 40 frames, exact rasterised silhouettes, fixed seed) and the Laplace
approximation keep this under a minute.
"""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.posterior.rigid import (DiscrepancyConfig, FrameLoss, NoiseConfig, RigidLogPosterior, RigidPriorConfig,
                                    calibrate_noise, laplace_samples, refit_discrepancy, to_natural, truth_params)
from vidsim.posterior.sampler import PosteriorError, covered
from vidsim.reality.rigid import RigidEffects, RigidRealityConfig, make_throw
from vidsim.rigid.body import BoxBody
from vidsim.rigid.dynamics import PARAM_NAMES
from vidsim.rigid.evaluate import perturbed_guess
from vidsim.rigid.fit import Stage, fit_throw

VY = PARAM_NAMES.index("vy")


@pytest.fixture(scope="module")
def drag_throw():
    sc = RigidRealityConfig(n_frames=40, n_background=2, width=320, height=240, focal=320.0)
    th = make_throw(11, sc, RigidEffects(drag=3.0, angular_drag=3.0), render=False)
    body = BoxBody.from_meta(th.meta["object"])
    guess = perturbed_guess(th.truth, np.random.default_rng(11), orient_deg=5.0, omega_rel=0.1, vel_rel=0.05,
                            pos_m=0.02, grav_deg=2.0)
    fc = {"multistart": "none", "screen": [Stage(0.5, None, 20, 0.3)], "screen_keep": [1], "refine": [],
          "final": [Stage(1.0, None, 40, 0.0)]}
    fit = fit_throw(th.masks, th.times, th.camera, body, guess, fc)
    masks = th.masks[fit.frames]
    truth = to_natural(truth_params(th.truth, fit.q0, body.symmetries))  # scoring only
    return th, body, fit, masks, truth


def _laplace(loss: FrameLoss, p0: np.ndarray, model: str, bounds: np.ndarray | None) -> np.ndarray:
    nm = calibrate_noise(loss, p0, NoiseConfig(model=model, n_design=300, design_iters=2), np.random.default_rng(0))
    return to_natural(laplace_samples(nm, bounds, 20000, np.random.default_rng(1)))


def test_nuisance_at_zero_is_the_base_model(drag_throw) -> None:
    th, body, fit, masks, _ = drag_throw
    base = FrameLoss(body, th.camera, fit.times, masks, fit.t0, fit.q0)
    ext = FrameLoss(body, th.camera, fit.times, masks, fit.t0, fit.q0, effects=("quadratic_drag",))
    e0, e1 = base(fit.params), ext(np.r_[fit.params, 0.0])
    assert ext.n_params == 15 and np.array_equal(e0, e1)
    # drag slows the body: the rendered trajectory moves, the mismatch changes
    assert not np.allclose(ext(np.r_[fit.params, 1.0]), e0)


def test_drag_coefficient_absorbs_the_withheld_drag(drag_throw) -> None:
    """Without the nuisance the vertical velocity absorbs the drag and its interval misses the truth
    by many standard deviations; with ``discrepancy: [quadratic_drag]`` (and the held-out-halves noise
    model) the interval contains it, and the drag coefficient is positive and of physical order."""
    th, body, fit, masks, truth = drag_throw
    plain = FrameLoss(body, th.camera, fit.times, masks, fit.t0, fit.q0)
    S0 = _laplace(plain, fit.params, "sandwich", None)
    z0 = (np.median(S0[:, VY]) - truth[VY]) / S0[:, VY].std()
    assert not covered(S0, truth)[VY] and abs(z0) > 10, z0

    disc = DiscrepancyConfig(effects=("quadratic_drag",))
    loss = FrameLoss(body, th.camera, fit.times, masks, fit.t0, fit.q0, effects=disc.effects)
    p0 = refit_discrepancy(masks, loss, fit.params, disc)
    assert np.sum(loss(p0)) < np.sum(plain(fit.params))  # the refit mode explains more of the footage
    S = _laplace(loss, p0, "sandwich_holdout", disc.bounds())
    assert np.all((S[:, 14] >= 0) & (S[:, 14] <= disc.bounds()[0, 1]))  # draws respect the prior
    assert covered(S[:, :14], truth)[VY]
    # c2 = rho C / 2 for 3 x air (1.2 kg/m^3) on a bluff body (C ~ 1): ~1.8 kg/m^3; within a factor 3
    c2 = float(np.median(S[:, 14]))
    assert 0.6 < c2 < 5.0, c2
    # the marginal intervals of the 14 parameters are calibrated on this throw (plain: far fewer)
    assert covered(S[:, :14], truth).sum() >= 12 > covered(S0, truth).sum()


def test_log_posterior_honours_the_nuisance_prior(drag_throw) -> None:
    th, body, fit, masks, _ = drag_throw
    disc = DiscrepancyConfig(effects=("quadratic_drag",), upper={"quadratic_drag": 2.0})
    loss = FrameLoss(body, th.camera, fit.times, masks, fit.t0, fit.q0, effects=disc.effects)
    nm = calibrate_noise(loss, np.r_[fit.params, 0.5], NoiseConfig(n_design=200, design_iters=1),
                         np.random.default_rng(0))
    lp = RigidLogPosterior(loss, nm, fit.params, RigidPriorConfig(), disc.bounds())
    assert np.isfinite(lp(np.r_[fit.params, 0.5]))
    assert lp(np.r_[fit.params, -0.01]) == -np.inf and lp(np.r_[fit.params, 2.01]) == -np.inf


QD = ("quadratic_drag",)


def test_signed_prior_is_symmetric() -> None:
    assert DiscrepancyConfig(effects=QD).bounds().tolist() == [[0.0, 5.0]]
    assert DiscrepancyConfig(effects=QD, upper={"quadratic_drag": 2.0}, signed=True).bounds().tolist() == [[-2.0, 2.0]]


@pytest.mark.parametrize("kw, what", [({"effects": ("quadratic_drgg",)}, "quadratic_drgg"),
                                      ({"effects": QD + QD}, "twice"),
                                      ({"effects": QD, "upper": {"angular_drag": 1.0}}, "angular_drag"),
                                      ({"effects": QD, "upper": {"quadratic_drag": -1.0}}, "> 0")])
def test_bad_discrepancy_settings_are_errors(kw: dict, what: str) -> None:
    with pytest.raises(PosteriorError, match=what):
        DiscrepancyConfig(**kw).validate()
