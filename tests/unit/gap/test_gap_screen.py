"""The gap diagnosis on small synthetic throws drawn by the extended model itself (known answer).

A planted effect must be screened and named first; with nothing planted nothing is named; the
score test's algebra is checked on an exact linear case; the ball diagnosis names per-frame
timing errors only when they are there.
"""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.gap.rigid_diagnose import DiagnoseConfig, diagnose_rigid, score_screen
from vidsim.gap.rigid_model import GapError, RigidGapModel
from vidsim.io.atomic import to_json
from vidsim.rigid.body import t_object
from vidsim.rigid.dynamics import rot_to_quat
from vidsim.video.camera import PinholeCamera, intrinsics

CANDS = ["lens_k1", "com_offset", "linear_drag", "magnus", "time_jitter"]


def _throw(planted: dict[str, list[float]]):
    body, _ = t_object()
    cam = PinholeCamera(intrinsics(400.0, None, 159.5, 119.5), np.eye(3), np.zeros(3), 320, 240)
    times = np.arange(18) / 30.0
    p = np.zeros(14)
    p[0:3] = [-0.8, 0.1, 2.2]
    p[6:9] = [2.6, -3.0, 0.1]
    p[9:12] = [3.0, -4.0, 5.0]
    q = rot_to_quat(np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]))
    names = tuple(planted)
    m = RigidGapModel(body, cam, times, 0.0, q, names, scale=1.0)
    theta = np.r_[p, *[np.asarray(v, float) for v in planted.values()]] if names else p
    cov, ok = m.render(theta)
    assert ok
    masks = cov > 0.5
    fit = {"position": p[0:3].tolist(), "quaternion": q.tolist(), "velocity": p[6:9].tolist(),
           "omega_world": p[9:12].tolist(), "tilt": 0.0, "roll": 0.0, "t0": 0.0}
    return masks, times, cam, body, fit


CFG = DiagnoseConfig(candidates=CANDS, top_k=2, max_nfev=8, scale=0.5)


def test_planted_com_offset_is_screened_and_named_first():
    masks, times, cam, body, fit = _throw({"com_offset": [0.015, 0.0, 0.0]})
    d = diagnose_rigid(masks, times, cam, body, fit, CFG)
    assert d.screen["com_offset"]["rank"] == 1
    assert d.named and d.named[0] == "com_offset", d.verdict
    # measured 0.69 of the held-out excess over the noise floor closed
    assert d.refits["com_offset"]["heldout_closure"] >= 0.5


def test_null_case_names_nothing():
    masks, times, cam, body, fit = _throw({})
    d = diagnose_rigid(masks, times, cam, body, fit, CFG)
    assert d.named == [], d.verdict


def test_score_screen_exact_linear_case(rng):
    n = 400
    Jt = rng.normal(size=(n, 4))
    Ja = rng.normal(size=(n, 1))
    Jb = rng.normal(size=(n, 2))
    r = Jt @ rng.normal(size=4) * 0 + (Ja[:, 0] - Jt @ np.linalg.lstsq(Jt, Ja[:, 0], rcond=None)[0]) * 0.7
    s = score_screen(Jt, {"a": Ja, "b": Jb}, r)
    assert s["a"]["fraction"] == pytest.approx(1.0, abs=1e-9)
    assert s["a"]["step"][0] == pytest.approx(-0.7, rel=1e-9)  # r = J beta - obs convention: step = -beta
    assert s["b"]["fraction"] < 0.05


def test_bad_candidate_and_short_clip_are_clear_errors():
    with pytest.raises(GapError, match="unknown effect 'wind_gusts'"):
        DiagnoseConfig(candidates=["wind_gusts"]).validate()
    masks, times, cam, body, fit = _throw({})
    with pytest.raises(GapError, match="missing field 'tilt'"):
        diagnose_rigid(masks, times, cam, body, {k: v for k, v in fit.items() if k != "tilt"}, CFG)
    with pytest.raises(GapError, match="visible in only"):
        diagnose_rigid(masks[:5], times[:5], cam, body, fit, CFG)


