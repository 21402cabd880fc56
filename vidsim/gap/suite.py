"""The withheld-effect suite (rigid domain): make a case, fit it, diagnose it blind, score vs truth.

A case is a plain mapping (a config entry, so a user adds one without code)::

    {label: lens_k1, seed: 100, effects: {lens_k1: -0.05}, render: false}
    {label: [linear_drag, com_offset], ...}        # combined: every listed effect should be named
    {label: unexplained, seed: 7, gust: {wind: [4, 0, 0], start_s: 0.7, drag: 1.0}}

``effects`` are the fields of :class:`vidsim.reality.rigid.RigidEffects` (MuJoCo reality, switched
on and withheld from the model); ``label`` is the library effect(s) that should be named, ``none``
for a null case (nothing should be named) or ``unexplained`` for an effect outside the library
(the right answer is "none of the candidates explains the gap"). ``gust`` makes the out-of-library
reality of this module: quadratic drag throughout and a wind that starts blowing mid-flight
(time-varying, which no candidate of the library is). ``render: true`` films with pyrender and
segments (needed for blur and rolling shutter, which the fast rasterised path does not show).

Only :func:`score_case` reads the truth; :func:`run_case` hands the estimator (fit, diagnosis)
nothing but masks, times, camera, the body and the fit's rough initial guess (the documented
guess protocol of docs/rigid.md: the truth moved by 30 degrees, 30 %, 20 %, 10 cm and 10 degrees of gravity, a
stand-in for a user's guess; the diagnosis never sees it).
"""

from __future__ import annotations

import time
from dataclasses import fields
from typing import Any, Mapping

import numpy as np

from vidsim.gap.rigid_diagnose import DiagnoseConfig, RigidDiagnosis, diagnose_rigid
from vidsim.gap.rigid_model import RIGID_EFFECTS, GapError
from vidsim.reality.rigid import AIR_DENSITY, RigidEffects, RigidRealityConfig, make_throw
from vidsim.rigid.body import BoxBody

SPECIAL_LABELS = ("none", "unexplained")


def case_labels(case: dict, library: Mapping[str, Any] = RIGID_EFFECTS, error: type[ValueError] = GapError
                ) -> list[str]:
    """The effect names a case expects to be named (empty for ``none``/``unexplained``).

    ``library``: the domain's candidate effects (rigid by default); ``error``: raised for a label
    that is neither one of them nor special.
    """
    lab = case.get("label", "none")
    labs = [lab] if isinstance(lab, str) else list(lab)
    for x in labs:
        if x not in library and x not in SPECIAL_LABELS:
            raise error(f"case label {x!r} is neither a library effect {sorted(library)} nor one of "
                        f"{SPECIAL_LABELS}")
    allowed = case.get("allowed", [])
    if not isinstance(allowed, (list, tuple)) or not all(isinstance(a, str) and a in library for a in allowed):
        raise error(f"case allowed = {allowed!r}: expected a list of library effects {sorted(library)}")
    return [x for x in labs if x not in SPECIAL_LABELS]


def named_correctly(case: dict, labels: list[str], named: list[str], library: Mapping[str, Any]) -> bool:
    """Whether a case's diagnosis named the right thing (both domains): a single withheld effect
    (or a stated alias of it) named first; every effect of a combined case named, in any order;
    nothing named for ``none`` and ``unexplained``, apart from the case's ``allowed`` effects: ones
    its reality holds throughout besides what it tests (the rigid gust's throw has the drag of
    the ``drag`` case), which the model lacks and which may therefore be named without being wrong."""
    allowed = case.get("allowed", [])  # checked by case_labels
    first = named[0] if named else "none"
    if not labels:
        return all(n in allowed for n in named)
    if len(labels) == 1:
        return first == labels[0] or (labels[0] in library and first in library[labels[0]].alias)
    return all(x in named for x in labels)


def reality_effects(case: dict) -> RigidEffects:
    """The case's :class:`RigidEffects` (unknown keys are an error naming the key)."""
    e = dict(case.get("effects") or {})
    known = {f.name for f in fields(RigidEffects)}
    bad = sorted(set(e) - known)
    if bad:
        raise GapError(f"case effects: unknown key(s) {bad}; expected fields of RigidEffects {sorted(known)}")
    eff = RigidEffects(**{k: (list(v) if isinstance(v, (list, tuple)) else float(v)) for k, v in e.items()})
    try:
        eff.validate()
    except ValueError as err:
        raise GapError(str(err)) from err
    return eff


