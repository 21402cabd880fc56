#!/usr/bin/env bash
# Command 1 of the README: install what is needed, run the default (quick) pipeline, build the report.
# Extra arguments go to snakemake, e.g. `bash scripts/run_pipeline.sh --configfile workflow/config/full.yaml`.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/setup.sh"
cd "$ROOT"
snakemake --profile workflow/profiles/default "$@"
snakemake --profile workflow/profiles/default "$@" --report results/report.html
echo "[vidsim] done. Report: $ROOT/results/report.html   Recordings: rerun --web-viewer $ROOT/results/<stage>/*.rrd (headless; plain rerun with a display)"
