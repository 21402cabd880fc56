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
model). Writes ``score.yaml``, ``errors.csv`` and ``errors.png``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import ClothStageError, load_trial, make_objective, params_from_dict, read_selected
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
    truth = read_truth(tc.footage)
    if truth.get("kind") != "twin" or "params" not in truth:
        raise ClothStageError(f"{tc.footage}: its truth is not a twin reality's (kind = {truth.get('kind')!r})")
    sel = read_selected([str(tc.params)])[0]
    # the profile of these parameters (profile_cloth), if any: which of them the footage determines
    prof = load_yaml(tc.profile, ClothStageError, "profile.yaml", mapping=True).get("profiles", {}) if tc.profile else {}
    est = params_from_dict(sel["params"], str(tc.params))
    true = params_from_dict(truth["params"], f"truth of {tc.footage}")
    obj = make_objective([load_trial(tc.footage, cfg)], cfg)
    e_est = float(obj.evaluate_params(est).score)
    e_true = float(obj.evaluate_params(true).score)
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
    ratio = e_est / e_true if e_true > 0 else float("inf")
    checks = {"heldout_ratio": {"value": ratio, "target": float(tc.heldout_ratio), "met": bool(ratio <= tc.heldout_ratio)}}
    for n in tc.rel_tol_params:
        checks[f"{n}_relative_error"] = {"value": rows[n]["relative_error"], "target": float(tc.rel_tol),
                                         "met": bool(rows[n]["relative_error"] <= tc.rel_tol)}
    doc = {"heldout": {"footage": str(tc.footage), "error_selected": e_est, "error_true_params": e_true, "ratio": ratio},
           "parameters": rows, "checks": checks, "not_determined": [n for n, r in rows.items() if r["determined"] is False]}
    write_text(out / "errors.csv", "parameter,estimate,truth,relative_error,estimated,determined,interval_lo,"
               "interval_hi\n" + "".join(_csv_row(n, r) for n, r in rows.items()))
    _figure(rows, ratio, out / "errors.png")
    write_yaml(out / "score.yaml", doc)
    print(f"score_cloth_twin: held-out error ratio {ratio:.3f}; relative errors " +
          ", ".join(f"{n} {r['relative_error']:.0%}" for n, r in rows.items()), flush=True)


def _csv_row(name: str, r: dict) -> str:
    det = "" if r["determined"] is None else str(int(r["determined"]))
    lo, hi = ("", "") if r["interval"] is None else (f"{r['interval'][0]:.5g}", f"{r['interval'][1]:.5g}")
    return (f"{name},{r['estimate']:.5g},{r['truth']:.5g},{r['relative_error']:.4g},{int(r['estimated'])},{det},"
            f"{lo},{hi}\n")


def _figure(rows: dict, ratio: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(rows)
    rel = np.array([rows[n]["relative_error"] for n in names])
    col = ["C1" if not rows[n]["estimated"] else ("0.6" if rows[n]["determined"] is False else "C0") for n in names]
    fig, ax = plt.subplots(figsize=(7, 3))
    ax.bar(range(len(names)), rel, color=col)
    ax.axhline(0.25, color="C3", lw=0.8, ls="--")
    ax.set_yscale("symlog", linthresh=0.1)
    ax.set_xticks(range(len(names)), names, rotation=40, ha="right", fontsize=7)
    ax.set_ylabel("|estimate - truth| / truth")
    ax.set_title(f"twin: relative errors (grey: not determined by the footage; orange: not estimated); "
                 f"held-out error / true-parameter error = {ratio:.3f}", fontsize=7)
    save_figure(fig, path)


main = stage_app("score_cloth_twin", run)

if __name__ == "__main__":
    main()
