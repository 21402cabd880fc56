"""Stage ``fluid_metrics``: the fluid family's measured figures in one table for the report.

``python -m vidsim.cli.fluid_metrics 'fluid.inputs=[results/fluid/middlebury/summary.json,...]'
paths.out=results/fluid/metrics``. Reads the ``summary.json`` of ``fluid_middlebury``,
``fluid_flow`` and ``fluid_edit`` stages and writes ``metrics.csv`` (item, quantity, value,
target, met).
"""

from __future__ import annotations

import json
from pathlib import Path

from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.errors import ConfigError, FootageError
from vidsim.fluid.report import metrics_rows, rows_to_csv
from vidsim.io.atomic import write_text


def run(cfg: DictConfig) -> None:
    if not cfg.fluid.inputs:
        raise ConfigError("fluid.inputs is empty: give the summary.json files to collect")
    sums = []
    for p in cfg.fluid.inputs:
        p = Path(p)
        if not p.is_file():
            raise FootageError(f"fluid.inputs: {p}: summary file is missing")
        try:
            sums.append(json.loads(p.read_text()))
        except json.JSONDecodeError as e:
            raise FootageError(f"{p}: not valid JSON ({e})") from None
    try:
        rows = metrics_rows(sums)
    except (KeyError, ValueError) as e:
        raise ConfigError(f"fluid.inputs: {e}") from None
    out = Path(cfg.paths.out)
    write_text(out / "metrics.csv", rows_to_csv(rows))
    missed = [f"{r['item']} {r['quantity']}" for r in rows if r["met"] == "NO"]
    print(f"fluid_metrics: {len(rows)} figures, {len(missed)} below target" + (f": {missed}" if missed else ""), flush=True)


main = stage_app("fluid_metrics", run)

if __name__ == "__main__":
    main()