def test_two_planted_effects_are_both_named_by_forward_selection():
    masks, times, cam, body, fit = _throw({"com_offset": [0.015, 0.0, 0.0], "lens_k1": [-0.25]})
    d = diagnose_rigid(masks, times, cam, body, fit, CFG)
    assert sorted(d.named) == ["com_offset", "lens_k1"], d.verdict
    pair = d.refits["+".join(d.named)]
    # the second effect closes most of what the first left, on held-out frames
    assert pair["supported"] and pair["closure_of_remaining"] >= 0.5
    assert d.extra["conditional_screens"], "the second effect comes from a conditional screen"


def test_joint_pair_names_two_effects_only_when_each_adds_to_the_other():
    """The fallback after no single effect was named: a pair is named when it closes half the
    held-out excess and beats each member alone by pair_min_gain; jitter and aliases are never
    paired; the named order follows the single closures."""
    from vidsim.gap.rigid_diagnose import joint_pair_search

    # held-out gap before 100 px, floor 20 px: after = 100 - 80 closure
    singles = {k: {"heldout_closure": c, "heldout_after_px": 100 - 80 * c} for k, c in
               {"angular_drag": 0.23, "com_offset": 0.28, "wind": 0.45, "time_jitter": 0.3, "time_rate": 0.2,
                "gravity_scale": 0.2}.items()}
    pair_closure = {("angular_drag", "com_offset"): 0.61, ("angular_drag", "wind"): 0.55,
                    ("com_offset", "wind"): 0.52, ("gravity_scale", "time_rate"): 0.9}
    judged = []

    def judge(effs):
        judged.append(tuple(effs))
        c = pair_closure[tuple(effs)]
        return {"heldout_closure": c, "heldout_after_px": 100 - 80 * c, "params": {}}

    def supported(res, added, prev):
        return res["heldout_closure"] >= 0.5

    cfg = DiagnoseConfig()
    named, prev, out = joint_pair_search(["angular_drag", "com_offset", "wind"], singles, judge, supported, cfg,
                                         lambda s: None, 20.0)
    # angular_drag+wind (0.55) and com_offset+wind (0.52) add less than 0.2 to wind's own 0.45
    assert named == ["com_offset", "angular_drag"]
    assert out["angular_drag+wind"]["supported"] is False and out["angular_drag+com_offset"]["supported"] is True
    # the pair's refit is filed as "first+second", the second's share of what the first left
    assert singles["com_offset+angular_drag"] is prev and prev["named_jointly"]
    assert prev["closure_of_remaining"] == pytest.approx((0.61 - 0.28) / (1 - 0.28))
    judged.clear()
    named, prev, out = joint_pair_search(["time_jitter", "com_offset"], singles, judge, supported, cfg,
                                         lambda s: None, 20.0)
    assert named == [] and prev is None and judged == []  # jitter has its own rule, never in a joint pair
    # time_rate and gravity_scale are stated aliases: never a pair
    named, _, _ = joint_pair_search(["gravity_scale", "time_rate"], singles, judge, supported, cfg, lambda s: None,
                                    20.0)
    assert named == [] and judged == []
    with pytest.raises(GapError, match="pair_min_gain"):
        DiagnoseConfig(pair_min_gain=1.5).validate()


