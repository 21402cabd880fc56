"""The Snakemake DAG: lint-clean, the default target plans, and a config change reruns only its jobs."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from vidsim.io.paths import REPO_ROOT

SNAKEMAKE = [sys.executable, "-m", "snakemake"]


def _env() -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    return env


def _smk(*args: str, cwd: Path = REPO_ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([*SNAKEMAKE, *args], cwd=cwd, capture_output=True, text=True, env=_env(), timeout=600)


def test_lint_is_clean():
    r = _smk("--lint", "--profile", "workflow/profiles/default")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "Congratulations" in r.stdout + r.stderr


def test_default_target_dry_run(tmp_path):
    r = _smk("-n", "--profile", "workflow/profiles/default", "--config", f"results={tmp_path}/results")
    assert r.returncode == 0, r.stdout + r.stderr
    out = r.stdout + r.stderr
    for rule in ("calibrate_chessboard", "calibrate_scene", "reality_demo"):
        assert rule in out