def gust_throw(seed: int, cfg: RigidRealityConfig, wind: list[float], start_s: float, drag: float):
    """An out-of-library reality: quadratic drag and a wind that switches on at ``start_s``.

    The same throw as :func:`make_throw` with ``render=False`` (same seed, camera and initial
    state); MuJoCo integrates it again with ``opt.wind`` set to ``wind`` (world m/s) from
    ``start_s`` seconds after the first throw frame, and the exact silhouettes are redrawn.
    """
    import mujoco

    from vidsim.reality.rigid import MJ_TIMESTEP, mujoco_xml, sample_truth
    from vidsim.render.raster import silhouette_batch
    from vidsim.rigid.body import t_object
    from vidsim.rigid.dynamics import quat_to_rot
    from vidsim.video.camera import PinholeCamera, intrinsics

    eff = RigidEffects(drag=float(drag))
    th = make_throw(seed, cfg, eff, render=False)
    rng = np.random.default_rng(seed)
    body, _ = t_object()
    s = sample_truth(rng, cfg)
    model = mujoco.MjModel.from_xml_string(mujoco_xml(body, eff))
    data = mujoco.MjData(model)
    data.qpos[:3] = s["x0"]
    data.qpos[3:7] = s["q0"]
    data.qvel[:3] = s["v0"]
    data.qvel[3:6] = quat_to_rot(s["q0"]).T @ s["w0"]
    mujoco.mj_forward(model, data)
    n_bg, n = cfg.n_background, cfg.n_frames
    targets = np.arange(n) / cfg.fps
    pos = np.zeros((n, 3))
    quat = np.zeros((n, 4))
    t = 0.0
    for k, tk in enumerate(targets):
        while tk - t > 1e-12:
            model.opt.wind[:] = wind if t >= start_s else 0.0
            h = min(MJ_TIMESTEP, tk - t)
            model.opt.timestep = h
            mujoco.mj_step(model, data)
            t += h
        model.opt.timestep = MJ_TIMESTEP
        pos[k] = data.qpos[:3]
        quat[k] = data.qpos[3:7]
    Rc, C = s["R_cam"], s["C_cam"]
    K = intrinsics(cfg.focal, None, (cfg.width - 1) / 2, (cfg.height - 1) / 2)
    lens = PinholeCamera(K, Rc, -Rc @ C, cfg.width, cfg.height)
    Vb, F = body.mesh()
    Vs = np.stack([Vb @ quat_to_rot(q).T + p for p, q in zip(pos, quat)])
    th.masks[n_bg:] = silhouette_batch(Vs, F, lens)
    th.truth["gust"] = {"wind": list(map(float, wind)), "start_s": float(start_s), "drag": float(drag)}
    return th


def make_case(case: dict, scene: RigidRealityConfig | None = None):
    """Film a case: returns (masks (N, H, W) bool, throw) -- the masks are what the estimator sees."""
    scene = scene or RigidRealityConfig(n_background=3)
    seed = int(case.get("seed", 0))
    if "gust" in case:
        g = dict(case["gust"])
        th = gust_throw(seed, scene, list(g.get("wind", [4.0, 0.0, 0.0])), float(g.get("start_s", 0.7)),
                        float(g.get("drag", 1.0)))
        return th.masks, th
    eff = reality_effects(case)
    render = bool(case.get("render", False))
    th = make_throw(seed, scene, eff, render=render)
    if not render:
        return th.masks, th
    from vidsim.video.segment import SegmentConfig, segment

    return segment(th.frames, cfg=SegmentConfig()), th