def test_score_reads_jointly_named_strengths_from_the_pair_refit():
    """Effects named as a pair were estimated together: the suite scores both strengths from the
    pair's refit, not the first member's own single refit (whose value absorbed the second)."""
    from vidsim.gap.rigid_diagnose import RigidDiagnosis
    from vidsim.gap.suite import score_case

    def refit(params, closure, **kw):
        return {"params": {k: {"value": v} for k, v in params.items()}, "heldout_closure": closure,
                "heldout_after_px": 50.0, **kw}

    z = np.zeros(3)
    refits = {"com_offset": refit({"com_offset": [0.0, 0.0, 0.03]}, 0.28),
              "angular_drag": refit({"angular_drag": [9.0]}, 0.23),
              "com_offset+angular_drag": refit({"com_offset": [0.0, 0.0, 0.011], "angular_drag": [2.1]}, 0.61,
                                               closure_of_remaining=0.46, named_jointly=True)}
    body, _ = t_object()
    truth = {"effects": {"com_offset": [0.0, 0.0, 0.01], "angular_drag": 2.0}}
    case = {"label": ["angular_drag", "com_offset"]}

    def diag(refits):
        return RigidDiagnosis(["com_offset", "angular_drag"], "explained", z, z, np.array([0]), np.ones(1),
                              np.ones(1), {}, refits, {}, z, z, z, 0.0, 0, {"gap_present": True})

    sc = score_case(case, diag(refits), truth, body)
    assert sc["correct"]
    assert sc["recovery"]["com_offset"]["estimate"] == [0.0, 0.0, 0.011]
    assert sc["recovery"]["com_offset"]["rel_error"] == pytest.approx(0.1)
    assert sc["closure"]["com_offset"] == 0.28  # the closure stays the first member's own
    # named one after the other (not jointly): the first's strength is its own refit's
    seq = dict(refits)
    seq["com_offset+angular_drag"] = {k: v for k, v in refits["com_offset+angular_drag"].items() if k != "named_jointly"}
    sc = score_case(case, diag(seq), truth, body)
    assert sc["recovery"]["com_offset"]["estimate"] == [0.0, 0.0, 0.03]


def test_cloth_score_reads_jointly_named_strengths_from_the_pair_refit():
    """The cloth suite's scoring follows the same rule as the rigid one."""
    from vidsim.gap.cloth_diagnose import ClothDiagnosis
    from vidsim.gap.cloth_suite import ClothSceneConfig, score_case

    def refit(params, closure, **kw):
        return {"params": {k: {"value": v} for k, v in params.items()}, "heldout_closure": closure,
                "heldout_after_px": 50.0, **kw}

    z = np.zeros(3)
    refits = {"grip_slip": refit({"grip_slip": [0.03, 0.03]}, 0.3),
              "lens_k1": refit({"lens_k1": [0.9]}, 0.2),
              "grip_slip+lens_k1": refit({"grip_slip": [0.021, 0.019], "lens_k1": [0.28]}, 0.7,
                                         closure_of_remaining=0.57, named_jointly=True)}
    truth = {"kind": "twin", "effects": {"grip_slip": {"drop": 0.02}, "lens_k1": 0.3}}
    case = {"label": ["grip_slip", "lens_k1"]}
    diag = ClothDiagnosis(["grip_slip", "lens_k1"], "explained", z, z, np.array([0]), np.ones(1), np.ones(1), {},
                          refits, {}, z, z, 0.0, 0, {"gap_present": True})
    sc = score_case(case, diag, truth, ClothSceneConfig())
    assert sc["correct"]
    assert sc["recovery"]["grip_slip"]["estimate"] == [0.021, 0.019]
    assert sc["recovery"]["lens_k1"]["estimate"] == [0.28]
    assert sc["closure"]["grip_slip"] == 0.3 and sc["closure"]["lens_k1"] == 0.57


def test_the_diagnosis_models_the_fits_own_gravity(monkeypatch):
    """A fit made with the footage's gravity magnitude (fit.yaml: gravity_magnitude, e.g. 3.71 on
    Mars) is diagnosed with that magnitude (was always 9.81: a built-in mismatch that gravity_scale
    or time_rate could have been named for)."""
    from vidsim.gap import rigid_diagnose
    from vidsim.rigid.body import t_object
    from vidsim.video.camera import PinholeCamera, intrinsics

    seen = {}

    class Stop(Exception):
        pass

    def fake_model(*args, **kw):
        seen["gravity"] = args[9] if len(args) > 9 else kw.get("gravity")
        raise Stop

    monkeypatch.setattr(rigid_diagnose, "RigidGapModel", fake_model)
    cam = PinholeCamera(intrinsics(400.0, None, 79.5, 59.5), np.eye(3), np.zeros(3), 160, 120)
    masks = np.zeros((12, 120, 160), bool)
    masks[:, 40:60, 50:80] = True
    fit = {"position": [0, 0, 1.0], "quaternion": [1, 0, 0, 0], "velocity": [0, 0, 0], "omega_world": [0, 0, 0],
           "tilt": 0.0, "roll": 0.0, "t0": 0.0, "gravity_magnitude": 3.71}
    with pytest.raises(Stop):
        rigid_diagnose.diagnose_rigid(masks, np.arange(12) / 30.0, cam, t_object()[0], fit)
    assert seen["gravity"] == 3.71
    with pytest.raises(rigid_diagnose.GapError, match="gravity_magnitude"):
        rigid_diagnose.diagnose_rigid(masks, np.arange(12) / 30.0, cam, t_object()[0], {**fit, "gravity_magnitude": 0})


