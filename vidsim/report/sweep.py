"""Collect the points of a Snakemake ``Paramspace`` sweep into one table and one plot.

``python -m vidsim.report.sweep --table T.tsv --points <dir>... --out <dir> --x <column>
[--group <column>] --quantities q1 q2``: each point folder holds the ``summary.csv`` of a stage
(``quantity,estimated,true,difference``); the point's parameter values are parsed from its folder
name (the workflow's Paramspace pattern ``key-value_key-value``). Writes ``sweep.csv`` (one row per point: the
parameters, then each quantity's estimate and its difference from the truth) and ``sweep.png``.
"""

from __future__ import annotations

import argparse
import csv
import io
from pathlib import Path

from vidsim.errors import VidsimError
from vidsim.io.atomic import write_text


def parse_point(name: str, columns: list[str]) -> dict[str, str]:
    """Values of ``columns`` from a Paramspace folder name ``c1-v1_c2-v2`` (``param_sep="-"``)."""
    out: dict[str, str] = {}
    rest = name
    for i, c in enumerate(columns):
        prefix = f"{c}-"
        if not rest.startswith(prefix):
            raise VidsimError(f"sweep point folder '{name}': expected '{prefix}...' (Paramspace pattern of {columns})")
        rest = rest[len(prefix):]
        if i + 1 < len(columns):
            nxt = f"_{columns[i + 1]}-"
            j = rest.find(nxt)
            if j < 0:
                raise VidsimError(f"sweep point folder '{name}': column '{columns[i + 1]}' not found")
            out[c], rest = rest[:j], rest[j + 1:]
        else:
            out[c] = rest
    return out


def read_summary(path: Path) -> dict[str, tuple[str, str]]:
    if not path.is_file():
        raise VidsimError(f"{path}: missing (the sweep point's stage did not write its summary.csv)")
    rows = list(csv.DictReader(io.StringIO(path.read_text())))
    if not rows or "quantity" not in rows[0]:
        raise VidsimError(f"{path}: expected a CSV with columns quantity,estimated,true,difference")
    return {r["quantity"]: (r.get("estimated", ""), r.get("difference", "")) for r in rows}


def _is_number(v) -> bool:
    try:
        float(v)
    except (TypeError, ValueError):
        return False
    return True


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--table", required=True)
    ap.add_argument("--points", nargs="+", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--x", required=True)
    ap.add_argument("--group", default=None)
    ap.add_argument("--quantities", nargs="+", required=True)
    a = ap.parse_args(argv)
    table = Path(a.table)
    if not table.is_file():
        raise SystemExit(f"vidsim sweep: error: {table}: the sweep table is missing")
    lines = table.read_text().splitlines()
    if not lines:
        raise SystemExit(f"vidsim sweep: error: {table}: empty (expected a tab-separated header and one row per point)")
    columns = lines[0].split("\t")
    for c in [a.x] + ([a.group] if a.group else []):
        if c not in columns:
            raise SystemExit(f"vidsim sweep: error: column '{c}' not in {a.table} (columns: {columns})")
    rows = []
    for p in a.points:
        p = Path(p)
        point = parse_point(p.name, columns)
        try:
            summ = read_summary(p / "summary.csv")
        except VidsimError as e:
            raise SystemExit(f"vidsim sweep: error: {e}") from None
        row = dict(point)
        for q in a.quantities:
            if q not in summ:
                raise SystemExit(f"vidsim sweep: error: quantity '{q}' not in {p / 'summary.csv'}")
            row[q], row[f"{q}_difference"] = summ[q]
        rows.append(row)
    out = Path(a.out)
    for c in [a.x] + ([a.group] if a.group else []):
        bad = [r[c] for r in rows if not _is_number(r[c])]
        if bad:
            raise SystemExit(f"vidsim sweep: error: column '{c}' must hold numbers to plot against, got {bad[:3]}")
    header = list(rows[0])
    write_text(out / "sweep.csv", "\n".join([",".join(header)] + [",".join(str(r[h]) for h in header) for r in rows]) + "\n")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from vidsim.report.figures import save_figure

    fig, axes = plt.subplots(1, len(a.quantities), figsize=(4.2 * len(a.quantities), 3.4), squeeze=False)
    groups = sorted({r[a.group] for r in rows}, key=float) if a.group else [None]
    for ax, q in zip(axes[0], a.quantities):
        for g in groups:
            sel = sorted((r for r in rows if g is None or r[a.group] == g), key=lambda r: float(r[a.x]))
            ys = [abs(float(r[f"{q}_difference"])) if r[f"{q}_difference"] else float(r[q]) for r in sel]
            ax.plot([float(r[a.x]) for r in sel], ys, "o-", label=f"{a.group}={g}" if g is not None else None)
        ax.set_xlabel(a.x)
        ax.set_ylabel(f"|{q} error|" if rows[0][f"{q}_difference"] else q)
        ax.grid(alpha=0.3)
        if a.group:
            ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, out / "sweep.png")


if __name__ == "__main__":
    try:
        main()
    except VidsimError as e:
        raise SystemExit(f"vidsim sweep: error: {e}")