def true_strengths(truth: dict, body: BoxBody, nominal_times: np.ndarray | None = None
                   ) -> dict[str, float | list[float]]:
    """Library-parameter values implied by the reality's effects (for scoring only).

    ``lens_k1`` and ``com_offset`` are the same quantities; ``time_jitter`` is the standard
    deviation of the true minus the nominal capture times (``nominal_times``, seconds: the times
    written to the footage); ``magnus`` is MuJoCo's Magnus force per
    unit mass and spin-velocity product, ``C_M rho sum(V_ellipsoid) / m`` (MuJoCo's fluid model
    uses each box's equivalent ellipsoid volume).
    """
    e = truth.get("effects", {})
    out: dict[str, Any] = {}
    if e.get("lens_k1"):
        out["lens_k1"] = float(e["lens_k1"])
    if np.any(e.get("com_offset", [0, 0, 0])):
        out["com_offset"] = list(map(float, e["com_offset"]))
    if e.get("time_jitter"):
        ct = np.asarray(truth["capture_times"], float)
        nominal = np.asarray(nominal_times, float) if nominal_times is not None else np.arange(len(ct)) / 30.0
        out["time_jitter"] = float(np.std(ct - nominal))
    if e.get("magnus"):
        vol = float(np.sum(4.0 / 3.0 * np.pi * np.prod(body.half_sizes, axis=1)))
        out["magnus"] = float(e["magnus"]) * AIR_DENSITY * vol / body.mass
    if e.get("exposure"):
        # the library's b spreads BLUR_SAMPLES renders over sqrt(b); the reality spreads its own number
        # over the exposure E: the b with the same time variance (8/9 E^2 for 7 against 5 samples;
        # scored as E^2 until 5 Dec 2026, 12.5 % too high)
        from vidsim.gap.rigid_model import BLUR_SAMPLES as LIB
        from vidsim.reality.rigid import BLUR_SAMPLES as REAL

        E = float(e["exposure"])
        out["motion_blur"] = E * E * float(np.var(np.linspace(-0.5, 0.5, REAL)) / np.var(np.linspace(-0.5, 0.5, LIB)))
    if e.get("rolling_shutter"):
        out["rolling_shutter"] = float(e["rolling_shutter"])
    return out


def score_case(case: dict, diag: RigidDiagnosis, truth: dict, body: BoxBody,
               nominal_times: np.ndarray | None = None) -> dict:
    """Named effect correct or not, held-out shrinkage and recovered strength vs truth."""
    labels = case_labels(case)
    lab = case.get("label", "none")
    named = list(diag.named)
    first = named[0] if named else "none"
    correct = named_correctly(case, labels, named, RIGID_EFFECTS)
    out: dict[str, Any] = {"label": lab if isinstance(lab, str) else "+".join(lab), "named": named,
                           "named_first": first, "correct": bool(correct), "verdict": diag.verdict,
                           "gap_present": bool(diag.extra.get("gap_present", False)),
                           "noise_floor_px": float(diag.floor_test.mean()),
                           "heldout_before_px": float(diag.gap_per_frame[diag.test].mean())}
    # the supported candidates the held-out frames cannot tell from the first named (undecided)
    # (None where the naming step did not test it: a joint pair, or nothing named)
    alike = diag.refits.get(first, {}).get("as_good_on_heldout") if named else None
    out["named_first_as_good"] = list(alike) if alike is not None else None
    truths = true_strengths(truth, body, nominal_times)
    rec = {}
    for lbl in labels:
        # the refit that added this effect: the named model up to it, else its single refit
        key = "+".join(named[: named.index(lbl) + 1]) if lbl in named else lbl
        r = diag.refits.get(key)
        if r is None:
            # never refitted (not among the screen's best): its closure is not measured, and the
            # headline counts it as not closing (it had silently left the denominator)
            out.setdefault("closure", {})[lbl] = None
            continue
        if "closure_of_remaining" in r:
            clos = r["closure_of_remaining"]  # None: no excess above the floor left to close
        else:
            clos = r["heldout_closure"] if lbl != "time_jitter" else r["train_closure"]
        out.setdefault("closure", {})[lbl] = None if clos is None else float(clos)
        if lbl == "time_jitter":
            out.setdefault("closure_kind", {})[lbl] = "training"  # its held-out values are fitted per frame
        out.setdefault("heldout_after_px", {})[lbl] = float(r["heldout_after_px"])
        if lbl in truths:
            # effects named jointly were refitted together: their strengths come from that refit
            joint = diag.refits.get("+".join(named)) if named else None
            if joint is not None and joint.get("named_jointly") and lbl in joint.get("params", {}):
                r = joint
            p = r["params"][lbl]
            est = p["std_s"] if lbl == "time_jitter" else p["value"]
            tv = truths[lbl]
            if lbl == "time_jitter" and "capture_times" in truth:
                # the same statistic as the estimate: the spread over the training frames (the
                # truth's over every frame, background frames included, had been compared)
                ct = np.asarray(truth["capture_times"], float)
                nominal = np.asarray(nominal_times, float) if nominal_times is not None else np.arange(len(ct)) / 30.0
                idx = np.asarray(diag.frames, int)[np.asarray(diag.train, int)]
                tv = float(np.std((ct - nominal)[idx]))
            if isinstance(tv, list):
                rel = float(np.linalg.norm(np.subtract(est, tv)) / max(np.linalg.norm(tv), 1e-12))
            else:
                est = float(np.ravel(est)[0])
                rel = float(abs(est - tv) / max(abs(tv), 1e-12))
            rec[lbl] = {"estimate": est, "truth": tv, "rel_error": rel}
    out["recovery"] = rec
    return out


