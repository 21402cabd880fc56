#!/usr/bin/env bash
# Install everything vidsim needs on a fresh Debian machine (idempotent, fast when done before):
#   1. the Debian packages headless pyrender needs (EGL + Mesa llvmpipe), installed with apt when missing;
#   2. a project virtual environment .venv with the package and its test extras (from pyproject.toml).
# Sourced by scripts/run_pipeline.sh and scripts/run_tests.sh; can be run on its own.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

say() { printf '[setup] %s\n' "$*" >&2; }

as_root() {
  if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null 2>&1; then sudo "$@"; else
    say "need root (or sudo) to run: $*"; exit 1; fi
}

apt_updated=0
apt_install() {
  [ "$#" -eq 0 ] && return 0
  if ! command -v apt-get >/dev/null 2>&1; then
    say "missing system packages ($*) and no apt-get: install their equivalents by hand"; exit 1
  fi
  if [ "$apt_updated" = 0 ]; then as_root apt-get update -qq; apt_updated=1; fi
  say "installing Debian packages: $*"
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null
}

# 1. system packages: EGL + Mesa (software OpenGL) for pyrender without a display. Skipped with
# VIDSIM_SKIP_APT=1 (a machine without root, e.g. a cluster login node: install the libraries by
# hand or through modules); a package counts as present when dpkg knows it under its name or its
# 64-bit-time name (Debian 13 / Ubuntu 24.04 renamed libglib2.0-0 to libglib2.0-0t64)
SYS_PKGS=(libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libgles2 libglib2.0-0)
missing=()
if [ "${VIDSIM_SKIP_APT:-0}" != 1 ] && command -v dpkg >/dev/null 2>&1; then
  for p in "${SYS_PKGS[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || dpkg -s "${p}t64" >/dev/null 2>&1 || missing+=("$p")
  done
fi
apt_install "${missing[@]}"

# 2. Python >= 3.11 and a virtual environment
PY="${PYTHON:-python3}"
if ! "$PY" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' 2>/dev/null; then
  say "need Python >= 3.11 (found: $("$PY" --version 2>&1 || echo none)); set PYTHON=/path/to/python3.11"; exit 1
fi
if [ -x .venv/bin/python ] && ! .venv/bin/python -m pip --version >/dev/null 2>&1; then
  # an interrupted first set-up leaves a .venv without pip: put pip in (never delete a .venv)
  say "the .venv has no working pip (an interrupted first set-up?): installing pip into it"
  if ! .venv/bin/python -m ensurepip --upgrade >/dev/null 2>&1; then
    say "could not install pip into .venv: remove the .venv folder and run this again"; exit 1
  fi
fi
if [ ! -x .venv/bin/python ]; then
  say "creating .venv with $("$PY" --version)"
  if ! "$PY" -m venv .venv 2>/dev/null; then
    rm -rf .venv
    if [ "${VIDSIM_SKIP_APT:-0}" = 1 ]; then
      say "$PY cannot make a virtual environment (no ensurepip): install python3-venv, or set PYTHON to a Python that can"; exit 1
    fi
    apt_install python3-venv
    "$PY" -m venv .venv
  fi
fi

stamp=.venv/.vidsim-install-stamp
want="$(cat pyproject.toml constraints.txt | sha256sum | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  say "installing Python packages into .venv (first time: a few minutes)"
  .venv/bin/python -m pip install -q --upgrade pip
  # constraints.txt pins every package to the versions the tests and figures were made with
  .venv/bin/python -m pip install -q -c constraints.txt -e ".[test]"
  echo "$want" > "$stamp"
fi

export PATH="$ROOT/.venv/bin:$PATH"
export PYOPENGL_PLATFORM=egl
say "ready: $(python --version), snakemake $(snakemake --version)"
