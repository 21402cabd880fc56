"""Stage ``rigid_summary``: one table (CSV + PNG) over the scored throws of the study.

``python -m vidsim.cli.rigid_summary "rigid.paths.scores='results/rigid/a/score.yaml results/rigid/b/score.yaml'"
paths.out=results/rigid`` writes ``summary.csv`` (one row per case: errors, pass/fail, segmentation
IoU, fit time, ``ambiguous`` True/False or ``unchecked`` when the fit refined one candidate, effects
switched on) and ``summary.png`` (each error over its threshold, per case).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli._rigid import RigidStageError, load_yaml
from vidsim.io.atomic import write_text
from vidsim.report.figures import save_figure
from vidsim.rigid.evaluate import CRITERIA

COLUMNS = ("orientation_deg", "omega_rel", "position_rel_range", "velocity_rel", "gravity_deg", "mean_iou")


def run(cfg: DictConfig) -> None:
    paths = [Path(p) for p in str(cfg.rigid.paths.scores).split()]
    if not paths:
        raise RigidStageError("rigid.paths.scores is empty: give the score.yaml files to collect (space separated)")
    out = Path(cfg.paths.out)
    rows = []
    for p in paths:
        d = load_yaml(p)
        if not isinstance(d, dict) or "errors" not in d:
            raise RigidStageError(f"{p}: missing field 'errors' (not a score_rigid output)")
        missing = [k for k in ("success", "segmentation", "fit") if k not in d]
        missing += [f"errors.{k}" for k in (*COLUMNS, "mean_iou_footage") if not isinstance(d["errors"], dict)
                    or k not in d["errors"]]
        missing += [f"{g}.{k}" for g, ks in (("segmentation", ("mean_iou",)), ("fit", ("seconds", "n_starts", "ambiguous")))
                    for k in ks if isinstance(d.get(g), dict) and k not in d[g]]
        if missing:
            raise RigidStageError(f"{p}: missing field(s) {missing} (not a score_rigid output of this version)")
        rows.append((p.parent.name, d))
    head = ["case", "seed", "success", *COLUMNS, "mean_iou_footage", "segmentation_iou", "fit_seconds", "n_starts",
            "ambiguous", "effects_on"]
    lines = [",".join(head)]
    for case, d in rows:
        e = d["errors"]
        eff = " ".join(f"{k}={v}" for k, v in d.get("effects_on", {}).items()).replace(",", ";")
        lines.append(",".join([case, str(d.get("seed")), str(d["success"]), *(f"{e[k]:.6g}" for k in COLUMNS),
                               f"{e['mean_iou_footage']:.6g}", f"{d['segmentation']['mean_iou']:.6g}",
                               f"{d['fit']['seconds']:.1f}", str(d['fit']['n_starts']),
                               "unchecked" if d['fit']['ambiguous'] is None else str(d['fit']['ambiguous']),
                               eff]))
    n_ok = sum(bool(d["success"]) for _, d in rows)

    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(max(6, 1.2 * len(rows) + 3), 4))
    w = 0.8 / len(COLUMNS)
    x = np.arange(len(rows))
    for j, k in enumerate(COLUMNS):
        # error over threshold (< 1 passes); IoU as shortfall (1 - IoU) over (1 - 0.97)
        r = [(1 - d["errors"][k]) / (1 - CRITERIA[k]) if k == "mean_iou" else d["errors"][k] / CRITERIA[k]
             for _, d in rows]
        ax.bar(x + (j - len(COLUMNS) / 2 + 0.5) * w, np.maximum(r, 1e-4), w,
               label=f"1 - mean_iou (over 1 - {CRITERIA[k]:g})" if k == "mean_iou" else k)
    ax.axhline(1.0, color="k", lw=1, ls="--")
    ax.set_yscale("log")
    ax.set_xticks(x, [c for c, _ in rows], rotation=30, ha="right")
    ax.set_ylabel("error / threshold (< 1 passes)")
    ax.set_title(f"rigid throws: {n_ok}/{len(rows)} meet every criterion")
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    save_figure(fig, out / "summary.png")
    write_text(out / "summary.csv", "\n".join(lines) + "\n")  # the main output last
    print(f"rigid_summary: {n_ok}/{len(rows)} throws meet every criterion -> {out / 'summary.csv'}")


main = stage_app("rigid_summary", run)

if __name__ == "__main__":
    main()
