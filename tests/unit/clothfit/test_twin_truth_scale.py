"""score_cloth_twin's truth scale and chaos-averaged ratio. Truth scale: failed simulations are left out of the quantiles, and too many
of them (or a failed truth) give no scale at all rather than a quantile of failure scores."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from vidsim.cli.cloth_twin_score import chaos_mean, truth_scale
from vidsim.cloth.params import ClothParams


class _Obj:
    """Scores a parameter set by its bend (a known smooth response); fails where told to."""

    def __init__(self, fail_every: int = 0):
        self.n = 0
        self.fail_every = fail_every

    def evaluate_params(self, p):
        self.n += 1
        if self.fail_every and self.n % self.fail_every == 0:
            return SimpleNamespace(ok=False, score=1e30)
        return SimpleNamespace(ok=True, score=100.0 * p.bend / 2e-5)


def test_quantiles_of_a_known_response():
    true = ClothParams(bend=2e-5)
    s = truth_scale(_Obj(), true, 100.0, ["bend"], 0.05, 400, 0, 1.10)
    # ratio = exp(N(0, 0.05)): its 90 % point is exp(1.2816 * 0.05)
    assert s["ratio_q90"] == pytest.approx(np.exp(1.2816 * 0.05), abs=0.01)
    assert s["ratio_q50"] == pytest.approx(1.0, abs=0.01)
    assert s["fraction_within_heldout_ratio"] == pytest.approx(np.mean(np.array(s["ratios"]) <= 1.10))
    assert s["failed"] == 0 and len(s["ratios"]) == 400


def test_failed_draws_are_left_out_or_void_the_scale():
    true = ClothParams(bend=2e-5)
    s = truth_scale(_Obj(fail_every=20), true, 100.0, ["bend"], 0.05, 40, 0, 1.10)  # 2 of 40 fail
    assert s["failed"] == 2 and len(s["ratios"]) == 38 and max(s["ratios"]) < 2.0
    assert truth_scale(_Obj(fail_every=5), true, 100.0, ["bend"], 0.05, 40, 0, 1.10) is None  # 8 of 40
    assert truth_scale(_Obj(), true, 100.0, ["bend"], 0.05, 40, 0, 1.10, true_ok=False) is None
    assert truth_scale(_Obj(), true, 100.0, ["bend"], 0.05, 0, 0, 1.10) is None


class _Chaotic(_Obj):
    """A response with a chaotic part: 100 bend / 2e-5 times (1 + 0.1 sin(1e6 bend / 2e-5))."""

    def evaluate_params(self, p):
        r = super().evaluate_params(p)
        if r.ok:
            r.score *= 1.0 + 0.1 * np.sin(1e6 * p.bend / 2e-5)
        return r


def test_chaos_mean_uses_common_draws_and_averages_each_side():
    true = ClothParams(bend=2e-5)
    # the same parameters on both sides: common draws give exactly 1 (independent draws would not)
    c = chaos_mean(_Chaotic(), true, true, ["bend"], 1e-4, 8, 0)
    assert c["ratio"] == 1.0 and c["errors_selected"] == c["errors_true"]
    # the chaotic part moves single runs by up to 10 %; the means follow the smooth response
    est = ClothParams(bend=2.2e-5)
    c = chaos_mean(_Chaotic(), est, true, ["bend"], 1e-4, 400, 0)
    assert np.ptp(np.array(c["errors_true"]) / 100.0) > 0.15
    assert c["error_true_mean"] == pytest.approx(np.mean(c["errors_true"]))
    assert c["ratio"] == pytest.approx(1.1, rel=0.01)
    # sigma 0: every copy is the unmoved run
    c0 = chaos_mean(_Obj(), est, true, ["bend"], 0.0, 3, 0)
    assert c0["errors_true"] == [100.0] * 3 and c0["ratio"] == pytest.approx(1.1)


def test_chaos_mean_is_void_when_a_copy_fails_or_off():
    true = ClothParams(bend=2e-5)
    assert chaos_mean(_Obj(fail_every=7), true, true, ["bend"], 1e-4, 8, 0) is None
    assert chaos_mean(_Obj(), true, true, ["bend"], 1e-4, 0, 0) is None
