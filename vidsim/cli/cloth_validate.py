"""Stage ``validate_cloth``: the fabric validation matrix (seed Figure 8) and Table 1.

Every fabric's selected parameters (``params.yaml`` of ``select_cloth``, its own density included)
are simulated on every fabric's *held-out* footage (the robot motion, never used for fitting) and
scored with the same metric: ``matrix.csv`` / ``matrix.png`` (rows: parameters, columns: footage; the diagonal should
win each column). ``table1.csv`` / ``table1.png`` collect per fabric the grid start, each trial's
optimum and the selected set with E1, E2 and the cross errors (from ``select_cloth``'s table).

Every cell is logged as it is scored, in ``.validate_cloth.checkpoint/column<j>.jsonl`` in the
output folder (:class:`vidsim.cli.cloth_common.LoggedScores`, as ``skirt_cloth``): a killed run,
run again, replays the cells already scored and simulates only the rest; a changed setting or
footage does not replay them. The folder is removed once ``validation.yaml`` is written.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import (
    ClothStageError,
    diagonal_wins,
    fabric_matrix,
    fabric_sets,
    matrix_csv,
    matrix_figure,
    read_selected,
)
from vidsim.cloth import ESTIMATED_NAMES
from vidsim.io.atomic import write_text, write_yaml
from vidsim.report.figures import save_figure


def run(cfg: DictConfig) -> None:
    out = Path(cfg.paths.out)
    fabrics, pfiles, footage, sets = fabric_sets(cfg.cloth.validate, "cloth.validate")
    sel = read_selected(pfiles)
    for f, s_ in zip(pfiles, sel):  # checked before the matrix's simulations, not after them
        if not isinstance(s_.get("trials"), list):
            raise ClothStageError(f"{f}: field 'trials' is missing (not a select_cloth output)")
    ckpt = out / ".validate_cloth.checkpoint"  # the cells' logs; removed once validation.yaml is written
    if ckpt.is_dir():
        print(f"validate_cloth: resuming from {ckpt} (cells already scored are replayed, not simulated)", flush=True)
    E, _ = fabric_matrix(footage, sets, cfg, fabrics, "validate_cloth", checkpoint=ckpt)
    n = len(fabrics)
    wins = diagonal_wins(E)
    write_text(out / "matrix.csv", matrix_csv(E, fabrics))
    matrix_figure(E, fabrics, "held-out footage (robot motion)", out / "matrix.png")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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
    # the estimated parameters: those that differ between the table's rows (the fixed ones are equal)
    shown = [k for k in ESTIMATED_NAMES if len({float(p[k]) for _, _, p, _, _ in rows}) > 1] or list(ESTIMATED_NAMES)
    hdr = "fabric,set," + ",".join(shown) + "," + ",".join(f"E_{t}" for t in trials) + ",E_sum\n"
    lines = [f"{fab},{name}," + ",".join(f"{float(p[k]):.4g}" for k in shown) + "," +
             ",".join(f"{errs[t]:.4g}" if t in errs else "" for t in trials) + "," + (f"{tot:.4g}" if tot is not None else "") + "\n"
             for fab, name, p, errs, tot in rows]
    write_text(out / "table1.csv", hdr + "".join(lines))
    fig, ax = plt.subplots(figsize=(7 + 1.1 * len(shown), 0.3 * len(rows) + 0.9))
    ax.axis("off")
    if rows:
        cells = [[fab, name] + [f"{float(p[k]):.3g}" for k in shown] + [f"{errs[t]:.3g}" if t in errs else "" for t in trials]
                 + [f"{tot:.3g}" if tot is not None else ""] for fab, name, p, errs, tot in rows]
        tb = ax.table(cellText=cells, colLabels=["fabric", "set", *shown, *[f"E {t}" for t in trials], "E sum"], loc="center",
                      cellLoc="center")
        tb.auto_set_font_size(False)
        tb.set_fontsize(7)
        tb.scale(1, 1.2)
        ax.set_title("Table 1 (* = selected: least E sum over the trials)", fontsize=9)
    else:  # params files without candidate rows (made by hand): said, not a crash in matplotlib's table
        ax.text(0.5, 0.5, "Table 1: the params files list no candidates (no select_cloth rows)", ha="center")
    save_figure(fig, out / "table1.png")
    write_yaml(out / "validation.yaml", {"fabrics": fabrics, "matrix": E.tolist(), "diagonal_wins": int(sum(wins)),
                                         "of": n, "wins_per_footage": dict(zip(fabrics, wins))})
    shutil.rmtree(ckpt, ignore_errors=True)
    print(f"validate_cloth: diagonal wins {sum(wins)}/{n}", flush=True)


main = stage_app("validate_cloth", run)

if __name__ == "__main__":
    main()
