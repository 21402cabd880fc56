"""Stage ``posterior_cloth``: how sure a fabric's selected cloth parameters are (issue 6, cloth part).

``python -m vidsim.cli.posterior_cloth posterior.cloth.params=results/cloth/select/linen/params.yaml
posterior.cloth.fits=[results/cloth/fit/linen_exp1/fit.yaml,results/cloth/fit/linen_exp2/fit.yaml]
posterior.cloth.footage=[results/footage/cloth_linen_exp1,results/footage/cloth_linen_exp2]
paths.out=results/posterior/cloth/linen`` plus the cloth overrides the fits were run with
(``cloth.model.*``: the surrogate is trained on the fits' cached evaluations, so the objective
must be the same; a mismatch is detected by re-evaluating each fit's best point and the cache of
that trial is then not used).

The likelihood is the sandwich-calibrated loss posterior of :mod:`vidsim.posterior.cloth` on the
fitted trials' summed error (E1 + E2), sampled by emcee on a GP surrogate and checked against the
true objective at ``posterior.cloth.n_check`` posterior draws. Writes ``summary.csv`` (point
estimate, 5/50/95 %, mean, sd per parameter, SI units), ``posterior.yaml`` (autocorrelation times,
``converged``, ESS, ``w``, the surrogate check, multimodality flag, correlation matrix in the
sampled coordinates: log10 of log-scaled parameters), ``corner.png``, ``correlation.png``,
``check.png`` (surrogate vs simulator at the draws), ``chain.npz`` and ``evals.jsonl`` (every true
evaluation: a killed run replays them and resumes its chain). Never reads truth.
"""

from __future__ import annotations

import dataclasses
import shutil
import time
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import ClothStageError, load_trial, make_objective
from vidsim.cli.posterior_rigid import summary_csv  # the same summary.csv columns as the rigid stage
from vidsim.cloth import PARAM_UNITS
from vidsim.config import to_plain
from vidsim.io.atomic import replace_dir, write_text, write_yaml
from vidsim.log.progress import Progress
from vidsim.optim.cache import fingerprint
from vidsim.posterior.cloth import ClothPosteriorSettings, FrameEval, cloth_posterior, read_eval_log
from vidsim.posterior.figures import corner_figure, correlation_figure
from vidsim.posterior.sampler import SamplerConfig, correlation, summarize
from vidsim.report.figures import save_figure
from vidsim.io.footage import load_yaml


def settings_from_config(pc: DictConfig) -> ClothPosteriorSettings:
    """:class:`ClothPosteriorSettings` of ``posterior.cloth`` (same field names; the emcee ones nested)."""
    names = [f.name for f in dataclasses.fields(ClothPosteriorSettings) if f.name != "sampler" and f.name in pc]
    samp = {f.name: pc[f.name] for f in dataclasses.fields(SamplerConfig) if f.name in pc}
    return ClothPosteriorSettings(**{n: pc[n] for n in names}, sampler=SamplerConfig(**samp))


def read_fits(paths: list[str]) -> tuple[list[dict], list[str], dict, dict]:
    """The fits' documents, their common estimated names, space and fixed values (checked equal)."""
    docs = []
    for p in paths:
        d = load_yaml(p, ClothStageError, "fit.yaml", mapping=True)
        for k in ("estimated", "config", "params"):
            if k not in d:
                raise ClothStageError(f"{p}: field '{k}' is missing")
        docs.append(d)
    est = list(docs[0]["estimated"])
    for p, d in zip(paths, docs):
        sp = d["config"].get("space") if isinstance(d["config"], dict) else None
        missing = [n for n in est if not isinstance(sp, dict) or n not in sp]
        if missing:
            raise ClothStageError(f"{p}: config.space has no range for the estimated parameter(s) {missing}")
    space = {n: docs[0]["config"]["space"][n] for n in est}
    fixed = dict(docs[0]["config"].get("fixed", {}) or {})
    for p, d in zip(paths[1:], docs[1:]):
        if list(d["estimated"]) != est or {n: d["config"]["space"][n] for n in est} != space \
                or dict(d["config"].get("fixed", {}) or {}) != fixed:
            raise ClothStageError(f"{p}: estimated parameters, space or fixed values differ from {paths[0]}; "
                                  "the fits of one fabric must estimate the same parameters")
    return docs, est, space, fixed


def _need_params(doc: dict, names: list[str], where: str) -> None:
    """A clear error when a parameter document lacks an estimated parameter (not a bare KeyError)."""
    got = doc.get("params") if isinstance(doc, dict) else None
    missing = [n for n in names if not isinstance(got, dict) or n not in got]
    if missing:
        raise ClothStageError(f"{where}: 'params' lacks the estimated parameter(s) {missing} (expected all of {names})")


