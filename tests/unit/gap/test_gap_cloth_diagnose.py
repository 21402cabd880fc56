"""One reduced cloth gap case end to end: film a twin swatch, fit it, diagnose it blind, score it.

The case is the null case (the twin reality has nothing the model lacks; it differs from the model
only by rendering, segmentation and sensor noise): the diagnosis must name no effect. The clip is
16 frames (0.53 s) at stride 1: the estimator's swatch trajectories become chaotic after about
0.3 s (a relative change of 1e-5 in a stiffness moves vertices by millimetres by the end of a 1 s
clip), so longer clips make finite differences meaningless (docs/gap.md, cloth).

A withheld grip slip (the fabric slides 2 cm down through both grips over 0.5 s) must be named
first and close at least half of the held-out excess over the noise floor (measured: closure
0.57, slip (0.0197, 0.0125) m vs (0.02, 0.02)). A time offset of 12 ms, not named on the whole
outline, must be named on the pixels near the grips (measured: closure 0.65, 11.5 ms). What is
*not* asserted, because it does not hold (measured and reported in docs/gap.md): a withheld wind
of (0.5, 0.8, 0) m/s or a lens k1 of 0.3 is screened first but not named on the same reduced
setting.
"""

from __future__ import annotations

import dataclasses
import inspect
import json

import numpy as np
import pytest

from vidsim.gap import cloth_diagnose
from vidsim.gap.cloth_diagnose import ClothDiagnoseConfig, ClothTrialInput, diagnose_cloth
from vidsim.gap.cloth_suite import ClothSceneConfig, run_case

SCENE = ClothSceneConfig(n_frames=16, frame_stride=1, budget=30, grid_levels=3)


@pytest.fixture(scope="module")
def null_case():
    """The null case, run with spies on the fit and the diagnosis: what each was handed."""
    from vidsim.gap import cloth_suite

    cfg = ClothDiagnoseConfig(top_k=2, metric_terms=True)
    seen: dict = {}
    real_fit, real_diag = cloth_suite.fit_case, cloth_suite.diagnose_cloth

    def fit_spy(*a, **k):
        seen["fit_args"] = a
        out = real_fit(*a, **k)
        seen["fitted"] = out[0]
        return out

    def diag_spy(trial, params0, *a, **k):
        seen["diag_trial"], seen["diag_params0"] = trial, params0
        return real_diag(trial, params0, *a, **k)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(cloth_suite, "fit_case", fit_spy)
        mp.setattr(cloth_suite, "diagnose_cloth", diag_spy)
        diag, score, cc = run_case({"label": "none", "seed": 320}, SCENE, cfg)
    return diag, score, cc, seen


def test_the_diagnosis_is_handed_no_truth(null_case):
    """What the diagnosis can read is the footage's side only (the suite keeps truth apart): its
    signature and input type hold no truth, and in a run it is handed the blind fit's parameters,
    which differ from the twin's true ones on every estimated name."""
    params = inspect.signature(diagnose_cloth).parameters
    assert not any("truth" in p for p in params)
    fields = {f.name for f in dataclasses.fields(ClothTrialInput)}
    assert fields == {"sil", "times", "corner_paths", "camera", "projector", "size", "density", "noise_sigma",
                      "theta", "mask"}
    _, _, cc, seen = null_case
    assert seen["diag_params0"] is seen["fitted"]  # the fit's result, not something else
    assert seen["diag_trial"] is cc.trial and seen["fit_args"][0] is cc.fit_trial
    truth = cc.truth["params"]
    for name in SCENE.estimate:  # a fit that copied the truth would equal it to the bit
        assert getattr(seen["fitted"], name) != truth[name], name


def test_floor_twin_on_the_models_mesh_moves_exactly_as_the_model(null_case):
    """The floor is rendering, segmentation and noise only: at the model's resolution its twin is
    simulated with the model's own fixed step and scheme (its motion equals the model's bit for
    bit), so no chaotic divergence of two integrators is counted as irreducible."""
    from vidsim.cloth import mid_range_params
    from vidsim.clothfit.features import FeatureSettings
    from vidsim.gap.cloth_model import ClothGapModel, ClothSetup

    diag, _, cc, _ = null_case
    setup = ClothSetup(cc.trial.times, cc.trial.corner_paths, np.asarray(diag.frames)[:8], cc.trial.camera,
                       cc.trial.size, cc.trial.density, SCENE.resolution, SCENE.settle_s_model)
    model = ClothGapModel(setup, mid_range_params(density=cc.trial.density), ["bend", "stretch"], (), 0.5, 1.0)
    th = model.theta0()
    sil, V, info = cloth_diagnose.twin_floor(model, th, cc.trial, ClothDiagnoseConfig(), FeatureSettings())
    assert info["resolution"] == SCENE.resolution and sil.shape[0] == 8
    np.testing.assert_array_equal(V, model.simulate(th)[0][setup.obs])


