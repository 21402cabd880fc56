"""emcee driver: recovery of a known Gaussian, the 50-tau convergence flag, bit-identical resume."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.posterior.sampler import PosteriorError, SamplerConfig, autocorr_time, correlation, covered, sample, summarize

COV = np.array([[1.0, 0.8, 0.0], [0.8, 1.0, 0.0], [0.0, 0.0, 4.0]])
ICOV = np.linalg.inv(COV)
MEAN = np.array([1.0, -2.0, 0.5])


def _logp(x: np.ndarray) -> float:
    d = x - MEAN
    return -0.5 * float(d @ ICOV @ d)


def test_gaussian_quantiles_correlation_and_convergence() -> None:
    cfg = SamplerConfig(n_walkers=16, chunk=250, min_steps=500, max_steps=5000, seed=3)
    ch = sample(_logp, MEAN + 0.1, COV, cfg)
    assert ch.converged and ch.n_steps >= 50 * ch.tau.max()
    S = ch.samples()
    rows = summarize(S, ["a", "b", "c"])
    sd = np.sqrt(np.diag(COV))
    for r, m, s in zip(rows, MEAN, sd):
        assert abs(r["median"] - m) < 0.1 * s
        assert abs((r["q95"] - r["q05"]) / (2 * 1.6449 * s) - 1) < 0.08
    C = correlation(S)
    assert abs(C[0, 1] - 0.8) < 0.05 and abs(C[0, 2]) < 0.05
    assert covered(S, MEAN).all() and not covered(S, MEAN + 3 * sd).any()


def test_short_chain_is_reported_not_converged() -> None:
    cfg = SamplerConfig(n_walkers=16, chunk=50, min_steps=50, max_steps=100, seed=1)
    ch = sample(_logp, MEAN, COV, cfg)
    assert ch.n_steps == 100
    assert not ch.converged  # 100 steps cannot be 50 autocorrelation times here
    assert ch.n_steps < 50 * ch.tau.max()


def test_resume_is_bit_identical(tmp_path) -> None:
    full = sample(_logp, MEAN, COV, SamplerConfig(n_walkers=8, chunk=50, min_steps=200, max_steps=200, seed=5),
                  tmp_path / "a.npz")
    # a run stopped after 100 steps, then started again with the longer budget
    sample(_logp, MEAN, COV, SamplerConfig(n_walkers=8, chunk=50, min_steps=100, max_steps=100, seed=5),
           tmp_path / "b.npz")
    resumed = sample(_logp, MEAN, COV, SamplerConfig(n_walkers=8, chunk=50, min_steps=200, max_steps=200, seed=5),
                     tmp_path / "b.npz")
    assert resumed.n_evals == 100 * 8  # only the missing half was sampled
    np.testing.assert_array_equal(full.chain, resumed.chain)
    np.testing.assert_array_equal(full.log_prob, resumed.log_prob)
    # the resumed run reports the chunks sampled before the kill too (for its progress log and
    # recording), with the convergence figures the uninterrupted run reported for them
    assert [h["step"] for h in resumed.history] == [h["step"] for h in full.history] == [50, 100, 150, 200]
    assert [h.get("resumed", False) for h in resumed.history] == [True, True, False, False]
    for a, b in zip(full.history, resumed.history):
        assert a["tau_max"] == b["tau_max"] or (np.isinf(a["tau_max"]) and np.isinf(b["tau_max"]))
    # acceptance of a replayed chunk: walkers that moved, counted from the chain itself (emcee's
    # own count for the first chunk also includes the move from the starting ball)
    assert abs(resumed.history[1]["acceptance"] - full.history[1]["acceptance"]) < 1e-12
    assert abs(resumed.history[0]["acceptance"] - full.history[0]["acceptance"]) < 0.05
    # the chain's acceptance is the whole chain's (not the last chunk's), the same after a resume and
    # on a rerun of a finished chain file (which samples nothing)
    assert resumed.acceptance == full.acceptance
    chunks = [h["acceptance"] for h in full.history]
    assert abs(full.acceptance - np.mean(chunks)) < 0.01 and full.acceptance != chunks[-1]
    again = sample(_logp, MEAN, COV, SamplerConfig(n_walkers=8, chunk=50, min_steps=200, max_steps=200, seed=5),
                   tmp_path / "b.npz")
    assert again.n_evals == 0 and again.acceptance == full.acceptance


def test_a_chain_of_another_posterior_is_not_resumed(tmp_path) -> None:
    cfg100 = SamplerConfig(n_walkers=8, chunk=50, min_steps=100, max_steps=100, seed=5)
    cfg200 = SamplerConfig(n_walkers=8, chunk=50, min_steps=200, max_steps=200, seed=5)
    sample(_logp, MEAN, COV, cfg100, tmp_path / "b.npz")  # killed after 100 steps

    def shifted(x: np.ndarray) -> float:  # the inputs changed before the rerun
        return _logp(np.asarray(x) - 0.3)

    again = sample(shifted, MEAN, COV, cfg200, tmp_path / "b.npz")
    assert again.n_evals == 200 * 8  # sampled afresh, not continued
    assert (tmp_path / "stale-1.b.npz").is_file()
    fresh = sample(shifted, MEAN, COV, cfg200, tmp_path / "c.npz")
    np.testing.assert_array_equal(again.chain, fresh.chain)
    # a chain with another number of walkers (settings changed since the kill) is kept aside too,
    # not continued and not a dead end that needs a hand-deleted file
    cfg12 = SamplerConfig(n_walkers=12, chunk=50, min_steps=100, max_steps=100, seed=5)
    other = sample(shifted, MEAN, COV, cfg12, tmp_path / "b.npz")
    assert other.n_evals == 100 * 12 and (tmp_path / "stale-2.b.npz").is_file()


def test_vectorised_resume_tolerates_batch_rounding(tmp_path) -> None:
    """A vectorised density (a GP surrogate) rounds differently in other batch shapes than
    emcee's half-ensembles; the resume check must not take that for changed inputs."""

    def batched(X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(X)
        return np.array([_logp(x) for x in X]) * (1.0 + 1e-9 * len(X))  # batch-shape rounding

    cfg100 = SamplerConfig(n_walkers=8, chunk=50, min_steps=100, max_steps=100, seed=5)
    cfg200 = SamplerConfig(n_walkers=8, chunk=50, min_steps=200, max_steps=200, seed=5)
    full = sample(batched, MEAN, COV, cfg200, tmp_path / "a.npz", vectorize=True)
    sample(batched, MEAN, COV, cfg100, tmp_path / "b.npz", vectorize=True)
    resumed = sample(batched, MEAN, COV, cfg200, tmp_path / "b.npz", vectorize=True)
    assert resumed.n_evals == 100 * 8 and not list(tmp_path.glob("stale-*"))
    np.testing.assert_array_equal(full.chain, resumed.chain)


def test_bad_settings_name_the_field(tmp_path) -> None:
    with pytest.raises(PosteriorError, match="n_walkers"):
        sample(_logp, MEAN, COV, SamplerConfig(n_walkers=4))
    with pytest.raises(PosteriorError, match="max_steps"):
        sample(_logp, MEAN, COV, SamplerConfig(n_walkers=8, min_steps=500, max_steps=100))
    # (a saved chain of other dimensions is moved aside: test_a_chain_of_another_posterior_is_not_resumed)


def test_autocorr_time_of_ar1_chain(rng) -> None:
    # AR(1) with phi = 0.9 has integrated autocorrelation time (1 + phi) / (1 - phi) = 19
    n, phi = 40000, 0.9
    x = np.zeros((n, 4, 1))
    e = rng.normal(size=(n, 4, 1))
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    assert abs(autocorr_time(x)[0] / 19.0 - 1) < 0.15


def test_replay_reports_a_last_partial_chunk() -> None:
    """A chain saved with another chunk length: every saved step is reported, the last chunk short."""
    from vidsim.posterior.sampler import _replay

    chain = np.cumsum(np.random.default_rng(0).normal(size=(130, 8, 2)), axis=0)
    recs = _replay(chain, SamplerConfig(n_walkers=8, chunk=50, min_steps=100, max_steps=200, seed=5))
    assert [r["step"] for r in recs] == [50, 100, 130] and all(r["resumed"] for r in recs)
    assert np.isinf(recs[0]["tau_max"]) and np.isinf(recs[1]["tau_max"]) and np.isfinite(recs[2]["tau_max"])
    assert recs[2]["acceptance"] == 1.0  # every walker moves at every step of this random walk
    assert _replay(chain[:30], SamplerConfig(n_walkers=8, chunk=50, min_steps=100, max_steps=200))[0]["step"] == 30


def test_the_sampler_keeps_a_14d_gaussian_at_its_width() -> None:
    """emcee 3.1's DESnookerMove does not leave the target invariant: mixed 20 % with DE moves it sampled a
    14-D standard normal with sd 0.91-0.92 (every interval ~9 % too narrow; the 3-D test above allows 8 %
    and saw 2 %). The project's SnookerMove follows Ter Braak & Vrugt (2008): sd within 3 %."""
    D = 14

    def lp(U):
        return -0.5 * np.sum(np.atleast_2d(U) ** 2, axis=1)

    cfg = SamplerConfig(n_walkers=32, max_steps=4000, min_steps=4000, chunk=4000, seed=0, de_fraction=0.8, init_scale=1.0)
    ch = sample(lp, np.zeros(D), np.eye(D), cfg, None, None, vectorize=True)
    S = ch.chain[500:].reshape(-1, D)
    assert abs(S.std(0).mean() - 1.0) < 0.03, S.std(0).mean()
    lo, hi = np.percentile(S, [5, 95], axis=0)
    assert abs((hi - lo).mean() / (2 * 1.6449) - 1.0) < 0.03
