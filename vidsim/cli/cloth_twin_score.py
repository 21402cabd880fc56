"""Stage ``score_cloth_twin``: the twin reality's estimate against its known truth (issue 5).

``python -m vidsim.cli.cloth_twin_score paths.out=results/cloth/twin/twin
cloth.twin.params=results/cloth/select/twin/params.yaml cloth.twin.profile=results/cloth/profile/twin/profile.yaml
cloth.twin.footage=results/footage/cloth_twin_robot``

``cloth.twin.params`` may be any file with a ``params`` mapping (a selection's ``params.yaml``, a
fit's ``fit.yaml``: the joint fit is scored this way); ``cloth.twin.profile`` is optional (empty:
no determination column).

The twin films the estimator's own simulator (finer mesh, known parameters), so the true answer
exists. A scoring stage: it reads the truth file beside the held-out footage (estimators never do).
It reports, for all nine parameters, the estimate, the truth, the relative error and whether the
footage determines the parameter (``profile_cloth``); and on the held-out motion the error of the
selected parameters against the error of the true parameters (both simulated by the estimator's
model). On a chaotic motion that ratio moves by tens of per cent when the true parameters move by a
few per cent (docs/cloth_study.md), so the stage also scores ``cloth.twin.perturb_draws`` sets of
the true parameters scaled by exp(N(0, ``perturb_sigma``)) and reports their ratios' quantiles
(``heldout.truth_scale``) and whether the estimate's ratio is within their 90 % point, beside the
issue's fixed 1.10. Because a change of 1e-4 already moves a single run's error by up to 13 % on the
soft twin's motion (docs/cloth_study.md, "Session 36"), the ratio of mean errors over
``cloth.twin.chaos_draws`` such copies of the estimate and of the truth (common draws of
exp(N(0, ``chaos_sigma``))) is reported beside the single-run ratio (``heldout.chaos_mean``). Writes ``score.yaml``, ``errors.csv`` and ``errors.png``.

Checkpoint: every simulation (estimate, truth, each perturbed draw) is logged as it finishes to
``.score_cloth_twin.checkpoint/evals.jsonl`` in the output folder (:class:`vidsim.cli.cloth_common.LoggedScores`:
keyed by the parameter set's exact values, fingerprinted by the footage and settings); a killed
stage, run again, replays them and writes what an uninterrupted run writes. The folder (with any
log of other inputs moved aside there) is removed once ``score.yaml`` is written.
"""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import (
    ClothStageError,
    LoggedScores,
    load_trial,
    make_objective,
    params_from_dict,
    read_selected,
)
from vidsim.cloth import ESTIMATED_NAMES
from vidsim.io.atomic import write_text, write_yaml
from vidsim.io.footage import load_yaml, read_truth
from vidsim.report.figures import save_figure


def run(cfg: DictConfig) -> None:
    out = Path(cfg.paths.out)
    tc = cfg.cloth.twin
    for key in ("params", "footage"):
        if not tc[key]:
            raise ClothStageError(f"cloth.twin.{key} is empty")
    for sig, n in (("perturb_sigma", "perturb_draws"), ("chaos_sigma", "chaos_draws")):
        if not (tc[sig] >= 0 and np.isfinite(tc[sig])) or tc[n] < 0:
            raise ClothStageError(f"cloth.twin.{sig} = {tc[sig]} (>= 0 expected) / cloth.twin.{n} "
                                  f"= {tc[n]} (>= 0 expected, 0: off)")
    truth = read_truth(tc.footage)
    if truth.get("kind") != "twin" or "params" not in truth:
        raise ClothStageError(f"{tc.footage}: its truth is not a twin reality's (kind = {truth.get('kind')!r})")
    sel = read_selected([str(tc.params)])[0]
    # the profile of these parameters (profile_cloth), if any: which of them the footage determines
    prof = load_yaml(tc.profile, ClothStageError, "profile.yaml", mapping=True).get("profiles", {}) if tc.profile else {}
    est = params_from_dict(sel["params"], str(tc.params))
    true = params_from_dict(truth["params"], f"truth of {tc.footage}")
    ckpt = out / ".score_cloth_twin.checkpoint"  # every simulation of this stage; removed once score.yaml is written
    if (ckpt / "evals.jsonl").is_file():
        print(f"score_cloth_twin: resuming from {ckpt} (simulations already run are replayed)", flush=True)
    obj = LoggedScores(make_objective([load_trial(tc.footage, cfg)], cfg), ckpt / "evals.jsonl")
    try:
        _score(cfg, out, obj, est, true, truth, prof)
    finally:
        obj.close()
    shutil.rmtree(ckpt, ignore_errors=True)


