"""score_cloth_twin's truth scale: failed simulations are left out of the quantiles, and too many
of them (or a failed truth) give no scale at all rather than a quantile of failure scores."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from vidsim.cli.cloth_twin_score import truth_scale
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
