"""Stage ``validate_cloth``: the fabric validation matrix (seed Figure 8) and Table 1.

Every fabric's selected parameters (``params.yaml`` of ``select_cloth``) are simulated on every
fabric's *held-out* footage (the robot motion, never used for fitting) and scored with the same
metric: ``matrix.csv`` / ``matrix.png`` (rows: parameters, columns: footage; the diagonal should
win each column). ``table1.csv`` / ``table1.png`` collect per fabric the grid start, each trial's
optimum and the selected set with E1, E2 and the cross errors (from ``select_cloth``'s table).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import ClothStageError, load_trial, make_objective
from vidsim.io.atomic import write_text, write_yaml
from vidsim.log.progress import Progress
from vidsim.report.figures import save_figure

SHOWN = ("bend", "stretch", "shear", "drag_linear", "drag_quad")


def run(cfg: DictConfig) -> None:
    out = Path(cfg.paths.out)
    v = cfg.cloth.validate
    fabrics, pfiles, footage = list(v.fabrics), list(v.params), list(v.footage)
    if not fabrics or not (len(fabrics) == len(pfiles) == len(footage)):
        raise ClothStageError(f"cloth.validate: fabrics ({len(fabrics)}), params ({len(pfiles)}) and footage "
                              f"({len(footage)}) must be non-empty lists of one length")
    sel = []
    for p in pfiles:
        if not Path(p).is_file():
            raise ClothStageError(f"{p}: params.yaml is missing")
        sel.append(yaml.safe_load(Path(p).read_text()))
    n = len(fabrics)
    E = np.zeros((n, n))
    prog = Progress(n * n, "validate_cloth matrix", enabled=cfg.log.progress)
    for j, f in enumerate(footage):
        tr = load_trial(f, cfg)
        obj = make_objective([tr], cfg)
        for i, s in enumerate(sel):
            th = np.array([float(s["params"][k]) for k in obj.space.names])
            E[i, j] = obj.evaluate(th).score
            prog.update(note=f"{fabrics[i]} params on {fabrics[j]} footage")
    wins = [int(np.argmin(E[:, j]) == j) for j in range(n)]
    write_text(out / "matrix.csv", "params\\footage," + ",".join(fabrics) + "\n" + "".join(
        f"{fabrics[i]}," + ",".join(f"{E[i, j]:.5g}" for j in range(n)) + "\n" for i in range(n)))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(1.3 * n + 2, 1.1 * n + 1.5))
    R = E / E.min(axis=0, keepdims=True)
    im = ax.imshow(R, cmap="viridis_r")
    for i in range(n):
        for j in range(n):
            ax.text(j, i, f"{E[i, j]:.3g}", ha="center", va="center", fontsize=8,
                    color="w" if R[i, j] > 0.5 * (R.max() + 1) else "k", weight="bold" if i == j else None)
    ax.set_xticks(range(n), fabrics)
    ax.set_yticks(range(n), fabrics)
    ax.set_xlabel("held-out footage (robot motion)")
    ax.set_ylabel("selected parameters of")
    ax.set_title(f"error / column minimum; diagonal wins {sum(wins)}/{n}", fontsize=9)
    fig.colorbar(im, ax=ax, shrink=0.8)
    save_figure(fig, out / "matrix.png")
    # Table 1: per fabric the grid start, every candidate with its error on each trial (own and
    # cross) and their sum, the selected row marked
    rows = []
    for fab, s in zip(fabrics, sel):
        short = {t: t.replace(f"cloth_{fab}_", "") for t in s["trials"]}
        if s.get("start"):
            rows.append((fab, "start (grid best)", s["start"], {}, None))
        for r in s.get("rows", []):
            trial, _, k = r["candidate"].partition("#")
            name = f"opt {short.get(trial, trial)}" + (f" #{k}" if k not in ("", "0") else "") + (" *" if r["chosen"] else "")
            rows.append((fab, name, r["params"], {short.get(t, t): e for t, e in r["errors"].items()}, r["total"]))
    trials = sorted({t for *_, errs, _ in rows for t in errs})
    hdr = "fabric,set," + ",".join(SHOWN) + "," + ",".join(f"E_{t}" for t in trials) + ",E_sum\n"
    lines = [f"{fab},{name}," + ",".join(f"{float(p[k]):.4g}" for k in SHOWN) + "," +
             ",".join(f"{errs[t]:.4g}" if t in errs else "" for t in trials) + "," + (f"{tot:.4g}" if tot is not None else "") + "\n"
             for fab, name, p, errs, tot in rows]
    write_text(out / "table1.csv", hdr + "".join(lines))
    fig, ax = plt.subplots(figsize=(12, 0.3 * len(rows) + 0.9))
    ax.axis("off")
    cells = [[fab, name] + [f"{float(p[k]):.3g}" for k in SHOWN] + [f"{errs[t]:.3g}" if t in errs else "" for t in trials] +
             [f"{tot:.3g}" if tot is not None else ""] for fab, name, p, errs, tot in rows]
    tb = ax.table(cellText=cells, colLabels=["fabric", "set", *SHOWN, *[f"E {t}" for t in trials], "E sum"], loc="center",
                  cellLoc="center")
    tb.auto_set_font_size(False)
    tb.set_fontsize(7)
    tb.scale(1, 1.2)
    ax.set_title("Table 1 (* = selected: least E sum over the trials)", fontsize=9)
    save_figure(fig, out / "table1.png")
    write_yaml(out / "validation.yaml", {"fabrics": fabrics, "matrix": E.tolist(), "diagonal_wins": int(sum(wins)),
                                         "of": n, "wins_per_footage": dict(zip(fabrics, wins))})
    print(f"validate_cloth: diagonal wins {sum(wins)}/{n}", flush=True)


main = stage_app("validate_cloth", run)

if __name__ == "__main__":
    main()