def _score(cfg: DictConfig, out: Path, obj: LoggedScores, est, true, truth: dict, prof: dict) -> None:
    """The stage's scoring and outputs (``obj``: the logged objective of the held-out footage)."""
    tc = cfg.cloth.twin
    e_est = float(obj.evaluate_params(est).score)
    res_true = obj.evaluate_params(true)
    e_true = float(res_true.score)
    rows = {}
    for n in ESTIMATED_NAMES:
        v, t = float(getattr(est, n)), float(getattr(true, n))
        rel = abs(v - t) / abs(t) if t != 0 else float("nan")
        p = prof.get(n)
        rows[n] = {"estimate": v, "truth": t, "relative_error": rel,
                   "estimated": n in obj.space.names,
                   "determined": None if p is None else bool(p["determined"]),
                   "interval": None if p is None else p["interval"],
                   "truth_in_interval": None if p is None else bool(p["interval"][0] <= t <= p["interval"][1])}
    if not res_true.ok:  # no reference: the ratio would compare with a failure score (1e30) and pass trivially
        ratio = float("nan")
        print(f"cloth_twin_score: the true parameters failed to simulate on {tc.footage} ({res_true.failure}): "
              "no held-out ratio", flush=True)
    else:
        ratio = e_est / e_true if e_true > 0 else float("inf")
    checks = {"heldout_ratio": {"value": ratio, "target": float(tc.heldout_ratio),
                                "met": bool(res_true.ok and ratio <= tc.heldout_ratio)}}
    scale = truth_scale(obj, true, e_true, obj.space.names, float(tc.perturb_sigma), int(tc.perturb_draws),
                        int(tc.perturb_seed), float(tc.heldout_ratio), true_ok=bool(res_true.ok))
    if scale is not None:
        # beside the check, not instead of it: is the estimate's held-out error inside the
        # spread that a few per cent of parameter change already gives on this chaotic motion?
        checks["heldout_ratio_within_truth_scale"] = {"value": ratio, "target": scale["ratio_q90"],
                                                      "met": bool(ratio <= scale["ratio_q90"])}
    chaos = chaos_mean(obj, est, true, obj.space.names, float(tc.chaos_sigma), int(tc.chaos_draws),
                       int(tc.perturb_seed)) if res_true.ok else None
    if chaos is not None:
        # beside the single-run check: each side's error averaged over its own chaos
        checks["heldout_ratio_chaos_mean"] = {"value": chaos["ratio"], "target": float(tc.heldout_ratio),
                                              "met": bool(chaos["ratio"] <= tc.heldout_ratio)}
    for n in tc.rel_tol_params:
        checks[f"{n}_relative_error"] = {"value": rows[n]["relative_error"], "target": float(tc.rel_tol),
                                         "met": bool(rows[n]["relative_error"] <= tc.rel_tol)}
    doc = {"heldout": {"footage": str(tc.footage), "error_selected": e_est, "error_true_params": e_true, "ratio": ratio,
                       "truth_scale": scale, "chaos_mean": chaos},
           "parameters": rows, "checks": checks, "not_determined": [n for n, r in rows.items() if r["determined"] is False]}
    write_text(out / "errors.csv", "parameter,estimate,truth,relative_error,estimated,determined,interval_lo,"
               "interval_hi\n" + "".join(_csv_row(n, r) for n, r in rows.items()))
    method = "joint fit" if Path(str(tc.params)).name == "fit.yaml" else "cross-trial selection"
    _figure(rows, ratio, out / "errors.png", None if scale is None else scale["ratio_q90"], float(cfg.cloth.twin.rel_tol),
            label=f"{Path(str(tc.footage)).name} ({method})")
    write_yaml(out / "score.yaml", doc)
    if scale is not None:
        print(f"score_cloth_twin: the true parameters moved by exp(N(0, {scale['sigma']:g})) give held-out ratios "
              f"{scale['ratio_q10']:.3f} / {scale['ratio_q50']:.3f} / {scale['ratio_q90']:.3f} (10/50/90 %), "
              f"{scale['fraction_within_heldout_ratio']:.0%} within {tc.heldout_ratio:g}", flush=True)
    if chaos is not None and e_true > 0:
        print(f"score_cloth_twin: averaged over {chaos['draws']} copies each moved by exp(N(0, {chaos['sigma']:g})): "
              f"held-out errors {chaos['error_selected_mean']:.4g} / {chaos['error_true_mean']:.4g}, ratio "
              f"{chaos['ratio']:.3f} (single runs of the truth: {min(chaos['errors_true']) / e_true:.3f}-"
              f"{max(chaos['errors_true']) / e_true:.3f} of its unmoved error)", flush=True)
    print(f"score_cloth_twin: held-out error ratio {ratio:.3f}; relative errors " +
          ", ".join(f"{n} {r['relative_error']:.0%}" for n, r in rows.items()), flush=True)