def test_null_case_names_nothing(null_case):
    diag, score, cc, _ = null_case
    assert diag.named == [], diag.verdict
    assert score["correct"] and score["named_first"] == "none"
    # every candidate refitted was judged on held-out frames and found unsupported
    assert diag.refits and not any(r["supported"] for r in diag.refits.values())
    assert set(diag.test).isdisjoint(diag.train) and len(diag.test) >= 4
    # scoring's footprints: no effect to film without; two noise draws differ on the outline only
    assert score["effect_footprint_px"] is None
    assert 0.0 < score["noise_footprint_px"] < 100.0  # measured 17 px per frame of 76 800


@pytest.mark.slow
def test_withheld_grip_slip_is_named_first_and_closes_half_the_excess():
    """One reduced withheld-effect case (51 CPU-s): the first step of the selection only, judged on
    the whole outline (the grips pass of the default ``split`` names it too, closure 0.62: docs/gap.md;
    the time offset test below covers that pass)."""
    case = {"label": "grip_slip", "seed": 303, "effects": {"grip_slip": {"drop": 0.02, "ramp_s": 0.5}}}
    diag, score, _ = run_case(case, SCENE, ClothDiagnoseConfig(top_k=1, pairs=False, metric_terms=False,
                                                               region="outline"))
    assert diag.named[:1] == ["grip_slip"], diag.verdict
    assert score["correct"]
    # top_k = 1: no other candidate was refitted, so none can be as good
    assert score["named_first_as_good"] == []
    floor, before = score["noise_floor_px"], score["heldout_before_px"]
    after = score["heldout_after_px"]["grip_slip"]
    assert (before - after) / (before - floor) >= 0.5
    assert score["closure"]["grip_slip"] >= 0.5
    # the slip's footprint on the footage is well above the sensor noise's
    assert score["effect_footprint_px"] > 2.0 * score["noise_footprint_px"]


def test_null_case_report_is_consistent(null_case):
    diag, score, _, _ = null_case
    d = json.loads(json.dumps(diag.to_dict()))
    floor = d["noise_floor_heldout_px"]
    before = score["heldout_before_px"]
    assert 0 < floor < before  # the fit is not exact: held-out gap above the rendering floor
    split = d["where"]["split_heldout_px"]
    # the parts sum to the total by construction (the dynamics part is the remainder), so that sum
    # checks nothing; checked instead: each entry against the quantity it is defined from, reported
    # elsewhere in the result (nothing is named here, so the gap, floor, camera part and "where" are
    # all the outline pass's)
    test = d["heldout_frames"]
    assert split["total"] == pytest.approx(np.mean(np.asarray(d["gap_per_frame_px"])[test]), rel=1e-9)
    assert split["total"] == pytest.approx(before, rel=1e-9)
    assert split["rendering_and_noise (floor)"] == pytest.approx(floor, rel=1e-9)
    # the camera part: how much of the held-out gap the imaging-only refit (motion fixed) closes
    # (here none: its held-out gap, measured 325 px, is above the base's 302, so the part is 0)
    cam = d["camera_part"]
    assert cam["effects"], cam
    cam_after = cam["heldout_after_px"]
    assert split["camera (imaging and timing candidates, motion fixed)"] == pytest.approx(
        max(before - max(cam_after, floor), 0.0), rel=1e-9, abs=1e-12), (split, cam_after)
    per_part = d["where"]["per_part"]
    assert set(per_part) == set(cloth_diagnose.PARTS)
    assert all(v["px"] >= 0 for v in per_part.values())
    assert "per_metric_term" in d["where"]
    assert np.isfinite(d["gap_per_frame_px"]).all()


