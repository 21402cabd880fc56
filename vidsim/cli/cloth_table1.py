"""Stage ``table1_cloth``: the seed's Table 1 with an interval per parameter (issue 6).

Per fabric, the selected parameters of ``select_cloth`` (the cross-trial E1+E2 choice) beside the
posterior of ``posterior_cloth``: the median and the central 90 % interval (5 % and 95 %
quantiles) of every estimated parameter; parameters the fits held fixed are marked ``fixed``.

``python -m vidsim.cli.cloth_table1 paths.out=results/posterior/cloth/table1 cloth.table1.fabrics=[linen,satin]
cloth.table1.params=[<params.yaml>,...] cloth.table1.summaries=[<summary.csv>,...]``

Outputs: ``table1_intervals.csv`` (one row per fabric and parameter: selected value, median, q05,
q95, whether the selected value lies inside its interval, and the interval's width: q95/q05 for
positive parameters spanning more than a factor 1.5, else the half-width +-(q95 - q05)/2), ``table1_intervals.png``.
"""

from __future__ import annotations

import csv
from pathlib import Path

from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli.cloth_common import ClothStageError, read_selected
from vidsim.cloth import ESTIMATED_NAMES, PARAM_UNITS
from vidsim.io.atomic import write_text
from vidsim.report.figures import save_figure

SUMMARY_FIELDS = ("name", "point", "q05", "median", "q95")


def read_summary(path: str) -> dict[str, dict[str, float]]:
    """``{parameter: {point, q05, median, q95}}`` of a posterior ``summary.csv`` (names a missing file or field)."""
    p = Path(path)
    if not p.is_file():
        raise ClothStageError(f"{path}: posterior summary.csv is missing")
    with p.open() as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise ClothStageError(f"{path}: posterior summary.csv has no parameter rows")
    missing = [f for f in SUMMARY_FIELDS if f not in rows[0]]
    if missing:
        raise ClothStageError(f"{path}: summary.csv lacks the field(s) {missing}")
    out = {}
    for r in rows:
        try:
            out[r["name"]] = {k: float(r[k]) for k in SUMMARY_FIELDS[1:]}
        except ValueError:
            raise ClothStageError(f"{path}: parameter {r['name']!r} has a non-numeric quantile") from None
    return out


def _width(q05: float, q95: float) -> str:
    if q05 > 0 and q95 / q05 > 1.5:
        return f"x{q95 / q05:.3g}"
    return f"+-{(q95 - q05) / 2:.3g}"


def run(cfg: DictConfig) -> None:
    out = Path(cfg.paths.out)
    tc = cfg.cloth.table1
    fabrics, pfiles, sfiles = list(tc.fabrics), list(tc.params), list(tc.summaries)
    if not fabrics or not (len(fabrics) == len(pfiles) == len(sfiles)):
        raise ClothStageError(f"cloth.table1: fabrics ({len(fabrics)}), params ({len(pfiles)}) and summaries "
                              f"({len(sfiles)}) must be non-empty lists of one length")
    sel = read_selected(pfiles)
    post = [read_summary(s) for s in sfiles]
    lines = ["fabric,parameter,unit,selected,median,q05,q95,selected_inside,width\n"]
    cells = []
    for fab, s, q in zip(fabrics, sel, post):
        row = [fab]
        for n in ESTIMATED_NAMES:
            v = float(s["params"][n])
            if n in q:
                e = q[n]
                inside = e["q05"] <= v <= e["q95"]
                lines.append(f"{fab},{n},{PARAM_UNITS[n]},{v:.5g},{e['median']:.5g},{e['q05']:.5g},{e['q95']:.5g},"
                             f"{str(inside).lower()},{_width(e['q05'], e['q95'])}\n")
                row.append(f"{v:.3g}\n[{e['q05']:.2g}, {e['q95']:.2g}]")
            else:
                lines.append(f"{fab},{n},{PARAM_UNITS[n]},{v:.5g},,,,,fixed\n")
                row.append(f"{v:.3g}\n(fixed)")
        cells.append(row)
    write_text(out / "table1_intervals.csv", "".join(lines))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(1.35 * len(ESTIMATED_NAMES) + 1.5, 0.75 * len(fabrics) + 1.0))
    ax.axis("off")
    tb = ax.table(cellText=cells, colLabels=["fabric", *[f"{n}\n({PARAM_UNITS[n]})" for n in ESTIMATED_NAMES]],
                  loc="center", cellLoc="center")
    tb.auto_set_font_size(False)
    tb.set_fontsize(6.5)
    tb.scale(1, 2.6)
    ax.set_title("Table 1: selected parameters and their 90 % posterior intervals", fontsize=9)
    save_figure(fig, out / "table1_intervals.png")
    inside = sum(ln.split(",")[7] == "true" for ln in lines[1:])
    est = sum(ln.rstrip().split(",")[-1] != "fixed" for ln in lines[1:])
    print(f"table1_cloth: {len(fabrics)} fabrics; the selected value lies inside its own 90 % interval for "
          f"{inside}/{est} estimated parameters", flush=True)


main = stage_app("table1_cloth", run)

if __name__ == "__main__":
    main()