class CaseFailed(GapError):
    """A case whose run failed at run time (its fit diverged, or left nothing to diagnose): a failed
    score for that case, not the end of the suite (a configuration error is still one)."""


def failed_score(case: dict, reason: str) -> dict:
    """The score of a case that failed at run time: wrong by definition (a null case that failed has
    not "named nothing"), its reason kept, its gaps unknown (None)."""
    lab = case.get("label", "none")
    return {"label": lab if isinstance(lab, str) else "+".join(lab), "named": [], "named_first": "(failed)",
            "correct": False, "verdict": f"failed: {reason}", "failed": reason, "gap_present": False,
            "heldout_before_px": None, "noise_floor_px": None}


def run_case(case: dict, dcfg: DiagnoseConfig | None = None, scene: RigidRealityConfig | None = None,
             progress=None, checkpoint=None) -> tuple[RigidDiagnosis, dict, np.ndarray, Any]:
    """Film, fit (single start from the project's perturbed-guess protocol), diagnose, score.
    ``checkpoint``: the diagnosis's folder of finished steps (see :func:`diagnose_rigid`; None: none).

    Returns:
        (diagnosis, score, masks, throw).
    """
    from vidsim.rigid.evaluate import perturbed_guess
    from vidsim.rigid.fit import fit_throw

    t = time.perf_counter()
    masks, th = make_case(case, scene)
    body = BoxBody.from_meta(th.meta["object"])
    # the initial guess protocol of the rigid issue (truth moved by fixed amounts): the stand-in
    # for the user's rough guess; the fit and the diagnosis never see the truth itself
    guess = perturbed_guess(th.truth, np.random.default_rng(int(case.get("seed", 0)) + 1000003))
    res = fit_throw(masks, th.times, th.camera, body, guess, {"multistart": "none"})
    t_fit = time.perf_counter() - t
    if not np.all(np.isfinite(res.states)):
        raise CaseFailed(f"the single-start fit diverged (best objective {res.history[-1] if res.history else float('nan'):.3g})")
    try:
        diag = diagnose_rigid(masks, th.times, th.camera, body, res.summary(), dcfg, progress, checkpoint=checkpoint)
    except GapError as e:
        if str(e).startswith("fit:"):  # the fitted throw cannot be diagnosed (diverges, behind the camera)
            raise CaseFailed(str(e)) from e
        raise
    sc = score_case(case, diag, th.truth, body, th.times)
    sc["fit_seconds"] = t_fit
    sc["diagnose_seconds"] = diag.seconds
    sc["fit_mean_iou"] = float(res.mean_iou)
    return diag, sc, masks, th


def confusion(scores: dict[str, dict], library: Mapping[str, Any] = RIGID_EFFECTS
              ) -> tuple[list[str], list[str], np.ndarray]:
    """Confusion matrix of single-label cases: rows true label, columns first named effect
    (``library``: the domain's candidate effects, rigid by default)."""
    rows = sorted({s["label"] for s in scores.values()})
    cols = sorted({s["named_first"] for s in scores.values()} | {r for r in rows if r in library} | {"none"})
    M = np.zeros((len(rows), len(cols)), int)
    for s in scores.values():
        M[rows.index(s["label"]), cols.index(s["named_first"])] += 1
    return rows, cols, M