def test_effect_start_finds_a_coarse_start_the_refit_from_zero_would_miss():
    """Observed silhouettes made by the model itself with a wind of 3 x its scale along y: the
    start search tries +-1 and +-3 scales per axis and must pick exactly that point."""
    from vidsim.cloth import mid_range_params
    from vidsim.gap.cloth_diagnose import Problem, effect_start
    from vidsim.gap.cloth_model import CLOTH_EFFECTS, ClothGapModel, ClothSetup
    from vidsim.reality.cloth import corner_paths, swatch_motion
    from vidsim.video.camera import PinholeCamera, intrinsics, look_at

    R, t = look_at(np.array([0.0, -1.6, 0.9]), np.array([0.0, 0.0, 0.85]), np.array([0.0, 0.0, 1.0]))
    cam = PinholeCamera(intrinsics(560.0, None, 159.5, 119.5), R, t, 320, 240, np.zeros(5))
    times = np.arange(10) / 30.0
    setup = ClothSetup(times, corner_paths(swatch_motion("exp1"), times), np.arange(0, 10, 2), cam, 0.3, 0.2,
                       resolution=6, settle_s=0.3)
    m = ClothGapModel(setup, mid_range_params(density=0.2), ["bend", "stretch"], ("wind",), scale=0.5)
    th0 = m.theta0()
    truth = th0.copy()
    truth[m.slices["wind"].start + 1] = 3.0 * CLOTH_EFFECTS["wind"].scale
    obs, ok = m.render(truth)
    assert ok
    roi = np.ones_like(obs, bool)
    prob = Problem(m, obs, roi, np.arange(obs.shape[0]), {}, 1e-3)
    start, n = effect_start(prob, th0, "wind", [1.0, 3.0])
    assert n == 1 + 3 * 2 * 2
    np.testing.assert_array_equal(start, truth)
    same, n0 = effect_start(prob, th0, "wind", [])
    assert n0 == 1 and same is th0


def test_global_search_leaves_a_local_basin_and_never_returns_worse():
    """The derivative-free search before a refit: on a residual with a local basin at the start and
    a deeper one 2 typical scales away (where a trust region started at the local minimum cannot
    go), it must return a point of lower cost inside its box and the bounds; at the global minimum
    it returns the start itself; with no evaluations it does nothing."""
    from types import SimpleNamespace

    from vidsim.gap.cloth_diagnose import global_search

    xs = np.array([0.5, 0.2, 1.0])
    lower = np.array([-np.inf, 0.0, -np.inf])
    model = SimpleNamespace(x_scale=lambda: xs, lower=lambda: lower, upper=lambda: np.full(3, np.inf))
    deep = np.array([1.0, 0.4, 0.0])   # 2 typical scales from the start along the first two axes

    def residual(th):
        d0, d1 = (th - np.zeros(3)) / xs, (th - deep) / xs
        # two wells: a shallow one at the start (depth 1) and a deep one at `deep` (depth 4)
        return np.array([np.sqrt(5.0 - 1.0 * np.exp(-4 * d0 @ d0) - 4.0 * np.exp(-d1 @ d1))])

    prob = SimpleNamespace(model=model, residual=residual)
    start = np.zeros(3)
    th, n = global_search(prob, start, 80, width=3.0, seed=0)
    assert n == 81
    c0, c = float(residual(start) @ residual(start)), float(residual(th) @ residual(th))
    assert c < c0 - 1.0, (c0, c, th)
    assert np.all(np.abs(th - start) <= 3.0 * xs + 1e-12) and th[1] >= 0.0
    assert np.all(np.abs(th[:2] - deep[:2]) <= 0.6 * xs[:2]), th
    best, _ = global_search(prob, deep, 40, width=3.0)   # nothing beats the global minimum
    assert best is deep or np.array_equal(best, deep)
    same, n0 = global_search(prob, start, 0)
    assert n0 == 0 and np.array_equal(same, start)
    with pytest.raises(cloth_diagnose.ClothGapError, match="global_evals"):
        ClothDiagnoseConfig(global_evals=-1).validate()
    with pytest.raises(cloth_diagnose.ClothGapError, match="global_width"):
        ClothDiagnoseConfig(global_evals=10, global_width=float("inf")).validate()
    # a start outside the bounds is refused; a parameter with no room (lower = upper) never moves
    with pytest.raises(cloth_diagnose.ClothGapError, match="outside"):
        global_search(prob, np.array([0.0, -0.1, 0.0]), 10)
    pinned = SimpleNamespace(model=SimpleNamespace(x_scale=lambda: xs, lower=lambda: np.array([-np.inf, 0.3, -np.inf]),
                                                   upper=lambda: np.array([np.inf, 0.3, np.inf])),
                             residual=residual)
    th, _ = global_search(pinned, np.array([0.0, 0.3, 0.0]), 40, width=3.0)
    assert th[1] == 0.3


