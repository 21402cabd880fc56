"""Stage ``fit_cloth``: cloth parameters of one fabric x trial (seed 4.4: grid, then annealing).

``python -m vidsim.cli.cloth_fit paths.footage=results/footage/cloth_linen_exp1
paths.out=results/cloth/fit/linen_exp1``

Features (silhouettes from the footage's own background model, angle maps) are extracted from
the footage; the corner paths, size and density come from ``meta.yaml``; the camera and projector
from the footage's calibration. The coarse grid (``cloth.fit.grid_levels`` values of each
``grid_params``) is followed by simulated annealing (or CMA-ES, ``cloth.fit.method``) for
``cloth.fit.budget`` evaluations. With ``cloth.fit.footage=[folder1,folder2,...]`` the fit is
*joint*: one parameter set minimising the sum of the trials' errors (the seed's "more general
solution"); ``fit.yaml`` then also lists each trial's error. Every evaluation is appended to
``evals.jsonl`` in the output folder (fsync'd): a killed stage, run again, replays those
evaluations without simulating and continues. The log's first line is the objective's
fingerprint (:meth:`vidsim.clothfit.objective.ClothObjective.fingerprint`): a rerun whose footage
or settings changed moves the old log aside (``evals.stale-<k>.jsonl``) instead of replaying it,
and a finished run leaves only its own evaluations in the log (an earlier run's, e.g. with
another seed, go to ``evals.other-runs-<k>.jsonl``). Outputs: ``fit.yaml`` (best, start and the best distinct candidates for the cross-trial
selection, from this run's evaluations only), ``trace.csv`` (per evaluation: phase, energy, best so far,
and ``simulated``: 0 for a repeated point the cache answered), ``energy.png`` and ``cloth.rrd`` (footage, fitted mesh, simulated
silhouette and angle maps, per-frame error and the energy curve).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import ClothStageError, irradiance_to_uint8, load_trial, make_objective, params_dict
from vidsim.clothfit.study import fit
from vidsim.config import to_plain
from vidsim.io.atomic import write_text, write_yaml
from vidsim.log import make_logger
from vidsim.log.progress import Progress
from vidsim.optim import FAILED_SCORE
from vidsim.optim.anneal import AnnealConfig
from vidsim.optim.cache import keep_only, point_key
from vidsim.report.figures import save_figure


class _Progressed:
    """Objective wrapper printing a progress line per new evaluation."""

    def __init__(self, obj, prog: Progress) -> None:
        self.obj, self.prog, self.best = obj, prog, np.inf

    def __call__(self, u):
        out = self.obj(u)
        self.best = min(self.best, out[0])
        self.prog.update(note=f"E = {out[0]:.4g}  best {self.best:.4g}")
        return out


def candidates(points: np.ndarray, values: np.ndarray, space, k: int) -> list[dict]:
    """The ``k`` best distinct points this fit evaluated (unit-cube distance > 0.05; failures
    excluded). Only this run's evaluations count (``FitResult.points``, replays of its own
    earlier evaluations included), not everything its log holds: a rerun with another seed in the
    same folder must hand the selection what a run in an empty folder would."""
    rows = [(float(f), np.asarray(u, float)) for u, f in zip(points, values) if f < FAILED_SCORE]
    rows.sort(key=lambda x: x[0])
    out: list[tuple[float, np.ndarray]] = []
    for f, u in rows:
        if all(np.max(np.abs(u - v)) > 0.05 for _, v in out):
            out.append((f, u))
        if len(out) >= k:
            break
    return [{"score": f, "theta": space.as_dict(space.from_unit(u))} for f, u in out]


def run(cfg: DictConfig) -> None:
    out = Path(cfg.paths.out)
    fc = cfg.cloth.fit
    folders = list(fc.footage) or ([cfg.paths.footage] if cfg.paths.footage else [])
    if not folders:
        raise ClothStageError("paths.footage is empty: give a cloth footage folder (or cloth.fit.footage=[...] for a "
                              "joint fit over several trials)")
    t0 = time.perf_counter()
    trial, frames = load_trial(folders[0], cfg, with_frames=True)
    trials = [trial] + [load_trial(f, cfg) for f in folders[1:]]
    obj = make_objective(trials, cfg)
    t_feat = time.perf_counter() - t0
    space = obj.space
    if int(fc.n_candidates) < 1:
        raise ClothStageError(f"cloth.fit.n_candidates must be >= 1 (points handed to the selection), got {fc.n_candidates}")
    if fc.method == "cmaes" and not 0 < float(fc.cma_sigma0) <= 1:
        raise ClothStageError(f"cloth.fit.cma_sigma0 must be in (0, 1] (unit-cube step), got {fc.cma_sigma0}")
    n_grid = int(fc.grid_levels) ** len(fc.grid_params)
    total = n_grid + int(fc.budget)
    label = "+".join(t.name for t in trials)
    print(f"fit_cloth {label}: {sum(t.features.n_frames for t in trials)} frames, {space.dim} parameters {space.names}, "
          f"grid {n_grid} + {fc.method} {fc.budget} evaluations", flush=True)
    log = out / "evals.jsonl"
    prog = Progress(total, f"fit_cloth {label}", every_s=5.0, enabled=cfg.log.progress)
    acfg = AnnealConfig(budget=int(fc.budget), cooling=float(fc.cooling), evals_per_T=int(fc.evals_per_T),
                        step=float(fc.step), min_step=float(fc.min_step), seed=int(fc.seed), name="cloth.fit")
    n_before = obj.n_evals
    wrapped = _Progressed(obj, prog)
    wrapped.space = space  # fit() reads objective.space
    res = fit(wrapped, grid_params=list(fc.grid_params), levels=int(fc.grid_levels), budget=int(fc.budget),
              method=str(fc.method), anneal_cfg=acfg, sigma0=float(fc.cma_sigma0), seed=int(fc.seed), cache_path=log,
              cache_context=obj.fingerprint())
    n_new = obj.n_evals - n_before
    # the log keeps this run's evaluations only (earlier runs' records of the same objective moved aside)
    aside = keep_only(log, {point_key(u) for u in res.points})
    if aside is not None:
        print(f"fit_cloth {label}: evaluations of earlier runs in {log.name} (another seed or budget) moved to "
              f"{aside.name}", flush=True)
    t_fit = time.perf_counter() - t0 - t_feat
    best = obj.params(res.theta, trial.density)
    grid_best = int(np.argmin(res.grid_values))
    # the start of the annealing: the grid's best point
    from vidsim.optim.grid import grid_points

    dims = [space.names.index(p) for p in fc.grid_params]
    gpts = grid_points(dims, int(fc.grid_levels), n=space.dim) if dims else np.full((1, space.dim), 0.5)
    start = obj.params(space.from_unit(gpts[grid_best]), trial.density)
    ev = obj.evaluate(res.theta, keep=True)
    doc = {
        "trial": label, "footage": folders[0] if len(folders) == 1 else folders, "method": str(fc.method),
        "trials": [t.name for t in trials], "per_trial": [float(e) for e in ev.per_trial] if ev.ok else None,
        "score": float(res.score), "params": params_dict(best), "estimated": list(space.names),
        "start": {"score": float(res.grid_values[grid_best]), "params": params_dict(start)},
        "candidates": candidates(res.points, np.concatenate([res.grid_values, res.trace]), space, int(fc.n_candidates)),
        "n_evals": int(res.n_evals), "n_new_simulations": int(n_new), "n_failed": int(np.sum(res.trace >= FAILED_SCORE)),
        "seconds": {"features": round(t_feat, 2), "fit": round(t_fit, 2)},
        # per trial (in "trials" order): the mean per-frame fold and silhouette terms of the best set
        "e_fold_mean": [float(np.mean(e)) for e in ev.e_fold] if ev.ok else None,
        "e_silh_mean": [float(np.mean(e)) for e in ev.e_silh] if ev.ok else None,
        "config": to_plain(cfg.cloth.fit),
    }
    vals = np.concatenate([res.grid_values, res.trace])
    sim = simulated_flags(res.points)  # compare_cloth counts simulations by this column
    write_text(out / "trace.csv", "evaluation,phase,energy,best_so_far,simulated\n" + "".join(
        f"{i},{'grid' if i < len(res.grid_values) else fc.method},{v:.6g},{b:.6g},{s_}\n"
        for i, (v, b, s_) in enumerate(zip(vals, res.best_trace, sim))))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 3.2))
    ok = vals < FAILED_SCORE
    ax.plot(np.flatnonzero(ok), vals[ok], ".", ms=3, color="0.6", label="evaluation")
    ax.plot(res.best_trace, "-", color="C0", label="best so far")
    ax.axvline(len(res.grid_values) - 0.5, color="C3", lw=0.8, ls="--", label="grid | " + str(fc.method))
    ax.set_yscale("log")
    ax.set_xlabel("evaluation")
    ax.set_ylabel("E (rad$^2$ + alpha px)")
    ax.set_title(f"{label}: {res.n_evals} evaluations, best {res.score:.4g}", fontsize=9)
    ax.legend(fontsize=7)
    save_figure(fig, out / "energy.png")
    with make_logger(out / "cloth.rrd", "vidsim.fit_cloth", cfg.log.rerun) as lg:
        lg.series("fit/energy", vals, timeline="evaluation")
        lg.series("fit/best_energy", res.best_trace, timeline="evaluation")
        if ev.ok:
            mesh_tris = obj.meshes[0].triangles
            for k in range(trial.features.n_frames):
                lg.set_frame(k)
                lg.image("footage/camera/image", frames[k])
                lg.mask("footage/camera/silhouette", trial.features.sil[k])
                # the fitted cloth's silhouette over the footage (same image space), and its rendering
                lg.mask("footage/camera/fit_silhouette", ev.sil_sim[0][k])
                lg.image("fit/camera/image", irradiance_to_uint8(ev.images[0][k]))
                lg.image("footage/camera/angle_deg", np.nan_to_num(np.degrees(trial.features.theta[k]), nan=0.0).astype(np.float32))
                lg.image("fit/camera/angle_deg", np.nan_to_num(np.degrees(ev.theta_sim[0][k]), nan=0.0).astype(np.float32))
                lg.mesh3d("world/fit/cloth", ev.positions[0][k], mesh_tris, color=(0.2, 0.5, 0.9))
                lg.points3d("world/known/corners", trial.corner_paths[k], radii=0.008)
                lg.scalar("fit/error/fold", float(ev.e_fold[0][k]))
                lg.scalar("fit/error/silhouette", float(ev.e_silh[0][k]))
    write_yaml(out / "fit.yaml", doc)
    print(f"fit_cloth {label}: best E = {res.score:.4g} after {res.n_evals} evaluations ({n_new} simulated, "
          f"{res.n_evals - n_new} replayed) in {t_fit:.1f} s", flush=True)


def simulated_flags(points: np.ndarray) -> list[int]:
    """Per evaluation of a fit (its unit-cube ``points`` in order): 1 for the first evaluation of a
    point in the run (a simulation, made now or, in a resumed run, before the kill), 0 for a repeat
    the evaluation cache answered (the annealing's start is the grid's best point, for one)."""
    seen: set[str] = set()
    out = []
    for u in points:
        k = point_key(u)
        out.append(int(k not in seen))
        seen.add(k)
    return out


main = stage_app("fit_cloth", run)

if __name__ == "__main__":
    main()