def test_verdict_allows_effects_the_reality_holds_throughout_but_nothing_else():
    """A case's verdict (both domains): the withheld effect or a stated alias first; every effect of
    a combination in any order; nothing for none/unexplained, except the case's `allowed` effects
    (the rigid gust's throw has the drag case's drag throughout: naming it is not wrong, review of
    6 Dec 2026). A bad `allowed` entry is refused when the case's labels are read, before a run."""
    from vidsim.gap.cloth_model import CLOTH_EFFECTS
    from vidsim.gap.rigid_model import RIGID_EFFECTS
    from vidsim.gap.suite import case_labels, named_correctly

    def ok(case, named, lib=RIGID_EFFECTS):
        return named_correctly(case, case_labels(case, lib), named, lib)

    gust = {"label": "unexplained", "allowed": ["quadratic_drag"]}
    assert ok(gust, []) and ok(gust, ["quadratic_drag"])
    assert not ok(gust, ["wind"]) and not ok(gust, ["quadratic_drag", "wind"])
    assert not ok({"label": "unexplained"}, ["quadratic_drag"])  # without `allowed`, as before
    assert ok({"label": "none"}, []) and not ok({"label": "none"}, ["lens_k1"])
    assert ok({"label": "magnus"}, ["magnus", "lens_k1"]) and not ok({"label": "magnus"}, ["lens_k1", "magnus"])
    assert ok({"label": ["lens_k1", "com_offset"]}, ["com_offset", "lens_k1"])
    assert not ok({"label": ["lens_k1", "com_offset"]}, ["com_offset"])
    assert ok({"label": "grip_slip"}, ["grip_slip"], CLOTH_EFFECTS)
    for bad in ("quadratic_drag", ["no_such_effect"], [3]):
        with pytest.raises(GapError, match="allowed"):
            case_labels({"label": "unexplained", "allowed": bad})


class _Killed(Exception):
    pass


def test_killed_diagnosis_resumes_from_its_checkpoint_with_the_same_result(tmp_path, monkeypatch):
    """A diagnosis killed after its screen, rerun with the same checkpoint folder, replays the base
    refit, floor and screen (no refit of the base again) and ends with the uninterrupted result."""
    from vidsim.gap import rigid_diagnose

    masks, times, cam, body, fit = _throw({"com_offset": [0.015, 0.0, 0.0]})
    d_whole = diagnose_rigid(masks, times, cam, body, fit, CFG)
    whole = d_whole.to_dict()

    def kill_after_screen(note):
        if note == "screen":
            raise _Killed

    with pytest.raises(_Killed):
        diagnose_rigid(masks, times, cam, body, fit, CFG, progress=kill_after_screen, checkpoint=tmp_path)
    assert len(list(tmp_path.glob("*.pkl"))) == 3  # base, floor, screen

    starts = []
    real_refit = rigid_diagnose.refit
    monkeypatch.setattr(rigid_diagnose, "refit", lambda prob, th0, *a, **k: starts.append(len(th0)) or
                        real_refit(prob, th0, *a, **k))
    d_resumed = diagnose_rigid(masks, times, cam, body, fit, CFG, checkpoint=tmp_path)
    assert starts and min(starts) > 14, "the base (14 parameters) was refitted again"
    resumed = d_resumed.to_dict()
    whole.pop("seconds"), resumed.pop("seconds")
    assert to_json(resumed) == to_json(whole)
    assert np.array_equal(d_resumed.signed_heatmap, d_whole.signed_heatmap)
    # inputs changed: nothing replayed (another key), the result is the new input's
    other = dict(fit, position=[-0.79, 0.1, 2.2])
    starts.clear()
    diagnose_rigid(masks, times, cam, body, other, CFG, checkpoint=tmp_path)
    assert 14 in starts
