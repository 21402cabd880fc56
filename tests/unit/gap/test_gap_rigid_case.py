"""One rigid withheld-effect case end to end through the suite's own path (MuJoCo reality -> single-
start fit from the perturbed-guess protocol -> blind diagnosis -> score), as the README's gap figures
are made: the unit tests of the screen start from the true state on footage the gap model drew itself
(review, 5 Dec 2026). The case is the public suite's `com_offset` (conf/gap/default.yaml), unchanged."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pytest
import yaml

from vidsim.config import CONF_DIR
from vidsim.gap.suite import run_case


class SealedTruth(Mapping):
    """A throw's truth that records (and refuses) every read while sealed: it is sealed from the
    moment the initial-guess protocol has read it until the scoring starts, so the fit and the
    diagnosis cannot read it, whether they were handed it or a reference to it leaked."""

    def __init__(self, truth: dict) -> None:
        self._truth = truth
        self.sealed = False
        self.reads: list[str] = []

    def _read(self, what: str) -> None:
        if self.sealed:
            self.reads.append(what)
            raise AssertionError(f"the truth was read before scoring ({what})")

    def __getitem__(self, key):
        self._read(repr(key))
        return self._truth[key]

    def __iter__(self):
        self._read("iteration")
        return iter(self._truth)

    def __len__(self) -> int:
        self._read("len")
        return len(self._truth)


def rel_diff(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.mark.slow
def test_withheld_com_offset_is_named_first_and_recovered_from_mujoco_footage(monkeypatch):
    import vidsim.gap.suite as suite
    import vidsim.rigid.evaluate as evaluate

    seen = {}
    real = suite.diagnose_rigid

    def spy(*args, **kw):
        seen["args"], seen["kw"] = args, kw
        return real(*args, **kw)

    # the truth is sealed between the guess protocol (which reads it) and the scoring
    real_make, real_guess, real_score = suite.make_case, evaluate.perturbed_guess, suite.score_case
    sealed: list[SealedTruth] = []
    was_sealed: list[bool] = []  # the seal's state when scoring opened it (True: it was in place)

    def make_case(*a, **k):
        masks, th = real_make(*a, **k)
        th.truth = SealedTruth(th.truth)
        sealed.append(th.truth)
        return masks, th

    def perturbed_guess(truth, *a, **k):
        guess = real_guess(truth, *a, **k)
        truth.sealed = True
        return guess

    def score_case(case, diag, truth, *a, **k):
        was_sealed.append(truth.sealed)
        truth.sealed = False
        return real_score(case, diag, truth, *a, **k)

    monkeypatch.setattr(suite, "diagnose_rigid", spy)
    monkeypatch.setattr(suite, "make_case", make_case)
    monkeypatch.setattr(evaluate, "perturbed_guess", perturbed_guess)
    if hasattr(suite, "perturbed_guess"):  # imported at module level by a refactor: patch that name too
        monkeypatch.setattr(suite, "perturbed_guess", perturbed_guess)
    monkeypatch.setattr(suite, "score_case", score_case)
    case = yaml.safe_load(open(f"{CONF_DIR}/gap/default.yaml"))["cases"]["com_offset"]
    diag, score, masks, th = run_case(case)
    # the seal was in place from the guess to the scoring (and scoring opened it)
    assert len(sealed) == 1 and th.truth is sealed[0] and was_sealed == [True] and not sealed[0].sealed
    assert sealed[0].reads == [], f"the fit or the diagnosis read the truth: {sealed[0].reads}"
    assert score["correct"] and score["named_first"] == "com_offset", score
    # the naming step tested the others: a list (empty when nothing else was as good on held-out)
    assert isinstance(score["named_first_as_good"], list), score
    # the shrinkage and strength targets (measured 0.9+ and 5 % in the suite runs)
    assert score["closure"]["com_offset"] >= 0.5, score
    assert score["recovery"]["com_offset"]["rel_error"] <= 0.30, score["recovery"]
    # the diagnosis was handed the footage, times, camera, body and the fit: the truth only scores
    # (the seal above: it read nothing of the truth; here: it was not handed the truth's values)
    args = list(seen["args"]) + list(seen["kw"].values())
    assert not any(a is th.truth or a is th.truth._truth for a in args)
    fit = args[4]
    assert isinstance(fit, dict) and not {"effects", "capture_times", "seed"} & set(fit), sorted(fit)
    for k in ("position", "velocity", "omega_world"):  # the fit's estimates, not the truth's values
        assert rel_diff(fit[k], th.truth[k]) > 1e-6, (k, fit[k], th.truth[k])
    q, q_true = np.asarray(fit["quaternion"], float), np.asarray(th.truth["quaternion"], float)
    assert min(rel_diff(q, q_true), rel_diff(-q, q_true)) > 1e-6, (q, q_true)  # q and -q: one rotation
    assert np.array_equal(args[1], th.times)  # the footage's times
