"""One line per results folder of the cloth study: the validation and skirt matrices' counts (own
fabric's parameters best in a column, and which columns are lost) and each twin's held-out ratio
and bend/shear errors, read from the stages' outputs (nothing is recomputed); also the joint fits'
twin scores where ``cloth/twin_joint/<twin>/score.yaml`` exists (stage ``score_cloth_twin_joint``
for twins listed in ``cloth.compare``, or ``cloth_twin_score`` run by hand on a ``fit_joint`` folder).

Used to compare annealing seeds (docs/cloth_study.md, "Annealing seeds 1-4 with the fix" and
"Joint fits against selection on the twins")::

    python benchmarks/cloth_seed_summary.py results results_s1 results_s2
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import yaml


def matrix_line(path: Path) -> str:
    """``k/n`` columns whose own row is lowest, and the lost columns with the winning row."""
    rows = list(csv.reader(path.open()))
    cols = rows[0][1:]
    M = {r[0]: [float(x) for x in r[1:]] for r in rows[1:]}
    lost = []
    for j, c in enumerate(cols):
        best = min(M, key=lambda r: M[r][j])
        if best != c:
            lost.append(f"{c} -> {best} ({M[best][j]:.1f} < {M[c][j]:.1f})" if c in M else f"{c} -> {best}")
    return f"{len(cols) - len(lost)}/{len(cols)}" + (f" lost: {'; '.join(lost)}" if lost else "")


def twin_line(path: Path) -> str:
    d = yaml.safe_load(path.read_text())
    p = d["parameters"]

    def err(n: str) -> str:
        # determined: True/False from the profile, None when scored without one (a joint fit)
        return f"{p[n]['relative_error']:.2f}" + (" (not determined)" if p[n].get("determined") is False else "")

    return f"ratio {d['heldout']['ratio']:.2f}, bend {err('bend')}, shear {err('shear')}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="+", help="results folders (each with cloth/validate, cloth/skirt, cloth/twin)")
    for r in ap.parse_args().results:
        parts = [r]
        for name in ("validate", "skirt"):
            f = Path(r) / "cloth" / name / "matrix.csv"
            parts.append(f"{name} {matrix_line(f)}" if f.is_file() else f"{name} -")
        for f in sorted((Path(r) / "cloth" / "twin").glob("*/score.yaml")):
            parts.append(f"{f.parent.name}: {twin_line(f)}")
        for f in sorted((Path(r) / "cloth" / "twin_joint").glob("*/score.yaml")):
            parts.append(f"{f.parent.name} joint: {twin_line(f)}")
        print(" | ".join(parts))


if __name__ == "__main__":
    main()
