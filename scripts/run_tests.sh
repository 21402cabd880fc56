#!/usr/bin/env bash
# Command 2 of the README: install what is needed and run the test suite (CI runs exactly this).
# Extra arguments go to pytest, e.g. `bash scripts/run_tests.sh -k calibration`.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/setup.sh"
cd "$ROOT"
export NUMBA_NUM_THREADS="${NUMBA_NUM_THREADS:-1}"
python -m pytest -q --durations=15 "$@"