def test_time_jitter_columns_placebo_and_refit_on_model_made_footage():
    """Per-frame time errors (std 3 ms, 12 frames) on silhouettes the model made itself: the
    jitter's batched Jacobian columns equal columns differenced one frame at a time (a frame's
    image depends on its own time only), the score test credits jitter well beyond its placebo (the
    same per-frame freedom across the image motion), and the trust-region refit recovers every
    frame's error (measured: to 1e-12 s; the gap falls from 72 px per frame to ~0)."""
    from vidsim.cloth import mid_range_params
    from vidsim.gap.cloth_diagnose import Problem, placebo_jacobian, refit
    from vidsim.gap.cloth_model import CLOTH_EFFECTS, ClothGapModel, ClothSetup
    from vidsim.gap.rigid_diagnose import score_screen
    from vidsim.reality.cloth import corner_paths, swatch_motion
    from vidsim.video.camera import PinholeCamera, intrinsics, look_at

    R, t = look_at(np.array([0.0, -1.6, 0.9]), np.array([0.0, 0.0, 0.85]), np.array([0.0, 0.0, 1.0]))
    cam = PinholeCamera(intrinsics(560.0, None, 159.5, 119.5), R, t, 320, 240, np.zeros(5))
    times = np.arange(12) / 30.0
    setup = ClothSetup(times, corner_paths(swatch_motion("exp1"), times), np.arange(12), cam, 0.3, 0.2,
                       resolution=6, settle_s=0.3)
    m = ClothGapModel(setup, mid_range_params(density=0.2), ["bend", "stretch"], ("time_jitter",), scale=0.5)
    sl = m.slices["time_jitter"]
    assert sl.stop - sl.start == 12 and m.effect_size("time_jitter") == 12
    th0 = m.theta0()
    truth = th0.copy()
    truth[sl] = np.random.default_rng(1).normal(0.0, 0.003, 12)
    obs, ok = m.render(truth)
    assert ok
    prob = Problem(m, obs, np.ones_like(obs, bool), np.arange(12), {}, 1e-3)
    r0 = prob.residual(th0)
    J = prob.jacobian(th0, r0)
    hs = prob.step_vector(th0)
    for k in (0, 5, 11):
        j = sl.start + k
        tp = th0.copy()
        tp[j] += hs[j]
        np.testing.assert_array_equal(J[:, j], (prob.residual(tp) - r0) / hs[j])
    Jx = J * m.x_scale()
    placebo = placebo_jacobian(prob, th0) * CLOTH_EFFECTS["time_jitter"].scale
    assert placebo.shape == (r0.size, 12) and np.any(placebo)
    scr = score_screen(Jx[:, : m.n_base], {"time_jitter": Jx[:, sl], "placebo": placebo}, r0)
    assert scr["time_jitter"]["fraction"] > 0.5 > 0.1 > scr["placebo"]["fraction"]  # measured 0.81, 0.003
    th, _ = refit(prob, th0, 8)
    np.testing.assert_allclose(th[sl], truth[sl], atol=1e-5)
    assert prob.gap_per_frame(th).mean() < 0.05 * prob.gap_per_frame(th0).mean()
    # held out: one number per frame fitted on the frame itself, as its time error or as the
    # placebo's shift across the motion; only the time error explains these frames
    from vidsim.gap.cloth_diagnose import heldout_placebo_fit, heldout_time_fit

    # (held-out errors within the search's bound, 4 sd of the training frames' errors: 5.2 ms)
    test, train = np.array([4, 6, 9]), np.array([0, 1, 2, 3, 5, 7, 8, 10, 11])
    th_tr = truth.copy()
    th_tr[sl.start + test] = 0.0

    def explained(pr: Problem) -> tuple[bool, bool]:
        """Whether the time fit and the placebo fit each leave < 10 % of the held-out gap (> 5 px)."""
        before = pr.gap_per_frame(th_tr, test)
        assert np.all(before > 5.0), before
        fits = heldout_time_fit(pr, th_tr, test, train), heldout_placebo_fit(pr, th_tr, test, train)
        assert all(np.all((f < 0.1 * before) | (f > 0.5 * before)) for f in fits), (fits, before)  # clear-cut
        return tuple(bool(np.all(f < 0.1 * before)) for f in fits)

    assert explained(prob) == (True, False)
    # the other way round: the held-out frames moved across their motion by as much
    from vidsim.gap.cloth_diagnose import _across_motion
    from vidsim.gap.cloth_model import soft_coverage

    P, V, _ = m.simulate(th_tr)
    cam, tc = m._camera(th_tr), m.capture_times(th_tr)
    obs2 = obs.copy()
    for k in test:
        uv0, perp = _across_motion(cam, m.setup.times, P, V, tc[k])
        obs2[k] = soft_coverage(uv0 + truth[sl.start + k] * perp, m.tris, cam.height, cam.width, m.ramp,
                                float(th_tr[m.n_est]), m.boundary)
    assert explained(Problem(m, obs2, np.ones_like(obs2, bool), np.arange(12), {}, 1e-3)) == (False, True)


