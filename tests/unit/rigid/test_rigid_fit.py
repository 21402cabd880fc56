"""Recovery of thrown-T parameters from silhouettes of an independent engine (MuJoCo), known truth."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.reality.rigid import RigidRealityConfig, make_throw
from vidsim.rigid.body import BoxBody, RigidBodyError
from vidsim.rigid.evaluate import perturbed_guess, score
from vidsim.rigid.fit import FitConfig, Stage, fit_throw, icosahedral_group

# half resolution at most: the CI version of the benchmark table
SMALL = {
    "screen": [Stage(0.25, 10, 20, 1.0), Stage(0.25, 20, 25, 1.0)],
    "screen_keep": [6, 2],
    "refine": [Stage(0.25, None, 30, 1.0), Stage(0.5, None, 30, 0.3)],
    "final": [Stage(0.5, None, 60, 0.0)],
}


def _throw(seed):
    th = make_throw(seed, RigidRealityConfig(n_background=3), render=False)
    return th, BoxBody.from_meta(th.meta["object"])


@pytest.mark.slow
@pytest.mark.parametrize("seed", [11, 12])
def test_recovery_from_30_degree_guess(seed):
    th, body = _throw(seed)
    guess = perturbed_guess(th.truth, np.random.default_rng(seed), orient_deg=30.0)
    res = fit_throw(th.masks, th.times, th.camera, body, guess, {**SMALL, "multistart": "none"})
    s = score(res, th.truth, body)
    assert s["success"], s
    assert res.history[0] > 3 * res.history[-1]  # the descent did the work


@pytest.mark.slow
def test_recovery_from_90_degree_guess_needs_the_multistart():
    """A throw whose 90-degree guess a single start does not recover (12.6 degrees off, measured in
    review) and the icosahedral multistart does (0.57). Until 6 Dec 2026 this test used a throw
    that a single start recovers too, so a multistart that did nothing passed it."""
    th, body = _throw(12)
    guess = perturbed_guess(th.truth, np.random.default_rng(12), orient_deg=90.0)
    single = score(fit_throw(th.masks, th.times, th.camera, body, guess, {**SMALL, "multistart": "none"}),
                   th.truth, body)
    assert not single["success"], single
    res = fit_throw(th.masks, th.times, th.camera, body, guess, {**SMALL, "multistart": "icosahedral"})
    s = score(res, th.truth, body)
    assert s["success"], s
    assert res.n_starts == 30  # 60 group elements modulo the T's half-turn symmetry


def test_icosahedral_group_is_a_group():
    G = icosahedral_group()
    assert G.shape == (60, 3, 3)
    assert np.allclose(G[0], np.eye(3))
    prod = G[7] @ G[23]
    assert min(np.abs(prod - g).max() for g in G) < 1e-9


def test_bad_inputs_are_named():
    th, body = _throw(11)
    guess = perturbed_guess(th.truth, np.random.default_rng(0))
    with pytest.raises(RigidBodyError, match="masks"):
        fit_throw(th.masks[:, :100], th.times, th.camera, body, guess)
    with pytest.raises(RigidBodyError, match="quaternion"):
        fit_throw(th.masks, th.times, th.camera, body, {**guess, "quaternion": [0, 0, 0]})
    with pytest.raises(RigidBodyError, match="unknown field 'itermax'"):
        FitConfig.from_dict({"itermax": 3})
    empty = np.zeros_like(th.masks)
    with pytest.raises(RigidBodyError, match="visible"):
        fit_throw(empty, th.times, th.camera, body, guess)


def test_stage_driver_reads_body_and_guess_from_meta():
    from vidsim.rigid.stage import estimate_throw

    th, body = _throw(14)
    guess = perturbed_guess(th.truth, np.random.default_rng(14), orient_deg=10.0, omega_rel=0.05, vel_rel=0.05,
                            pos_m=0.02, grav_deg=2.0)
    meta = {**th.meta, "initial_guess": guess}
    cfg = {**SMALL, "multistart": "none", "refine": [Stage(0.5, None, 20, 0.3)], "final": []}
    est = estimate_throw(None, th.times, th.camera, meta, fit_cfg=cfg, masks=th.masks)
    assert est.fit.mean_iou > 0.9
    with pytest.raises(RigidBodyError, match="object"):
        estimate_throw(None, th.times, th.camera, {}, masks=th.masks)
    with pytest.raises(RigidBodyError, match="initial guess"):
        estimate_throw(None, th.times, th.camera, th.meta, masks=th.masks)


def test_two_solution_report_ignores_symmetry_and_flags_distinct_ties():
    from vidsim.rigid.dynamics import quat_exp, quat_mul
    from vidsim.rigid.fit import Candidate, distinct_alternatives, rot_to_quat

    _, body = _throw(11)
    p = np.r_[0.0, 0.5, 3.0, 0, 0, 0, 0.3, -5.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0]  # not spinning
    q = quat_exp(np.array([0.2, 0.4, -0.1]))
    times = np.linspace(0, 1, 10)
    best = Candidate(p, q, 1.0, 0.98, np.ones(10), [], 0)
    same = Candidate(p, quat_mul(q, rot_to_quat(body.symmetries[1])), 1.0, 0.98, np.ones(10), [], 1)
    other = Candidate(p, quat_mul(q, quat_exp(np.array([0.0, 0.0, 0.5]))), 1.0, 0.975, np.ones(10), [], 2)
    worse = Candidate(p, quat_mul(q, quat_exp(np.array([0.0, 0.0, 0.5]))), 1.0, 0.90, np.ones(10), [], 3)
    assert distinct_alternatives(best, [same, other, worse], body, times, 0.0) == [1]


# a few iterations per stage: the checkpoint's bookkeeping, not the recovery, is under test here
TINY = {"screen": [Stage(0.25, 10, 4, 1.0)], "screen_keep": [2], "refine": [Stage(0.25, None, 4, 1.0)],
        "final": [Stage(0.25, None, 4, 0.0)], "multistart": "icosahedral"}


class _Killed(Exception):
    pass


def test_killed_fit_resumes_from_its_checkpoint_to_the_uninterrupted_result(tmp_path):
    th, body = _throw(11)
    guess = perturbed_guess(th.truth, np.random.default_rng(11), orient_deg=30.0)
    ref = fit_throw(th.masks, th.times, th.camera, body, guess, TINY)  # no checkpoint

    ck = tmp_path / "stages.jsonl"
    seen = []

    def kill_after_ten(done, total, note):
        seen.append(note)
        if len(seen) == 10:
            raise _Killed

    with pytest.raises(_Killed):
        fit_throw(th.masks, th.times, th.camera, body, guess, TINY, on_step=kill_after_ten, checkpoint=ck)
    assert ck.read_text().count('"key"') == 10  # each finished stage was logged as it ended

    res = fit_throw(th.masks, th.times, th.camera, body, guess, TINY, checkpoint=ck)
    assert res.replayed_stages == 10
    np.testing.assert_array_equal(res.params, ref.params)  # bit-identical to the uninterrupted fit
    np.testing.assert_array_equal(res.q0, ref.q0)
    assert res.history == ref.history and res.mean_iou == ref.mean_iou
    assert [c.cost for c in res.alternatives] == [c.cost for c in ref.alternatives]


def test_checkpoint_of_other_inputs_is_moved_aside_not_replayed(tmp_path):
    th, body = _throw(11)
    guess = perturbed_guess(th.truth, np.random.default_rng(11), orient_deg=30.0)
    ck = tmp_path / "stages.jsonl"
    fit_throw(th.masks, th.times, th.camera, body, guess, {**TINY, "multistart": "none"}, checkpoint=ck)
    masks = th.masks.copy()
    k = int(np.flatnonzero(masks.reshape(len(masks), -1).any(1))[3])
    masks[k] = np.roll(masks[k], 2, axis=1)  # one silhouette moved by 2 px: another fit
    res = fit_throw(masks, th.times, th.camera, body, guess, {**TINY, "multistart": "none"}, checkpoint=ck)
    assert res.replayed_stages == 0
    assert (tmp_path / "stages.stale-1.jsonl").is_file()
    # and a changed setting is another fit too
    res = fit_throw(masks, th.times, th.camera, body, guess, {**TINY, "multistart": "none", "hmax": 0.01},
                    checkpoint=ck)
    assert res.replayed_stages == 0
    assert (tmp_path / "stages.stale-2.jsonl").is_file()


def test_stage_driver_fits_with_the_footages_gravity_magnitude():
    """estimate_throw ignored meta['gravity_magnitude'] and fitted every throw with 9.81 m/s^2."""
    from vidsim.rigid.stage import estimate_throw

    th, _ = _throw(14)
    guess = perturbed_guess(th.truth, np.random.default_rng(14), orient_deg=10.0)
    cfg = {"screen": [Stage(0.25, 10, 2, 1.0)], "screen_keep": [1], "refine": [], "final": [], "multistart": "none"}
    meta = {**th.meta, "gravity_magnitude": 1.62, "initial_guess": guess}
    assert estimate_throw(None, th.times, th.camera, meta, fit_cfg=cfg, masks=th.masks).fit.gravity == 1.62
    assert estimate_throw(None, th.times, th.camera, meta, fit_cfg=FitConfig(**cfg), masks=th.masks).fit.gravity == 1.62
    no_g = {k: v for k, v in meta.items() if k != "gravity_magnitude"}  # absent: the settings' value
    assert estimate_throw(None, th.times, th.camera, no_g, fit_cfg={**cfg, "gravity": 3.7}, masks=th.masks).fit.gravity == 3.7
    with pytest.raises(RigidBodyError, match=r"'gravity' = 3\.7 m/s\^2 contradicts meta 'gravity_magnitude' = 1\.62"):
        estimate_throw(None, th.times, th.camera, meta, fit_cfg={**cfg, "gravity": 3.7}, masks=th.masks)
    with pytest.raises(RigidBodyError, match=r"meta: 'gravity_magnitude' must be a number \(m/s\^2\), got 'moon'"):
        estimate_throw(None, th.times, th.camera, {**meta, "gravity_magnitude": "moon"}, fit_cfg=cfg, masks=th.masks)


def test_stage_history_costs_no_extra_objective_evaluations(monkeypatch):
    """The per-iteration history re-evaluated objective and gradient in scipy's callback (76 calls
    for scipy's 58); it now records scipy's value of the iterate, the same number."""
    from vidsim.rigid import fit as F

    th, body = _throw(11)
    guess = perturbed_guess(th.truth, np.random.default_rng(11), orient_deg=30.0)
    fr = F.visible_frames(th.masks)
    p, q, _ = F._parse_guess(guess)
    obj = F.SilhouetteObjective(body, th.camera, th.times[fr][:10], th.masks[fr][:10], float(th.times[fr][0]), 0.25, 1.0)
    seen = {}
    orig = F.minimize

    def spy(*a, **k):
        r = orig(*a, **k)
        seen["nfev"], seen["nit"] = r.nfev, r.nit
        return r

    monkeypatch.setattr(F, "minimize", spy)
    p1, q1, E, hist = F.run_stage(obj, p, q, 6)
    assert seen["nit"] >= 2 and obj.n_evals == seen["nfev"]
    assert len(hist) in (seen["nit"], seen["nit"] + 1) and hist[-1] == E
    assert hist[seen["nit"] - 1] == pytest.approx(obj(p1, q1, grad=False)[0], rel=1e-9)  # the last iterate's value


def test_ambiguity_is_unchecked_with_one_candidate_and_checked_with_two():
    th, body = _throw(11)
    guess = perturbed_guess(th.truth, np.random.default_rng(11), orient_deg=30.0)
    one = fit_throw(th.masks, th.times, th.camera, body, guess, {**TINY, "multistart": "none"})
    assert one.alternatives == [] and one.ambiguous is None and one.summary()["ambiguous"] is None
    two = fit_throw(th.masks, th.times, th.camera, body, guess, {**TINY, "screen": [Stage(0.25, 10, 2, 1.0)]})
    assert len(two.alternatives) == 1 and two.ambiguous in (True, False)
