"""Stage ``profile_cloth``: which parameters one fabric's footage determines (error profiles).

``python -m vidsim.cli.cloth_profile paths.out=results/cloth/profile/linen
cloth.profile.params=results/cloth/select/linen/params.yaml
cloth.profile.footage=[results/footage/cloth_linen_exp1,results/footage/cloth_linen_exp2]``

Around the selected parameters, each estimated parameter is swept across its whole range with the
others held (a slice; with ``cloth.profile.reoptimise_evals=N`` the others are re-optimised at each
point, a profile proper, its evaluations logged to ``evals.jsonl`` for resuming), on the fitted
trials together (E1 + E2, the selection's criterion); see :mod:`vidsim.clothfit.profile`.
Writes ``profile.yaml`` (per parameter: estimate, ``determined``, indifference interval, its
width as a fraction of the range; the loss's measured roughness and the tolerance it gave;
``stopped_short``: the parameters along which the profile found an error lower than the
estimate's by more than that tolerance, i.e. where the fit stopped short, with a warning),
``profiles.csv`` and ``profiles.png`` (one panel per parameter; a flat profile is labelled
"not determined").
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import ClothStageError, load_trial, make_objective, read_selected
from vidsim.clothfit.profile import profile_parameters, stopped_short
from vidsim.io.atomic import write_text, write_yaml
from vidsim.log.progress import Progress
from vidsim.optim import FAILED_SCORE
from vidsim.report.figures import save_figure


def run(cfg: DictConfig) -> None:
    out = Path(cfg.paths.out)
    pc = cfg.cloth.profile
    if not pc.params or not list(pc.footage):
        raise ClothStageError("cloth.profile.params (a params.yaml) and cloth.profile.footage (the fitted trials' "
                              "folders) must be given")
    sel = read_selected([str(pc.params)])[0]
    trials = [load_trial(f, cfg) for f in pc.footage]
    obj = make_objective(trials, cfg)
    missing = [n for n in obj.space.names if n not in sel["params"]]
    if missing:
        raise ClothStageError(f"{pc.params}: params lack {missing}")
    theta = np.array([float(sel["params"][n]) for n in obj.space.names])
    reopt = int(pc.get("reoptimise_evals", 0))
    if reopt < 0:
        raise ClothStageError(f"cloth.profile.reoptimise_evals must be >= 0 (0: a slice), got {reopt}")
    rough = int(pc.get("roughness_points", 0))
    if rough < 0 or not float(pc.get("roughness_z", 2.0)) >= 0:
        raise ClothStageError(f"cloth.profile.roughness_points and roughness_z must be >= 0, got {rough}, "
                              f"{pc.get('roughness_z')}")
    if int(pc.points) < 2:  # 1 or 0 points made every parameter "determined" (width 0.5 or 0)
        raise ClothStageError(f"cloth.profile.points must be >= 2 (values per parameter), got {pc.points}")
    if not float(pc.tol) >= 0:
        raise ClothStageError(f"cloth.profile.tol must be >= 0 (a fraction of the estimate's error), got {pc.tol}")
    if not 0 < float(pc.max_width) < 1:
        raise ClothStageError(f"cloth.profile.max_width must be in (0, 1) (a fraction of the unit range), got {pc.max_width}")
    n_points = obj.space.dim * int(pc.points)
    prog = Progress(n_points, "profile_cloth" + (f" (others re-optimised, {reopt} evaluations per point)"
                                                 if reopt else ""), enabled=cfg.log.progress)
    from vidsim.optim.cache import EvalCache

    # every evaluation (slice or profile) is logged, keyed by the objective's fingerprint: a killed
    # stage resumes (at the full setting a slice is ~70 two-trial evaluations, minutes of work)
    with EvalCache(obj, out / "evals.jsonl", context=obj.fingerprint()) as f_unit:
        rinfo: dict = {}
        profs = profile_parameters(obj, theta, points=int(pc.points), tol=float(pc.tol), max_width=float(pc.max_width),
                                   on_eval=lambda n, v, e: prog.update(note=f"{n} = {v:.3g}: E = {e:.4g}"),
                                   reoptimise_evals=reopt, seed=int(pc.get("seed", 0)), f_unit=f_unit,
                                   roughness_points=rough, roughness_z=float(pc.get("roughness_z", 2.0)), info=rinfo)
    doc = {"params": str(pc.params), "footage": list(pc.footage), "tol": float(pc.tol),
           "roughness_points": rough, "roughness_sd": rinfo["roughness_sd"], "tol_effective": rinfo["tol_effective"],
           "max_width": float(pc.max_width), "kind": "profile" if reopt else "slice",
           "reoptimise_evals": reopt, "profiles": {p.name: p.to_dict() for p in profs},
           "not_determined": [p.name for p in profs if not p.determined],
           # a slice or profile below the estimate by more than "as good": the fit stopped short there
           "stopped_short": stopped_short(profs, rinfo["tol_effective"])}
    write_text(out / "profiles.csv", "parameter,unit_position,value,error\n" + "".join(
        f"{p.name},{u:.4f},{v:.6g},{e:.6g}\n" for p in profs for u, v, e in zip(p.u, p.values, p.errors)))
    _figure(profs, obj.space, rinfo["tol_effective"], out / "profiles.png", reopt)
    write_yaml(out / "profile.yaml", doc)
    print(f"profile_cloth: roughness sd {rinfo['roughness_sd']:.3g} (as good: within {rinfo['tol_effective']:.1%} of "
          f"the estimate); not determined by the footage: {doc['not_determined'] or 'none'}", flush=True)
    for name, b in doc["stopped_short"].items():
        print(f"profile_cloth: WARNING: along {name} the profile reaches E = {b['error']:.4g} at {b['value']:.4g}, below the "
              f"estimate's {b['error_at_estimate']:.4g} by more than the 'as good' tolerance: the fit stopped short of "
              f"it, so this estimate is where the search ended, not a minimum", flush=True)


def _figure(profs, space, tol: float, path: Path, reopt: int = 0) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(profs)
    cols = min(3, n)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3.3 * cols, 2.4 * rows), squeeze=False)
    for ax, p, axis in zip(axes.ravel(), profs, space.axes):
        ok = p.errors < FAILED_SCORE
        ax.plot(p.values[ok], p.errors[ok] / p.e_hat, "o-", ms=3)
        ax.axhspan(0, 1 + tol, color="0.9", zorder=0)
        ax.axvline(p.values[np.argmin(np.abs(p.u - p.u_hat))], color="C3", lw=0.8)
        ax.axvspan(*p.interval, color="C2", alpha=0.15)
        if axis.log:
            ax.set_xscale("log")
        ax.set_ylim(bottom=max(0.0, np.nanmin(p.errors[ok] / p.e_hat) - 0.05) if ok.any() else 0)
        if not p.determined:
            label = "NOT determined (flat)"
        else:
            label = ("determined" if p.reoptimised else "sensitive (slice)") + ("" if p.resolved else ", width < grid step")
        ax.set_title(f"{p.name}: {label}", fontsize=8, color="k" if p.determined else "C3")
        ax.tick_params(labelsize=7)
        ax.set_ylabel("E / E(estimate)", fontsize=7)
    for ax in axes.ravel()[n:]:
        ax.set_axis_off()
    kind = (f"profiles, the others re-optimised ({reopt} evaluations per point)" if reopt
            else "slices, the others held at the estimate")
    fig.suptitle(f"error {kind}\n(grey: as good as the estimate, within {tol:.1%}, the larger of the tolerance "
                 f"and the roughness band; green: indifference interval)", fontsize=8)
    save_figure(fig, path)


main = stage_app("profile_cloth", run)

if __name__ == "__main__":
    main()
