"""Motion blur as the segmentation sees it (vidsim.gap.rigid_model.segmented_blur) and the
choice of its threshold on training frames (vidsim.gap.rigid_diagnose.blur_threshold_refit)."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.gap.rigid_diagnose import blur_threshold_refit
from vidsim.gap.rigid_model import segmented_blur


def _edge(x0: float, w: int = 40) -> np.ndarray:
    """Soft coverage of a half-plane x < x0 on a row of pixels (1-px ramp)."""
    x = np.arange(w) + 0.5
    return np.clip(x0 - x + 0.5, 0.0, 1.0)


def test_zero_exposure_is_the_unblurred_silhouette_exactly():
    c0 = _edge(17.3)
    for thr in (0.1, 0.35, 0.5, 0.9):
        assert np.array_equal(segmented_blur(c0, c0.copy(), thr), c0)


def test_a_moving_edge_is_dilated_by_a_low_threshold_and_kept_by_a_high_one():
    # the edge sweeps from x = 10 to x = 20 during the exposure: the mean coverage falls
    # linearly over the band; a segmentation keeping pixels covered >= 20 % of the exposure
    # reaches x ~ 18, one keeping >= 80 % stops at x ~ 12, and 50 % at the mid-exposure edge
    xs = np.linspace(10.0, 20.0, 41)
    mean = np.mean([_edge(x) for x in xs], axis=0)
    c0 = _edge(15.0)
    area = {thr: segmented_blur(c0, mean, thr).sum() for thr in (0.2, 0.5, 0.8)}
    assert area[0.2] == pytest.approx(18.0, abs=0.6)
    assert area[0.5] == pytest.approx(15.0, abs=0.6)
    assert area[0.8] == pytest.approx(12.0, abs=0.6)
    # binary away from the ramp: no fractional band where a segmented mask has none
    out = segmented_blur(c0, mean, 0.2)
    assert np.all((out[:16] == 1.0)) and np.all(out[20:] == 0.0)


class _Model:
    def __init__(self):
        self.slices = {"motion_blur": slice(0, 1)}
        self.blur_threshold = 0.35


class _Prob:
    def __init__(self):
        self.model = _Model()


def test_threshold_with_the_lowest_training_cost_is_kept_on_the_model():
    costs = {0.2: 5.0, 0.35: 3.0, 0.5: 4.0}
    prob = _Prob()
    seen = []

    def refit_fn(p, t):
        seen.append(p.model.blur_threshold)
        return np.array([p.model.blur_threshold]), {"cost": costs[p.model.blur_threshold]}

    th, info = blur_threshold_refit(prob, np.zeros(1), refit_fn, [0.2, 0.35, 0.5])
    assert seen == [0.2, 0.35, 0.5]
    assert info["blur_threshold"] == 0.35 == prob.model.blur_threshold and th[0] == 0.35
    # without blur in the model: one refit, the model untouched
    prob.model.slices = {}
    seen.clear()
    blur_threshold_refit(prob, np.zeros(1), refit_fn, [0.2, 0.5])
    assert seen == [0.35]
