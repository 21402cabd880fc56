"""Stage ``validate_cloth``: the fabric validation matrix (seed Figure 8) and Table 1.

Every fabric's selected parameters (``params.yaml`` of ``select_cloth``, its own density included)
are simulated on every fabric's *held-out* footage (the robot motion, never used for fitting) and
scored with the same metric: ``matrix.csv`` / ``matrix.png`` (rows: parameters, columns: footage; the diagonal should
win each column). ``table1.csv`` / ``table1.png`` collect per fabric the grid start, each trial's
optimum and the selected set with E1, E2 and the cross errors (from ``select_cloth``'s table).

Is a column decided? A single run's error on a chaotic motion is one draw of what parameters
within 1e-4 of each other score (docs/cloth_study.md, "Session 43"). Every set is therefore also
scored as ``cloth.validate.chaos_draws`` moved copies (each of the nine parameters scaled by the
fixed draws of exp(N(0, ``chaos_sigma``)) of ``cloth.model.chaos_members``, the same draws for every
set), and per column the own set's copies are compared with every other set's, copy by copy
(:func:`vidsim.cli.cloth_common.paired_margins`, the skirt matrix's test): ``won`` (significantly
better than every other set), ``lost`` (some other set significantly better, the cut corrected for the
number of sets; or its own set failed to simulate) or ``undecided``; a set that fails is left out
of a column's tests (``failed`` names it).
``matrix.csv`` and ``diagonal_wins`` stay the sets' own (unmoved) errors, the seed's Figure 8
(with ``cloth.model.chaos_members`` > 0, the fits' own chaos-averaged loss, that average);
``matrix_copies.csv`` holds the copies' means, on which the verdicts rest. What "decided" covers:
the model's chaos at the sets, nothing else. Where neither set is chaotic the copies agree to
within a tiny standard error and any margin is decided; footage noise, the annealing seed and
the fits' own spread are not in the test (they are measured over seeds: docs/cloth_study.md).

Every cell is logged as it is scored, in ``.validate_cloth.checkpoint/column<j>.jsonl`` (the copies in
``copies/column<j>.jsonl`` there) in the output folder (:class:`vidsim.cli.cloth_common.LoggedScores`, as ``skirt_cloth``): a killed run,
run again, replays the cells already scored and simulates only the rest; a changed setting or
footage does not replay them. The folder is removed once ``validation.yaml`` is written.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import (
    ClothStageError,
    chaos_copies,
    diagonal_wins,
    fabric_matrix,
    fabric_sets,
    matrix_csv,
    matrix_figure,
    paired_margins,
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
    vc = cfg.cloth.validate
    draws, sigma = chaos_copies(vc, "cloth.validate")
    ckpt = out / ".validate_cloth.checkpoint"  # the cells' logs; removed once validation.yaml is written
    if ckpt.is_dir():
        print(f"validate_cloth: resuming from {ckpt} (cells already scored are replayed, not simulated)", flush=True)
    E, _ = fabric_matrix(footage, sets, cfg, fabrics, "validate_cloth", checkpoint=ckpt)
    n = len(fabrics)
    wins = diagonal_wins(E)
    verdicts, tally, Ec = {}, None, None
    if draws:
        ccfg = OmegaConf.merge(cfg, {"cloth": {"model": {"chaos_members": int(draws), "chaos_sigma": float(sigma)}}})
        cells: list = []
        Ec, _ = fabric_matrix(footage, sets, ccfg, fabrics, f"validate_cloth copies ({int(draws)} per set)",
                              members=cells, checkpoint=ckpt / "copies")
        for j, m in paired_margins(Ec, cells).items():
            verdicts[fabrics[j]] = {"verdict": m["verdict"], "rival": fabrics[m["rival"]], "margin": m["margin"],
                                    "se": m["se"], "copies": m["members"], "cut": m["cut"], "cut_lost": m["cut_lost"],
                                    "failed": [fabrics[i] for i in m["failed"]]}
        tally = {k: sum(v["verdict"] == k for v in verdicts.values()) for k in ("won", "lost", "undecided")}
        write_text(out / "matrix_copies.csv", matrix_csv(Ec, fabrics))
    else:  # no copies: a previous run's copies matrix in this folder no longer belongs to these verdicts
        (out / "matrix_copies.csv").unlink(missing_ok=True)
    note = (f"over {int(draws)} copies moved by {sigma:g} (paired t, 2.5 % one-sided; a loss against any other set, Bonferroni): won {tally['won']}, "
            f"lost {tally['lost']}, undecided {tally['undecided']}") if tally else ""
    write_text(out / "matrix.csv", matrix_csv(E, fabrics))
    matrix_figure(E, fabrics, "held-out footage (robot motion)", out / "matrix.png", note)
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
    doc = {"fabrics": fabrics, "matrix": E.tolist(), "diagonal_wins": int(sum(wins)), "of": n,
           "wins_per_footage": dict(zip(fabrics, wins)),
           "copies": {"draws": int(draws), "sigma": float(sigma),
                      "matrix_mean": None if Ec is None else Ec.tolist(),
                      "diagonal_wins_mean": None if Ec is None else int(sum(diagonal_wins(Ec)))},
           "verdicts": verdicts, "decided": tally}
    write_yaml(out / "validation.yaml", doc)
    shutil.rmtree(ckpt, ignore_errors=True)
    print(f"validate_cloth: diagonal wins {sum(wins)}/{n}" + (f"; {note}" if note else ""), flush=True)


main = stage_app("validate_cloth", run)

if __name__ == "__main__":
    main()
