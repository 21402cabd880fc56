"""Noise calibration of the loss-based likelihood: known answers on linear-Gaussian frames."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.posterior.rigid import DESIGN_SCALE0, NoiseConfig, calibrate_noise, hac_covariance, truth_params
from vidsim.posterior.sampler import PosteriorError
from vidsim.rigid.dynamics import N_PARAM, quat_exp, quat_mul


class LinearFrames:
    """Per-frame squared residuals of a linear model: E_k = (y_k - a_k . p)^2, noise sd sigma.

    For this loss the exact log-likelihood is ``-sum E_k / (2 sigma^2)``, so a calibrated learning
    rate is ``1 / (2 sigma^2)``.
    """

    def __init__(self, rng: np.random.Generator, T: int, sigma: float, ar: float = 0.0) -> None:
        self.A = rng.normal(size=(T, N_PARAM)) / DESIGN_SCALE0 * 0.05
        e = rng.normal(size=T)
        for k in range(1, T):  # AR(1) residuals when ar > 0 (a structured misfit)
            e[k] = ar * e[k - 1] + np.sqrt(1 - ar ** 2) * e[k]
        self.y = sigma * e
        self.n_frames = T
        self.n_pixels = T * 100
        self.n_evals = 0

    def __call__(self, p: np.ndarray, q_base=None) -> np.ndarray:
        self.n_evals += 1
        return (self.y - self.A @ p) ** 2


@pytest.mark.parametrize("sigma", [0.5, 3.0])
def test_sandwich_recovers_the_true_likelihood_scale(rng, sigma: float) -> None:
    loss = LinearFrames(rng, 400, sigma)
    nm = calibrate_noise(loss, np.zeros(N_PARAM), NoiseConfig(n_design=300, design_iters=1), rng)
    assert abs(nm.w * 2 * sigma ** 2 - 1) < 0.25
    # the mode is the least-squares solution
    p_ls = np.linalg.lstsq(loss.A, loss.y, rcond=None)[0]
    sd = np.sqrt(np.diag(nm.cov))
    assert np.all(np.abs(nm.center - p_ls) < 0.2 * sd)
    # the posterior covariance is sigma^2 (A^T A)^-1
    cov_true = sigma ** 2 * np.linalg.inv(loss.A.T @ loss.A)
    assert np.allclose(np.sqrt(np.diag(nm.cov)) / np.sqrt(np.diag(cov_true)), 1.0, atol=0.15)


def test_iid_pixel_model_is_overconfident(rng) -> None:
    loss = LinearFrames(rng, 400, 1.0)
    w_sand = calibrate_noise(loss, np.zeros(N_PARAM), NoiseConfig(n_design=300, design_iters=1), rng).w
    w_pix = calibrate_noise(loss, np.zeros(N_PARAM), NoiseConfig("iid_pixel", n_design=300, design_iters=1), rng).w
    assert w_pix > 20 * w_sand  # 100 "pixels" per frame counted as independent measurements


def test_hac_no_spurious_widening_for_independent_scores(rng) -> None:
    loss = LinearFrames(rng, 400, 1.0, ar=0.8)
    w_iid = calibrate_noise(loss, np.zeros(N_PARAM), NoiseConfig(n_design=300, design_iters=1), rng).w
    w_hac = calibrate_noise(loss, np.zeros(N_PARAM), NoiseConfig("sandwich_hac", n_design=300, design_iters=1,
                                                                 hac_bandwidth=20), rng).w
    # regressors independent between frames: the scores are uncorrelated despite AR residuals
    assert 0.6 < w_hac / w_iid < 1.6


def test_hac_widens_when_scores_drift_together(rng) -> None:
    loss = LinearFrames(rng, 400, 1.0, ar=0.95)
    kern = np.ones(40) / 40.0  # regressors that vary slowly over the frames, like a throw's poses
    loss.A = np.stack([np.convolve(c, kern, mode="same") for c in loss.A.T], 1) * 6.0
    w_iid = calibrate_noise(loss, np.zeros(N_PARAM), NoiseConfig(n_design=300, design_iters=1), rng).w
    w_hac = calibrate_noise(loss, np.zeros(N_PARAM), NoiseConfig("sandwich_hac", n_design=300, design_iters=1,
                                                                 hac_bandwidth=40), rng).w
    assert w_hac < 0.5 * w_iid


def test_hac_covariance_known_values() -> None:
    g = np.ones((10, 1))
    # T + 2 sum_l (1 - l/3) (T - l) for bandwidth 2
    assert hac_covariance(g, 2)[0, 0] == pytest.approx(10 + 2 * (2 / 3 * 9 + 1 / 3 * 8))
    alt = np.array([[1.0], [-1.0]] * 5)
    assert hac_covariance(alt, 1)[0, 0] == pytest.approx(10 - 2 * 0.5 * 9)


def test_bad_noise_settings_name_the_field() -> None:
    with pytest.raises(PosteriorError, match="noise.model"):
        NoiseConfig(model="gaussian").validate()
    with pytest.raises(PosteriorError, match="n_design"):
        NoiseConfig(n_design=20).validate()


def test_truth_params_rotation_modulo_symmetry() -> None:
    d = np.array([0.05, -0.02, 0.03])
    q_true = np.array([0.9, 0.1, -0.3, 0.2])
    q_true /= np.linalg.norm(q_true)
    truth = {"position": [0, 0, 3], "quaternion": q_true.tolist(), "velocity": [1, 0, 0], "omega_world": [0, 1, 0],
             "tilt": 0.01, "roll": -0.02}
    flip = np.diag([1.0, -1.0, -1.0])
    base = quat_mul(q_true, quat_exp(-d))
    tp = truth_params(truth, base, np.stack([np.eye(3), flip]))
    np.testing.assert_allclose(tp[3:6], d, atol=1e-9)
    np.testing.assert_allclose(tp[[0, 1, 2, 6, 12, 13]], [0, 0, 3, 1, 0.01, -0.02])


def test_holdout_inflation_detects_a_drifting_misfit(rng) -> None:
    ok = LinearFrames(rng, 400, 1.0)
    nm = calibrate_noise(ok, np.zeros(N_PARAM), NoiseConfig("sandwich_holdout", n_design=300, design_iters=1), rng)
    assert nm.inflation < 3.0  # halves agree within noise (chi2 / D ~ 1)
    bad = LinearFrames(rng, 400, 1.0)
    bad.y = bad.y + np.linspace(-1, 1, 400) * 30.0 * (bad.A[:, 0] * DESIGN_SCALE0[0] / 0.05)  # unmodelled term
    nb = calibrate_noise(bad, np.zeros(N_PARAM), NoiseConfig("sandwich_holdout", n_design=300, design_iters=1), rng)
    assert nb.inflation > 10.0


def test_holdout_blocks_two_is_the_halves_and_more_blocks_see_a_drift_less(rng) -> None:
    from vidsim.posterior.rigid import PosteriorError, holdout_inflation

    T, D = 60, 3
    H = np.stack([np.eye(D) * (1.0 + 0.1 * k % 3) for k in range(T)])
    g = rng.normal(size=(T, D))
    # two blocks: the first half's mode against the second's, as documented
    h = T // 2
    d = -np.linalg.solve(H[:h].sum(0), g[:h].sum(0)) + np.linalg.solve(H[h:].sum(0), g[h:].sum(0))
    C = np.linalg.inv(H[:h].sum(0)) + np.linalg.inv(H[h:].sum(0))
    assert holdout_inflation(g, H, 1.0, 2) == pytest.approx(max(1.0, d @ np.linalg.solve(C, d) / D))
    # a misfit drifting linearly over the throw: each frame's own mode moves along the first axis
    drift = g.copy()
    drift[:, 0] -= H[:, 0, 0] * np.linspace(-1, 1, T) * 2.0
    k2, k6 = holdout_inflation(drift, H, 1.0, 2), holdout_inflation(drift, H, 1.0, 6)
    assert k2 > 10.0 and k6 > 1.0 and k6 < k2  # shorter blocks see less of a slow drift
    with pytest.raises(PosteriorError, match="holdout_blocks = 1"):
        holdout_inflation(g, H, 1.0, 1)


def test_holdout_confidence_bound_is_the_chi2_quantile_of_the_halves_statistic(rng) -> None:
    from scipy.stats import chi2 as chi2_dist

    from vidsim.posterior.rigid import PosteriorError, holdout_inflation

    T, D = 40, 4
    H = np.stack([np.eye(D)] * T)
    g = rng.normal(size=(T, D))
    g[:, 1] -= np.linspace(-1, 1, T) * 3.0  # a drift, so the inflation is above its floor of 1
    point = holdout_inflation(g, H, 1.0)
    upper = holdout_inflation(g, H, 1.0, 2, 0.9)
    assert point > 1.0
    # same statistic, divided by the 10 % quantile of chi2_D instead of its mean D
    assert upper == pytest.approx(point * D / chi2_dist.ppf(0.1, D))
    assert holdout_inflation(g, H, 1.0, 2, 0.5) == pytest.approx(point * D / chi2_dist.ppf(0.5, D))
    for bad in (1.0, -0.1):
        with pytest.raises(PosteriorError, match="holdout_confidence"):
            holdout_inflation(g, H, 1.0, 2, bad)
    with pytest.raises(PosteriorError, match="holdout_confidence"):
        holdout_inflation(g, H, 1.0, 3, 0.9)


def test_sandwich_intervals_cover_at_the_throws_frame_count(rng) -> None:
    """At T = 40 frames and D = 14 parameters (a throw) the uncorrected sandwich put w about T / (T - D)
    too high and its 90 % intervals covered 0.79 of the true parameters (1400 pairs, review); with the
    small-sample correction about 0.89. Here 24 replicates (336 pairs, standard error ~0.017)."""
    T = 40
    hits = []
    for r in range(24):
        g = np.random.default_rng(500 + r)
        loss = LinearFrames(g, T, 1.0)
        nm = calibrate_noise(loss, np.zeros(N_PARAM), NoiseConfig(n_design=400, design_iters=2), g)
        # the truth is p = 0 (y is pure noise); the Laplace 90 % interval around the mode
        hits.append(np.abs(nm.center) / np.sqrt(np.diag(nm.cov)) <= 1.6449)
    cov = float(np.mean(hits))
    assert 0.84 < cov < 0.95, cov


def test_logged_calibration_is_replayed_bit_for_bit_and_recomputed_for_other_inputs(rng, tmp_path) -> None:
    """posterior_rigid's resume: the noise calibration is logged once and replayed (no simulation)
    with every array equal to the bit; a log of another context is not replayed."""
    from dataclasses import fields

    from vidsim.posterior.rigid import DiscrepancyConfig, calibrate_logged

    loss = LinearFrames(rng, 200, 1.0)
    masks = np.zeros((200, 2, 2), bool)
    cfg = NoiseConfig(n_design=200, design_iters=1)
    log = tmp_path / "calibration.jsonl"
    p0, nm0 = calibrate_logged(masks, loss, np.zeros(N_PARAM), cfg, DiscrepancyConfig(), 7, str(log), "inputs-a")
    n = loss.n_evals
    assert n > 400
    p1, nm1 = calibrate_logged(masks, loss, np.zeros(N_PARAM), cfg, DiscrepancyConfig(), 7, str(log), "inputs-a")
    assert loss.n_evals == n  # replayed: nothing simulated
    assert np.array_equal(p0, p1)
    for f in fields(nm0):
        a, b = getattr(nm0, f.name), getattr(nm1, f.name)
        assert (np.array_equal(a, b) and a.dtype == b.dtype) if isinstance(a, np.ndarray) else (a == b and type(a) is type(b))
    # the same calibration without a log: equal to the logged one
    _, nm2 = calibrate_logged(masks, loss, np.zeros(N_PARAM), cfg, DiscrepancyConfig(), 7)
    assert nm2.w == nm0.w and np.array_equal(nm2.cov, nm0.cov)
    n = loss.n_evals
    calibrate_logged(masks, loss, np.zeros(N_PARAM), cfg, DiscrepancyConfig(), 7, str(log), "inputs-b")
    assert loss.n_evals > n and (tmp_path / "calibration.stale-1.jsonl").is_file()


class _Killed(Exception):
    pass


def test_calibration_killed_midway_replays_its_evaluated_points(rng, tmp_path) -> None:
    """A run killed during the noise calibration (after 250 of its evaluations) replays those 250 on
    the rerun and simulates only the rest, ending with the uninterrupted run's model bit for bit."""
    from dataclasses import fields

    from vidsim.posterior.rigid import DiscrepancyConfig, calibrate_logged

    loss = LinearFrames(rng, 200, 1.0)
    masks = np.zeros((200, 2, 2), bool)
    cfg = NoiseConfig(n_design=200, design_iters=1)
    _, whole = calibrate_logged(masks, loss, np.zeros(N_PARAM), cfg, DiscrepancyConfig(), 7)
    n_whole = loss.n_evals

    class Dies(LinearFrames):
        def __call__(self, p, q_base=None):
            if self.n_evals == 250:
                raise _Killed
            return super().__call__(p, q_base)

    dies = Dies(np.random.default_rng(0), 200, 1.0)
    dies.A, dies.y = loss.A, loss.y
    log = tmp_path / "calibration.jsonl"
    with pytest.raises(_Killed):
        calibrate_logged(masks, dies, np.zeros(N_PARAM), cfg, DiscrepancyConfig(), 7, str(log), "inputs-a")
    loss.n_evals = 0
    _, resumed = calibrate_logged(masks, loss, np.zeros(N_PARAM), cfg, DiscrepancyConfig(), 7, str(log), "inputs-a")
    assert loss.n_evals == n_whole - 250
    for f in fields(whole):
        a, b = getattr(whole, f.name), getattr(resumed, f.name)
        assert np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b