def check_figure(check: dict, w: float, path: Path) -> None:
    """Surrogate vs true loss at the check draws."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lt = np.asarray(check["loss_true"], float)
    ls = np.asarray(check["loss_surrogate"], float)
    ok = np.isfinite(lt)
    fig, ax = plt.subplots(figsize=(4.2, 4.0))
    if not ok.any():  # every check draw failed to simulate: say so, do not crash after the sampling
        ax.text(0.5, 0.5, f"all {len(lt)} check draws failed to simulate:\nno comparison", ha="center",
                va="center", transform=ax.transAxes)
        ax.set_axis_off()
        save_figure(fig, path)
        return
    ax.plot(lt[ok], ls[ok], "o", ms=3, color="C0")
    lo, hi = float(min(lt[ok].min(), ls[ok].min())), float(max(lt[ok].max(), ls[ok].max()))
    ax.plot([lo, hi], [lo, hi], "k-", lw=0.7)
    ax.set_xlabel("true loss E1 + E2")
    ax.set_ylabel("surrogate loss")
    ax.set_title(f"{int(ok.sum())} posterior draws: max |error| {check['max_abs_error']:.3g}\n"
                 f"= {check['max_abs_error_logp']:.2f} log-density units "
                 f"({check['max_abs_error_logp_offset_free']:.2f} offset-free), w = {w:.3g}\n"
                 f"loss roughness (GP nugget) sd {check['roughness_sd']:.3g} = {check['roughness_sd_logp']:.2f} "
                 "log-density units" + ("\nNOT RELIABLE: " + "; ".join(check["problems"]) if check.get("problems") else ""),
                 fontsize=8)
    save_figure(fig, path)


def run(cfg: DictConfig) -> None:
    pc = cfg.posterior.cloth
    if not pc.params:
        raise ClothStageError("posterior.cloth.params is empty: give the select_cloth params.yaml")
    fits, footage = list(pc.fits), list(pc.footage)
    if not fits or len(fits) != len(footage):
        raise ClothStageError(f"posterior.cloth.fits ({len(fits)}) and posterior.cloth.footage ({len(footage)}) "
                              "must be non-empty lists of one length (the fitted trials)")
    sel = load_yaml(pc.params, ClothStageError, "params.yaml", mapping=True)
    if "params" not in sel:
        raise ClothStageError(f"{pc.params}: field 'params' is missing")
    docs, est, space_cfg, fixed = read_fits(fits)
    out = Path(cfg.paths.out)
    t0 = time.perf_counter()
    # the objective of the fits: same estimated names, box and fixed values as recorded in fit.yaml
    cfg2 = cfg.copy()
    OmegaConf.set_struct(cfg2, False)
    cfg2.cloth.fit.space = space_cfg
    cfg2.cloth.fit.estimate = est
    cfg2.cloth.fit.fixed = fixed
    trials = [load_trial(f, cfg2) for f in footage]
    obj = make_objective(trials, cfg2)
    space = obj.space
    alpha = obj.alpha
    t_feat = time.perf_counter() - t0

    def evaluate(u: np.ndarray) -> FrameEval:
        r = obj.evaluate(space.from_unit(u))
        if not r.ok:
            return FrameEval([], ok=False, failure=r.failure)
        return FrameEval([np.asarray(a) + alpha * np.asarray(b) for a, b in zip(r.e_fold, r.e_silh)])

    # cached annealing evaluations of each trial's fit; used only when that trial's objective
    # reproduces the fit's best score (same model settings)
    cached, cache_notes = [], []
    for t, (fp, d) in enumerate(zip(fits, docs)):
        U, f = read_eval_log(Path(fp).parent / "evals.jsonl", space.dim)
        use = len(f) > 0
        if use:
            i = int(np.argmin(f))
            one = make_objective([trials[t]], cfg2)
            r = one.evaluate(space.from_unit(U[i]))
            use = r.ok and abs(r.score - f[i]) <= 1e-6 * max(abs(f[i]), 1e-12)
            cache_notes.append({"fit": fp, "n": int(len(f)), "best_cached": float(f[i]),
                                "best_reevaluated": float(r.score) if r.ok else None, "used": bool(use)})
            if not use:
                print(f"posterior_cloth: {fp}: re-evaluated best {r.score:.6g} != cached {f[i]:.6g}: "
                      "its cache is not used (different model settings?)", flush=True)
        else:
            cache_notes.append({"fit": fp, "n": 0, "used": False})
        cached.append((U, f) if use else (np.zeros((0, space.dim)), np.zeros(0)))
    _need_params(sel, space.names, f"{pc.params}")
    theta_sel = np.array([float(sel["params"][n]) for n in space.names])
    center = space.to_unit(theta_sel)
    cands = []
    for row in sel.get("rows", []) or []:
        errs = row.get("errors", {}) or {}
        if len(errs) == len(trials):
            _need_params(row, space.names, f"{pc.params}: rows[{row.get('candidate', '?')}]")
            th = np.array([float(row["params"][n]) for n in space.names])
            cands.append((space.to_unit(th), float(sum(float(v) for v in errs.values()))))
    s = settings_from_config(pc)
    tmp = out.with_name(f".{out.name}.part")  # kept on a kill: evals.jsonl and chain files are resumed
    tmp.mkdir(parents=True, exist_ok=True)
    prog = Progress(int(np.ceil(s.sampler.max_steps / s.sampler.chunk)), "posterior_cloth chain chunks",
                    enabled=cfg.log.progress)
    print(f"posterior_cloth: {len(trials)} trials, {space.dim} parameters {space.names}, "
          f"cached evaluations {[len(c[1]) for c in cached]}", flush=True)
    post = cloth_posterior(evaluate, space.dim, center, cached, s, tmp, cands,
                           progress=lambda m: print(f"posterior_cloth: {m}", flush=True),
                           on_chunk=lambda i: prog.update(note=f"step {i['step']} tau_max {i['tau_max']:.0f}"),
                           context=fingerprint("posterior_cloth frames", obj.fingerprint()))
    ch = post.chain
    S = post.samples()
    nat = space.from_unit(S)
    rows = summarize(nat, space.names, theta_sel)
    for r in rows:
        r["unit"] = PARAM_UNITS.get(r["name"], "")
    # display / correlation coordinates: log10 of log-scaled parameters
    logs = [a.log for a in space.axes]
    disp = np.where(logs, np.log10(np.maximum(nat, 1e-300)), nat)
    dnames = [("log10 " if lg else "") + n for n, lg in zip(space.names, logs)]
    corr = correlation(disp) if space.dim > 1 else np.ones((1, 1))
    sampling_min = max(post.seconds["sampling"], 1e-9) / 60.0
    total_s = time.perf_counter() - t0
    diag = {
        "converged": bool(ch.converged), "n_steps": int(ch.n_steps), "burn": int(ch.burn),
        "n_walkers": int(ch.chain.shape[1]), "tau": [float(x) for x in ch.tau], "tau_max": float(np.max(ch.tau)),
        "steps_per_tau": float(ch.n_steps / np.max(ch.tau)) if np.isfinite(np.max(ch.tau)) else 0.0,
        "min_tau_multiple": float(s.sampler.min_tau_multiple),
        "ess": float(ch.ess), "ess_per_min_sampling": float(ch.ess / sampling_min),
        "ess_per_min_stage": float(ch.ess / (total_s / 60.0)), "acceptance": float(ch.acceptance),
        "noise": s.noise, "w": float(post.w), "weights": post.weights, "loss_mode_surrogate": float(post.loss_mode),
        "mode_unit": [float(x) for x in post.mode], "mode": space.as_dict(space.from_unit(post.mode)),
        "multimodal": bool(post.multimodal), "multimodal_reasons": post.multimodal_reasons,
        "true_evaluations": int(post.n_true_evals), "new_true_evaluations": int(post.n_new_evals),
        "seconds": {"features": round(t_feat, 2), **{k: round(v, 2) for k, v in post.seconds.items()},
                    "stage": round(total_s, 2)},
    }
    check = {k: v for k, v in post.check.items() if k not in ("draws", "loss_true", "loss_surrogate")}
    write_text(tmp / "summary.csv", summary_csv(rows))
    write_yaml(tmp / "posterior.yaml", {
        "diagnostics": diag, "surrogate_check": check, "names": space.names,
        "units": [PARAM_UNITS.get(n, "") for n in space.names],
        "correlation_coordinates": dnames, "correlation": np.round(corr, 4).tolist(),
        "design_rounds": post.rounds, "cache": cache_notes, "fixed": fixed,
        "trials": [t.name for t in trials], "point_estimate": pc.params,
        "config": to_plain(pc)})
    warn = ", ".join(w for w, bad in (("chain NOT converged", not diag.get("converged", True)),
                                       ("multimodal", bool(diag.get("multimodal"))),
                                       ("surrogate check failed (strict)", not check.get("ok", True))) if bad)
    save_figure(corner_figure(disp, dnames, None, np.where(logs, np.log10(theta_sel), theta_sel), flags=warn),
                tmp / "corner.png")
    save_figure(correlation_figure(corr, dnames, "cloth posterior correlation (log10 of log-scaled parameters)"),
                tmp / "correlation.png")
    check_figure(post.check, post.w, tmp / "check.png")
    # the chain the summaries were made from (a killed earlier run may have left a later round's file)
    shutil.copyfile(post.chain_file, tmp / "chain.npz")
    replace_dir(tmp, out)
    print(f"posterior_cloth: converged {diag['converged']} (steps {diag['n_steps']}, tau_max {diag['tau_max']:.0f}), "
          f"ESS {diag['ess']:.0f}, surrogate max error {check['max_abs_error_logp']:.3g} log-density units "
          f"(ok {check['ok']}, roughness sd {check['roughness_sd_logp']:.3g}, consistent "
          f"{check['consistent_with_roughness']}), multimodal {diag['multimodal']}, {total_s:.0f} s", flush=True)
    if check.get("problems"):
        print("posterior_cloth: WARNING: the surrogate posterior is not reliable here: " + "; ".join(check["problems"])
              + " (posterior.yaml: surrogate_check.problems)", flush=True)


main = stage_app("posterior_cloth", run)

if __name__ == "__main__":
    main()