def test_twin_case_with_time_jitter_films_at_jittered_times_and_rejects_bad_values():
    """The suite's twin reality draws one capture-time error per frame (scoring reads them back as
    the errors around the offset and rate); a jitter that would reorder frames, or a negative
    one, stops with an error naming the key."""
    from vidsim.gap.cloth_model import ClothGapError
    from vidsim.gap.cloth_suite import _true_time_errors, make_case

    scene = ClothSceneConfig(n_frames=10, frame_stride=1, n_background=3)
    cc = make_case({"label": "time_jitter", "seed": 5, "effects": {"time_jitter": 0.004, "time_offset": 0.01}},
                   scene)
    err = _true_time_errors(cc.truth, scene)
    assert err.shape == (10,) and 0.001 < np.std(err) < 0.008 and abs(np.mean(err)) < 0.004
    np.testing.assert_allclose(np.asarray(cc.truth["capture_times"]) - err, np.arange(10) / scene.fps + 0.01)
    np.testing.assert_array_equal(cc.trial.times, np.arange(10) / scene.fps)  # the footage says nominal times
    for bad in (0.05, -0.001):
        with pytest.raises(ClothGapError, match="time_jitter"):
            make_case({"label": "time_jitter", "seed": 5, "effects": {"time_jitter": bad}}, scene)


def test_grip_discs_cover_the_projected_corners_and_nothing_beyond_the_radius():
    from vidsim.gap.cloth_diagnose import grip_discs
    from vidsim.video.camera import PinholeCamera, intrinsics, look_at

    R, t = look_at(np.array([0.0, -1.6, 0.9]), np.array([0.0, 0.0, 0.85]), np.array([0.0, 0.0, 1.0]))
    cam = PinholeCamera(intrinsics(280.0, None, 79.5, 59.5), R, t, 160, 120, np.zeros(5))
    cp = np.array([[[-0.15, 0.0, 1.0], [0.15, 0.0, 1.0]], [[-0.1, 0.05, 1.02], [0.12, 0.0, 0.98]]])
    m = grip_discs(cam, cp, 120, 160, 6.0)
    uv = cam.project(cp.reshape(-1, 3)).reshape(2, 2, 2)
    yy, xx = np.mgrid[0:120, 0:160] + 0.5
    for f in range(2):
        d = np.min([np.hypot(xx - u, yy - v) for u, v in uv[f]], axis=0)
        np.testing.assert_array_equal(m[f], d <= 6.0)
        assert m[f].sum() == pytest.approx(2 * np.pi * 36, rel=0.1)  # two disjoint discs of radius 6


def _fake_diagnosis(named, region_gap, region, refits, gap_present=True):
    T = 6
    test = np.array([2, 4])
    return cloth_diagnose.ClothDiagnosis(
        list(named), "x", np.arange(T), np.array([0, 1, 3, 5]), test, np.full(T, region_gap), np.full(T, 10.0),
        {k.split("+")[-1]: {"rank": i + 1, "fraction": 0.1} for i, k in enumerate(refits)}, refits,
        {"where": region}, np.zeros((4, 4)), np.zeros(3), 1.0, 5,
        {"gap_present": gap_present, "heldout_excess_px": region_gap - 10.0})