def test_posterior_rigid_output_holds_no_calibration_log(rng, tmp_path) -> None:
    """The stage's calibration log, and the stale copy it moves aside after a kill and an input
    change, stay in their checkpoint folder, which is removed before the staging folder becomes the
    output (before: calibration.stale-1.jsonl reached results/posterior/rigid/<throw>/)."""
    from vidsim.cli.posterior_rigid import calibration_log, finish
    from vidsim.posterior.rigid import DiscrepancyConfig, calibrate_logged

    loss = LinearFrames(rng, 200, 1.0)
    masks = np.zeros((200, 2, 2), bool)
    cfg = NoiseConfig(n_design=150, design_iters=1)
    tmp, out = tmp_path / ".throw.part", tmp_path / "throw"
    tmp.mkdir()
    (tmp / "calibration.jsonl").write_text("{}\n")  # where an earlier version kept the log
    log = calibration_log(tmp)
    for ctx in ("inputs-a", "inputs-b"):  # killed, then rerun with a changed input
        calibrate_logged(masks, loss, np.zeros(N_PARAM), cfg, DiscrepancyConfig(), 7, str(log), ctx)
    assert log.with_name("calibration.stale-1.jsonl").is_file()
    (tmp / "summary.csv").write_text("name\n")
    finish(tmp, out)
    assert sorted(p.name for p in out.rglob("*")) == ["summary.csv"]
