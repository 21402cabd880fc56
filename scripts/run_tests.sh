#!/usr/bin/env bash
# Command 2 of the README: install what is needed and run the test suite (CI runs exactly this).
# Extra arguments go to pytest, e.g. `bash scripts/run_tests.sh -k calibration`.
# The suite runs on every core (pytest-xdist, one test file per worker at a time, so a file's
# module fixtures are built once); VIDSIM_TEST_WORKERS=1 runs it in one process (no xdist).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/setup.sh"
cd "$ROOT"
export NUMBA_NUM_THREADS="${NUMBA_NUM_THREADS:-1}"
workers="${VIDSIM_TEST_WORKERS:-$(nproc 2>/dev/null || echo 1)}"
if ! [[ "$workers" =~ ^[0-9]+$ ]] || [ "$workers" -lt 1 ]; then
  echo "[tests] VIDSIM_TEST_WORKERS must be a whole number >= 1, got '$workers'" >&2; exit 2
fi
if [ "$workers" -gt 1 ]; then
  python -m pytest -q --durations=15 -n "$workers" --dist loadfile "$@"
else
  python -m pytest -q --durations=15 "$@"
fi