def test_split_diagnosis_lists_the_grips_names_first_and_keeps_each_refit_under_its_region(tmp_path):
    grips = _fake_diagnosis(["time_offset"], 50.0, "grips", {"time_offset": {"params": {}}, "lens_k1": {"params": {}}})
    outline = _fake_diagnosis(["wind"], 300.0, "outline", {"wind": {"params": {}}, "damping": {"params": {}}})
    grips.where["model_chaos"], outline.where["model_chaos"] = {"heldout_px": 2.0}, {"heldout_px": 40.0}
    d = cloth_diagnose.combine_passes({"grips": grips, "outline": outline})
    assert d.named == ["time_offset", "wind"]
    assert d.verdict == "explained by time_offset (grips), wind (outline)"
    assert d.named_refit_keys() == ["grips:time_offset", "outline:wind"]
    assert d.refit_key("wind") == "outline:wind" and d.refit_key("lens_k1") == "grips:lens_k1"
    assert d.refit_key("air_drag") is None
    # gap and floor are those of the pass that named first; "where" is the outline's
    assert d.gap_per_frame[0] == 50.0 and d.extra["primary_region"] == "grips"
    # ... except the model's own chaos, reported beside the headline gap: the primary pass's pixels
    assert d.where == {"where": "outline", "model_chaos": {"heldout_px": 2.0}} and set(d.extra["passes"]) == {"grips", "outline"}
    assert [d.extra["passes"][r]["model_chaos"]["heldout_px"] for r in ("grips", "outline")] == [2.0, 40.0]
    # the screen is the primary pass's; each pass keeps its own (both screen the grip candidates)
    assert d.screen is grips.screen
    assert d.extra["passes"]["outline"]["screen"] is outline.screen
    json.dumps(d.to_dict())
    # the report's figure draws the refit curves of the primary pass only (the other counts other pixels)
    from vidsim.cli.gap_common import plot_diagnosis

    for k, r in d.refits.items():
        r.update(region=k.split(":")[0], gap_per_frame_after_px=[1.0] * 6)
    plot_diagnosis(d, tmp_path / "split.png", floor_label="floor")
    assert (tmp_path / "split.png").stat().st_size > 0
    # neither names: the outline pass is primary; the verdict says whether a gap remains anywhere
    quiet = cloth_diagnose.combine_passes({"grips": _fake_diagnosis([], 11.0, "grips", {}, False),
                                           "outline": _fake_diagnosis([], 300.0, "outline", {}, True)})
    assert quiet.named == [] and quiet.extra["primary_region"] == "outline"
    assert quiet.verdict == "none of the candidates explains the gap"
    # named by both passes: listed once, under the grips pass's refit
    both = cloth_diagnose.combine_passes({
        "grips": _fake_diagnosis(["grip_slip"], 60.0, "grips", {"grip_slip": {"params": {}}}),
        "outline": _fake_diagnosis(["grip_slip", "wind"], 300.0, "outline",
                                   {"grip_slip": {"params": {}}, "grip_slip+wind": {"params": {}}})})
    assert both.named == ["grip_slip", "wind"]
    assert both.named_refit_keys() == ["grips:grip_slip", "outline:grip_slip+wind"]
    assert both.verdict == "explained by grip_slip (grips), wind (outline)"
    none = cloth_diagnose.combine_passes({"grips": _fake_diagnosis([], 11.0, "grips", {}, False),
                                          "outline": _fake_diagnosis([], 12.0, "outline", {}, False)})
    assert none.verdict == "no gap beyond the noise floor"


def test_a_killed_split_diagnosis_resumes_after_its_last_finished_pass(null_case, tmp_path, monkeypatch):
    """Each finished pass is kept in the checkpoint folder: a rerun after a kill in the outline pass
    does not redo the grips pass, and a pass kept for other inputs is not reused."""
    _, _, cc, _ = null_case
    calls: list[str] = []

    def fake_region(trial, params0, estimated, *, cfg, progress=None, camera_candidates=None, **kw):
        calls.append(cfg.region)
        if cfg.region == "outline" and calls.count("outline") == 1:
            raise KeyboardInterrupt  # the kill
        return _fake_diagnosis(["time_offset"] if cfg.region == "grips" else [], 50.0, cfg.region,
                               {"time_offset": {"params": {}}})

    monkeypatch.setattr(cloth_diagnose, "_diagnose_region", fake_region)
    from vidsim.cloth import ClothParams

    params = ClothParams()
    ck = tmp_path / "passes"
    with pytest.raises(KeyboardInterrupt):
        diagnose_cloth(cc.trial, params, ["bend"], checkpoint=ck)
    assert calls == ["grips", "outline"] and (ck / "pass_grips.pkl").is_file()
    d = diagnose_cloth(cc.trial, params, ["bend"], checkpoint=ck)
    assert calls == ["grips", "outline", "outline"]  # the grips pass came from the checkpoint
    assert d.named == ["time_offset"] and d.refits["grips:time_offset"]["region"] == "grips"
    # other inputs (another base) do not reuse the kept passes
    diagnose_cloth(cc.trial, params, ["bend", "stretch"], checkpoint=ck)
    assert calls[3:] == ["grips", "outline"]


