"""Sweeps: a Hydra multirun lands one folder per point; the Paramspace study plans one job per row."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import pytest

from vidsim.errors import VidsimError
from vidsim.io.paths import REPO_ROOT
from vidsim.report.sweep import parse_point


def _env() -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    return env


def _calibrate_sweep(res: Path, sigmas: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "vidsim.cli.calibrate", "-m", f"calibrate.noise_sigma={sigmas}", "calibrate.n_views=4",
         f"paths.results={res}", "log.rerun=false"],
        cwd=REPO_ROOT, capture_output=True, text=True, env=_env(), timeout=300,
    )


def test_hydra_multirun_writes_each_point_to_its_own_folder(tmp_path):
    res = tmp_path / "results"
    r = _calibrate_sweep(res, "0.5,4")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    rms = {}
    for sigma in ("0.5", "4"):
        d = res / "sweeps" / "calibrate" / f"calibrate.n_views=4,calibrate.noise_sigma={sigma},log.rerun=False"
        rows = {row["quantity"]: row for row in csv.DictReader((d / "summary.csv").open())}
        rms[sigma] = float(rows["rms_px"]["estimated"])
    # more sensor noise, larger reprojection residual: the points really ran with their own values
    assert rms["4"] > 1.3 * rms["0.5"]


def test_a_failing_sweep_point_is_marked_and_the_sweep_goes_on(tmp_path):
    res = tmp_path / "results"
    r = _calibrate_sweep(res, "-1,0.5")
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    assert "Traceback" not in r.stderr
    assert "calibrate.noise_sigma = -1.0 is not valid" in r.stderr
    assert "1 sweep point(s) failed" in r.stderr
    sweep = res / "sweeps" / "calibrate"
    bad = sweep / "calibrate.n_views=4,calibrate.noise_sigma=-1,log.rerun=False"
    good = sweep / "calibrate.n_views=4,calibrate.noise_sigma=0.5,log.rerun=False"
    assert not bad.exists()  # the failed point (first in the sweep) left nothing behind
    assert (good / "summary.csv").exists()  # and the next point still ran
    rows = list(csv.DictReader((sweep / "failed.csv").open()))
    assert [row["point"] for row in rows] == [bad.name] and "noise_sigma" in rows[0]["error"]


def test_paramspace_plans_one_job_per_table_row(tmp_path):
    table = tmp_path / "t.tsv"
    table.write_text("calibrate__noise_sigma\tcalibrate__n_views\n1.0\t4\n3.0\t4\n3.0\t8\n")
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"results: {tmp_path}/results\nstages: {{calibration_chessboard: false, demo: false, "
                   f"sweep_calibration: true}}\nsweep_calibration: {{table: {table}}}\n")
    r = subprocess.run([sys.executable, "-m", "snakemake", "-n", "--profile", "workflow/profiles/default",
                        "--configfile", str(cfg)], cwd=REPO_ROOT, capture_output=True, text=True, env=_env(), timeout=300)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-3000:]
    assert "calibrate__noise_sigma-3.0_calibrate__n_views-8" in out
    jobs = [ln.split() for ln in out.splitlines() if ln.strip().startswith(("calibrate_sweep_point", "collect_calibration_sweep"))]
    counts = {j[0]: int(j[1]) for j in jobs if len(j) == 2 and j[1].isdigit()}
    assert counts == {"calibrate_sweep_point": 3, "collect_calibration_sweep": 1}, out[-3000:]


def test_sweep_point_names_parse_back_to_their_values():
    cols = ["calibrate__noise_sigma", "calibrate__n_views"]
    assert parse_point("calibrate__noise_sigma-0.5_calibrate__n_views-12", cols) == {
        "calibrate__noise_sigma": "0.5", "calibrate__n_views": "12"}
    with pytest.raises(VidsimError, match="calibrate__n_views"):
        parse_point("calibrate__noise_sigma-0.5", cols)