def truth_scale(obj, true, e_true: float, names: list[str], sigma: float, draws: int, seed: int,
                limit: float, true_ok: bool = True) -> dict | None:
    """Held-out ratios of the true parameters with each of ``names`` scaled by exp(N(0, sigma)):
    their 10/50/90 % quantiles and the fraction within ``limit``, over the draws that simulated.

    None (no scale to compare with) for 0 draws, when the true parameters themselves failed to
    simulate (``true_ok``), or when more than 10 % of the draws failed: a failed simulation scores
    the objective's failure score, and quantiles over those would be meaningless."""
    if draws <= 0 or not true_ok or not e_true > 0:
        return None
    rng = np.random.default_rng(seed)
    r, n_failed = [], 0
    for _ in range(draws):
        res = obj.evaluate_params(dataclasses.replace(true, **{n: getattr(true, n) * float(np.exp(rng.normal(0, sigma)))
                                                               for n in names}))
        if res.ok and np.isfinite(res.score):
            r.append(res.score / e_true)
        else:
            n_failed += 1
    if n_failed > 0.1 * draws:
        print(f"score_cloth_twin: {n_failed} of {draws} perturbed true parameter sets failed to simulate; "
              "no truth scale reported", flush=True)
        return None
    r = np.array(r)
    q = np.quantile(r, [0.1, 0.5, 0.9])
    return {"sigma": sigma, "draws": draws, "failed": n_failed, "seed": seed, "parameters": list(names),
            "ratio_q10": float(q[0]), "ratio_q50": float(q[1]), "ratio_q90": float(q[2]),
            "fraction_within_heldout_ratio": float(np.mean(r <= limit)), "ratios": [float(x) for x in r]}


def chaos_mean(obj, est, true, names: list[str], sigma: float, draws: int, seed: int) -> dict | None:
    """Held-out errors of ``draws`` copies of the estimate and of the truth, each with every one of
    ``names`` scaled by exp(N(0, sigma)), the same draws for both sides (common random numbers),
    and the ratio of the two means: a single run's error on a chaotic motion is one draw of what
    parameters within ``sigma`` of each other score. None for 0 draws or when any copy fails to
    simulate (a failure scores the objective's failure value, which a mean cannot carry)."""
    if draws <= 0:
        return None
    rng = np.random.default_rng(seed + 1)  # not the truth scale's draws
    scales = [{n: float(np.exp(rng.normal(0, sigma))) for n in names} for _ in range(draws)]
    errs = {}
    for side, p in (("selected", est), ("true", true)):
        e = []
        for sc in scales:
            res = obj.evaluate_params(dataclasses.replace(p, **{n: getattr(p, n) * sc[n] for n in names}))
            if not (res.ok and np.isfinite(res.score)):
                print(f"score_cloth_twin: a {sigma:g}-moved copy of the {side} parameters failed to simulate; "
                      "no chaos-averaged ratio", flush=True)
                return None
            e.append(float(res.score))
        errs[side] = e
    m_est, m_true = float(np.mean(errs["selected"])), float(np.mean(errs["true"]))
    return {"sigma": sigma, "draws": draws, "error_selected_mean": m_est, "error_true_mean": m_true,
            "ratio": m_est / m_true if m_true > 0 else float("inf"),
            "errors_selected": errs["selected"], "errors_true": errs["true"]}


def _csv_row(name: str, r: dict) -> str:
    det = "" if r["determined"] is None else str(int(r["determined"]))
    lo, hi = ("", "") if r["interval"] is None else (f"{r['interval'][0]:.5g}", f"{r['interval'][1]:.5g}")
    return (f"{name},{r['estimate']:.5g},{r['truth']:.5g},{r['relative_error']:.4g},{int(r['estimated'])},{det},"
            f"{lo},{hi}\n")


def _figure(rows: dict, ratio: float, path: Path, q90: float | None = None, rel_tol: float = 0.25,
            label: str = "twin") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(rows)
    rel = np.array([rows[n]["relative_error"] for n in names])
    col = ["C1" if not rows[n]["estimated"] else ("0.6" if rows[n]["determined"] is False else "C0") for n in names]
    fig, ax = plt.subplots(figsize=(7, 3))
    ax.bar(range(len(names)), rel, color=col)
    ax.axhline(rel_tol, color="C3", lw=0.8, ls="--")  # the criterion (cloth.twin.rel_tol)
    ax.set_yscale("symlog", linthresh=0.01)
    for i, n in enumerate(names):  # the profile's interval: does it hold the truth?
        tin = rows[n].get("truth_in_interval")
        if tin is not None:
            ax.text(i, rel[i], "in" if tin else "out", ha="center", va="bottom", fontsize=6,
                    color="C2" if tin else "C3")
    ax.set_xticks(range(len(names)), names, rotation=40, ha="right", fontsize=7)
    ax.set_ylabel("|estimate - truth| / truth")
    scale = "" if q90 is None else f" (true parameters moved a few %: up to {q90:.3f}, 90 %)"
    ax.set_title(f"{label}: relative errors (grey: not determined by the footage; orange: not estimated; "
                 f"in/out: truth inside the profile's interval)\n"
                 f"held-out error / true-parameter error = {ratio:.3f}{scale}", fontsize=7)
    save_figure(fig, path)


main = stage_app("score_cloth_twin", run)

if __name__ == "__main__":
    main()