def test_a_refit_stuck_at_its_start_point_is_recognised():
    """The guard of ``min_refit_move``: a refit that ends where its start search put it (off zero)
    is stuck; one that moved, or that started from zero (no effect), is not; tol 0 turns it off."""
    from vidsim.gap.cloth_diagnose import stuck_at_start

    sc = np.array([0.3, 0.3, 0.3])
    linen = ([0.0, 0.0, -0.3], [3.6e-6, 1.3e-6, -0.2999974])  # the quick linen diagnosis's wind (m/s)
    assert stuck_at_start(*linen, sc, 0.01)
    assert not stuck_at_start(*linen, sc, 0.0)
    assert not stuck_at_start([0.0, 0.0, -0.3], [0.0, 0.0, -0.25], sc, 0.01)  # moved 0.17 scales
    assert not stuck_at_start([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], sc, 0.01)  # started from "off"
    with pytest.raises(cloth_diagnose.ClothGapError, match="min_refit_move"):
        ClothDiagnoseConfig(min_refit_move=-1.0).validate()


def test_region_settings_are_checked():
    with pytest.raises(cloth_diagnose.ClothGapError, match="region"):
        ClothDiagnoseConfig(region="edges").validate()
    with pytest.raises(cloth_diagnose.ClothGapError, match="residual=band"):
        ClothDiagnoseConfig(region="split", residual="moments").validate()
    with pytest.raises(cloth_diagnose.ClothGapError, match="grip_radius_px"):
        ClothDiagnoseConfig(grip_radius_px=0.5).validate()
    with pytest.raises(cloth_diagnose.ClothGapError, match="polish_nfev"):
        ClothDiagnoseConfig(polish_nfev=-1).validate()
    with pytest.raises(cloth_diagnose.ClothGapError, match="gap.cloth.diagnose.multirate"):
        ClothDiagnoseConfig(multirate="0").validate()
    with pytest.raises(cloth_diagnose.ClothGapError, match="gap.cloth.diagnose.damping"):
        ClothDiagnoseConfig(damping="implicit").validate()
    ClothDiagnoseConfig(multirate="auto", damping="auto").validate()
    with pytest.raises(cloth_diagnose.ClothGapError, match="base_nfev"):
        ClothDiagnoseConfig(base_nfev=0).validate()
    for k in ("ramp", "fd_target_px"):
        with pytest.raises(cloth_diagnose.ClothGapError, match=k):
            ClothDiagnoseConfig(**{k: 0.0}).validate()
    with pytest.raises(cloth_diagnose.ClothGapError, match="min_closure"):
        ClothDiagnoseConfig(min_closure=float("nan")).validate()


@pytest.mark.slow
def test_withheld_time_offset_is_named_near_the_grips_and_its_strength_recovered():
    """A 12 ms frame-time offset, not named on the whole outline (docs/gap.md), is named on the
    pixels near the gripped corners (measured with the whole grips pass: closure 0.65, dt 11.5 ms)."""
    from vidsim.gap.cloth_diagnose import GRIP_EFFECTS

    case = {"label": "time_offset", "seed": 304, "effects": {"time_offset": 0.012}}
    cfg = ClothDiagnoseConfig(region="grips", candidates=list(GRIP_EFFECTS), top_k=1, pairs=False, metric_terms=False)
    diag, score, _ = run_case(case, SCENE, cfg)
    assert diag.named[:1] == ["time_offset"], diag.verdict
    assert score["correct"] and score["closure"]["time_offset"] >= 0.5
    assert score["recovery"]["time_offset"]["rel_error"] <= 0.3
    assert all(r["region"] == "grips" for r in diag.refits.values())
    # the named effect's refit was continued from where the judging refit stopped (polish_nfev)
    named = diag.refits[diag.named_refit_keys()[0]]
    assert named["nfev"] > named["before_polish"]["nfev"]
    assert score["closure"]["time_offset"] == named["closure_of_remaining"]


