"""Stage ``select_cloth``: cross-trial selection of one fabric's parameters (seed Table 1).

``python -m vidsim.cli.cloth_select paths.out=results/cloth/select/linen
cloth.select.fits=[fit1.yaml,fit2.yaml] cloth.select.footage=[footage1,footage2]`` (with the fits' own
``cloth.*`` settings: their estimated set and model).

Each trial's best distinct candidates (from its ``fit.yaml``) are evaluated on the *other* trial
without re-optimising; the candidate with the least E1 + E2 is chosen. Writes ``params.yaml``
and ``table.csv`` (one row per candidate: origin, parameters, E1, E2, E1 + E2, chosen).

With ``cloth.select.polish_budget`` > 0 the chosen set is then polished on E1 + E2 (one annealing
over all trials at once, started at the selection; evaluations in ``polish_evals.jsonl``, resumed
after a kill; the candidates' scores are logged in ``select_evals_<k>.jsonl``, one per trial, and
resumed the same way); ``params.yaml`` then holds the polished set when it lowers E1 + E2, with the
selection under ``selected`` and the polish's record under ``polish`` (``table.csv`` gets a
``polish`` row). ``params.yaml``'s ``trial_simulations`` says how many trial simulations the stage
made: ``selection`` (every candidate on every trial, its own included: simulated afresh) and
``polish`` (its distinct joint evaluations times the trials, plus the improved set's evaluation).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import ClothStageError, LoggedScores, load_trial, make_objective, params_dict
from vidsim.cloth import ESTIMATED_NAMES
from vidsim.io.atomic import write_text, write_yaml
from vidsim.log.progress import Progress
from vidsim.optim.anneal import AnnealConfig, anneal
from vidsim.optim.cache import EvalCache, point_key
from vidsim.io.footage import load_yaml


def run(cfg: DictConfig) -> None:
    out = Path(cfg.paths.out)
    fits, footage = list(cfg.cloth.select.fits), list(cfg.cloth.select.footage)
    if len(fits) < 2 or len(fits) != len(footage):
        raise ClothStageError(f"cloth.select.fits ({len(fits)}) and cloth.select.footage ({len(footage)}) must list "
                              "the same >= 2 trials")
    docs = []
    for f in fits:
        p = Path(f)
        if not p.is_file():
            raise ClothStageError(f"{p}: fit.yaml is missing")
        docs.append(load_yaml(p, ClothStageError, "fit.yaml", mapping=True))
    trials = [load_trial(f, cfg) for f in footage]
    objs = [make_objective([tr], cfg) for tr in trials]
    cands = []
    names = objs[0].space.names
    for i, d in enumerate(docs):
        missing = [k for k in ("params", "score") if k not in d]
        if missing:  # checked before the evaluations: Table 1's per-fit row needs both
            raise ClothStageError(f"{fits[i]}: field(s) {missing} missing (not a fit_cloth output)")
        est = d.get("estimated")
        if est is not None and set(est) != set(names):
            # the candidates' other values would be replaced by fixed or mid-range ones without a word
            raise ClothStageError(f"{fits[i]}: the fit estimated {list(est)}, but this selection's cloth.fit.estimate "
                                  f"gives {list(names)}: pass the fit's own settings")
        for k, c in enumerate(d.get("candidates") or [{"theta": d["params"]}]):
            theta = c.get("theta") if isinstance(c, dict) else None
            lacking = [n for n in names if not isinstance(theta, dict) or n not in theta]
            if lacking:
                raise ClothStageError(f"{fits[i]}: candidate {k} lacks the estimated parameter(s) {lacking} (the fit "
                                      f"estimated other parameters than cloth.fit.estimate = {list(names)}?)")
            cands.append((f"{trials[i].name}#{k}", theta))
    prog = Progress(len(cands) * len(trials), "select_cloth evaluations", enabled=cfg.log.progress)
    # each trial's scores logged as they finish (select_evals_<k>.jsonl), so a killed stage resumes
    # without simulating them again; ClothObjective.evaluate(theta) is evaluate_params of these params
    logs = [LoggedScores(obj, out / f"select_evals_{k}.jsonl") for k, obj in enumerate(objs)]
    rows = []
    try:
        for label, theta in cands:
            errs = []
            for tr, obj, log in zip(trials, objs, logs):
                th = np.array([float(theta[n]) for n in obj.space.names])
                errs.append(float(log.evaluate_params(obj.params(th, tr.density)).score))
                prog.update(note=label)
            rows.append((label, theta, errs))
    finally:
        for log in logs:
            log.close()
    tot = [sum(e) for _, _, e in rows]
    best = int(np.argmin(tot))
    label, theta, errs = rows[best]
    obj = objs[0]
    params = obj.params(np.array([float(theta[n]) for n in obj.space.names]), trials[0].density)
    selected = {"chosen": label, "params": params_dict(params), "errors": {tr.name: e for tr, e in zip(trials, errs)},
                "total": float(sum(errs))}
    polish = None
    sc = cfg.cloth.select
    if int(sc.polish_budget) > 0:
        params, errs, polish = _polish(trials, cfg, obj.theta_of(params), float(sum(errs)), out, errs)
        if polish["improved"]:
            label = f"polish({label})"
            rows.append((label, {n: float(getattr(params, n)) for n in ESTIMATED_NAMES}, errs))
            best = len(rows) - 1
    names = [n for n in ESTIMATED_NAMES]
    hdr = "candidate," + ",".join(names) + "," + ",".join(f"E{i + 1}" for i in range(len(trials))) + ",total,chosen\n"
    lines = [f"{lab}," + ",".join(f"{float(th.get(n, getattr(params, n))):.5g}" for n in names) + "," +
             ",".join(f"{e:.5g}" for e in es) + f",{sum(es):.5g},{int(j == best)}\n" for j, (lab, th, es) in enumerate(rows)]
    write_text(out / "table.csv", hdr + "".join(lines))
    extra = {"selected": selected, "polish": polish} if polish is not None else {}
    # trial simulations this selection made (compare_cloth adds them to the fits' budgets): every
    # candidate on every trial, and the polish's distinct joint evaluations, each simulating every trial
    sims = {"selection": len(cands) * len(trials), "polish": 0 if polish is None else int(polish["trial_simulations"])}
    write_yaml(out / "params.yaml", {
        **extra, "params": params_dict(params), "trial_simulations": sims, "chosen": label, "errors": {tr.name: e for tr, e in zip(trials, errs)},
        "total": float(sum(errs)), "trials": [tr.name for tr in trials], "fits": fits,
        "start": docs[0].get("start", {}).get("params"),
        "per_fit_best": {tr.name: {"params": d["params"], "score": d["score"]} for tr, d in zip(trials, docs)},
        "rows": [{"candidate": lab, "params": {n: float(th.get(n, getattr(params, n))) for n in names},
                  "errors": {tr.name: float(e) for tr, e in zip(trials, es)}, "total": float(sum(es)),
                  "chosen": j == best} for j, (lab, th, es) in enumerate(rows)],
    })
    print(f"select_cloth: chose {label} with E1+E2 = {sum(errs):.4g} of {len(rows)} candidates", flush=True)


def _polish(trials: list, cfg: DictConfig, theta0: np.ndarray, f_sel: float, out: Path, errs0: list[float]):
    """Joint annealing on E1 + E2 from the selected set (``cloth.select.polish_*``).

    Returns ``(params, per-trial errors, record)``: the polished set if it lowered E1 + E2, else the
    selection unchanged; the record has the budget, E1 + E2 before and after and the seconds.
    """
    import time

    sc = cfg.cloth.select
    if not (float(sc.polish_t0) > 0 and 0 < float(sc.polish_step) <= 1):
        raise ClothStageError(f"cloth.select.polish_t0 = {sc.polish_t0} must be > 0 and polish_step = "
                              f"{sc.polish_step} in (0, 1]")
    joint = make_objective(trials, cfg)
    u0 = joint.space.to_unit(np.asarray(theta0, float))
    t = time.perf_counter()
    budget = int(sc.polish_budget)
    prog = Progress(budget, "select_cloth polish (E1+E2)", enabled=cfg.log.progress)

    def f(u):
        r = joint(u)
        prog.update(note=f"{r[0]:.4g}")
        return r

    acfg = AnnealConfig(budget=budget, T0=float(sc.polish_t0) * f_sel, cooling=0.8, evals_per_T=10,
                        step=float(sc.polish_step), min_step=min(0.01, float(sc.polish_step)), seed=int(cfg.cloth.fit.seed))
    with EvalCache(f, out / "polish_evals.jsonl", context=joint.fingerprint()) as fc:
        res = anneal(fc, u0, acfg)
    improved = bool(np.isfinite(res.best_f) and res.best_f < f_sel)
    theta = joint.space.from_unit(res.best_u) if improved else np.asarray(theta0, float)
    params = joint.params(theta, trials[0].density)
    errs = list(joint.evaluate(theta).per_trial) if improved else list(errs0)
    # distinct points (a repeat is the cache's answer), each simulating every trial, and the improved
    # set's final evaluation
    n_points = len({point_key(u) for u, _ in fc.history})
    rec = {"budget": budget, "total_before": float(f_sel), "total_after": float(sum(errs)), "improved": improved,
           "seconds": time.perf_counter() - t, "trial_simulations": len(trials) * (n_points + int(improved))}
    print(f"select_cloth: polish E1+E2 {f_sel:.4g} -> {sum(errs):.4g} ({budget} joint evaluations)", flush=True)
    return params, errs, rec


main = stage_app("select_cloth", run)

if __name__ == "__main__":
    main()