def test_refit_free_mask_holds_the_dynamics_only_for_imaging_and_timing_effects():
    from vidsim.cloth import mid_range_params
    from vidsim.gap.cloth_diagnose import refit_free_mask
    from vidsim.gap.cloth_model import ClothGapModel, ClothSetup
    from vidsim.reality.cloth import corner_paths, swatch_motion
    from vidsim.video.camera import PinholeCamera, intrinsics, look_at

    R, t = look_at(np.array([0.0, -1.6, 0.9]), np.array([0.0, 0.0, 0.85]), np.array([0.0, 0.0, 1.0]))
    cam = PinholeCamera(intrinsics(560.0, None, 159.5, 119.5), R, t, 320, 240, np.zeros(5))
    times = np.arange(10) / 30.0
    setup = ClothSetup(times, corner_paths(swatch_motion("exp1"), times), np.arange(0, 10, 2), cam, 0.3, 0.2,
                       resolution=6, settle_s=0.3)
    p = mid_range_params(density=0.2)
    timed = np.array([False, True, True, True, True])
    lens = ClothGapModel(setup, p, ["bend", "stretch"], ("lens_k1",), scale=0.5)
    assert refit_free_mask(lens, ("lens_k1",), timed, False) is None
    free = refit_free_mask(lens, ("lens_k1",), timed, True)
    assert free.tolist() == [False, False, True, True]  # bend, stretch held; outline offset, k1 move
    wind = ClothGapModel(setup, p, ["bend", "stretch"], ("lens_k1", "wind"), scale=0.5)
    assert refit_free_mask(wind, ("lens_k1", "wind"), timed, True) is None  # a dynamics effect re-simulates
    jit = ClothGapModel(setup, p, ["bend", "stretch"], ("time_jitter",), scale=0.5)
    free = refit_free_mask(jit, ("time_jitter",), timed, True)
    assert free[:2].tolist() == [False, False] and free[2]
    assert free[jit.slices["time_jitter"]].tolist() == timed.tolist()
    assert refit_free_mask(jit, ("time_jitter",), timed, False)[:3].all()


def test_model_chaos_is_zero_without_a_move_and_grows_over_the_clip(null_case):
    """The model's own chaos (``where.model_chaos``): copies of a fit moved by 0 reproduce it to the
    pixel (the same simulation), and copies moved by 1e-4 drift apart as the clip goes on, which
    is what chaos is (the null case's soft swatch: the docstring above). Reported in the null
    case's diagnosis, its held-out mean consistent with its per-frame values."""
    from vidsim.cloth import mid_range_params
    from vidsim.gap.cloth_model import ClothGapModel, ClothSetup

    diag, _, cc, _ = null_case
    mc = diag.where["model_chaos"]
    per = np.asarray(mc["per_frame_px"])
    assert mc["draws"] == 4 and mc["failed"] == 0 and per.shape == (len(diag.frames),)
    assert mc["heldout_px"] == pytest.approx(per[diag.test].mean(), rel=1e-12)
    setup = ClothSetup(cc.trial.times, cc.trial.corner_paths, np.asarray(diag.frames), cc.trial.camera,
                       cc.trial.size, cc.trial.density, SCENE.resolution, SCENE.settle_s_model)
    est = ["bend", "stretch", "shear"]
    model = ClothGapModel(setup, mid_range_params(density=cc.trial.density).replace(bend=3e-6, stretch=300.0, shear=40.0),
                          est, (), 0.5, 1.0)
    th = model.theta0()
    T = len(diag.frames)

    def problem(m, fr, o):
        return cloth_diagnose.Problem(m, o, np.ones(o.shape, bool), fr, {}, 1e-3)

    zero = cloth_diagnose.model_chaos(model, th, problem, est, T, np.arange(T),
                                      ClothDiagnoseConfig(chaos_draws=2, chaos_sigma=0.0))
    assert zero["failed"] == 0 and np.all(np.asarray(zero["per_frame_px"]) == 0.0)
    moved = cloth_diagnose.model_chaos(model, th, problem, est, T, np.arange(T), ClothDiagnoseConfig(chaos_draws=4))
    g = np.asarray(moved["per_frame_px"])
    q = T // 4
    assert g[:q].mean() < 0.5, g  # within the first quarter the copies still coincide (sub-pixel)
    assert g[-q:].mean() > 5.0 * max(g[:q].mean(), 0.1), g  # and by the end they have drifted apart
    assert cloth_diagnose.model_chaos(model, th, problem, est, T, np.arange(T), ClothDiagnoseConfig(chaos_draws=0)) == {}
    with pytest.raises(cloth_diagnose.ClothGapError, match="chaos_draws"):
        ClothDiagnoseConfig(chaos_draws=-1).validate()
    for bad in (0.0, 2.0, float("nan")):  # 0 would report "no chaos" whatever the model does
        with pytest.raises(cloth_diagnose.ClothGapError, match="chaos_sigma"):
            ClothDiagnoseConfig(chaos_sigma=bad).validate()
