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


PROBE = '''
import sys
from vidsim.cli._app import stage_app
from vidsim.video.camera import CameraError


def run(cfg):
    if int(cfg.seed) == 1:
        raise CameraError("probe: field 'K' is singular")  # a vidsim ValueError, not a VidsimError
    print("probe ran", cfg.seed)


main = stage_app("probe", run)
main()
'''


def _probe(tmp: Path, *args: str) -> subprocess.CompletedProcess:
    f = tmp / "probe_stage.py"
    f.write_text(PROBE)
    return subprocess.run([sys.executable, str(f), *args, f"paths.results={tmp / 'results'}", "log.rerun=false"],
                          cwd=REPO_ROOT, capture_output=True, text=True, env=_env(), timeout=300)


def test_sweep_points_failing_with_any_project_error_are_marked_not_tracebacks(tmp_path):
    """A project ValueError that is not a VidsimError (CameraError, FeatureError, ...) failed a sweep
    point with a traceback and exit 1, and the sweep's summary line never came (review, 5 Dec 2026)."""
    r = _probe(tmp_path, "-m", "seed=0,1,2")
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    assert "Traceback" not in r.stderr and "field 'K' is singular" in r.stderr
    assert "1 sweep point(s) failed" in r.stderr and r.stdout.count("probe ran") == 2
    failed = tmp_path / "results" / "sweeps" / "probe" / "failed.csv"
    assert len(list(csv.DictReader(failed.open()))) == 1
    # the same sweep again: failed.csv is this sweep's, not the two sweeps' rows
    r = _probe(tmp_path, "-m", "seed=0,1,2")
    assert r.returncode == 2 and len(list(csv.DictReader(failed.open()))) == 1


def test_sweep_overrides_are_checked_like_single_runs(tmp_path):
    """'+' keys under a schema node were not checked in sweeps (the points ran, the key ignored)."""
    r = _probe(tmp_path, "-m", "+rigid.fit.max_iter=5", "seed=0,2")
    assert r.returncode == 2 and "rigid.fit.max_iter (added with '+') is unknown" in r.stderr, r.stderr[-2000:]
    assert "probe ran" not in r.stdout
    r = _probe(tmp_path, "-m", "camera.focal=3", "seed=0,2")
    assert r.returncode == 2 and "Traceback" not in r.stderr and "camera.focal" in r.stderr, r.stderr[-2000:]
    # the swept overrides themselves: a '+' key, an unknown key, a wrong type in any value stop the
    # sweep with one line before any point runs (the '+' key was ignored; the others were Hydra's
    # multi-line report, after the points before the bad value had run)
    for swept, words in (("+rigid.fit.max_iter=4,5", "rigid.fit.max_iter (added with '+') is unknown"),
                         ("rigid.fit.max_iterz=4,5", "max_iterz"),
                         ("seed=0,abc", "seed")):
        r = _probe(tmp_path, "-m", swept)
        assert r.returncode == 2 and "Traceback" not in r.stderr and words in r.stderr, r.stderr[-2000:]
        assert len(r.stderr.strip().splitlines()) == 1 and "probe ran" not in r.stdout, r.stderr[-2000:]


def test_an_unknown_group_option_lists_the_groups_options(tmp_path):
    r = _probe(tmp_path, "camera=nonexist", "seed=0")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr[-2000:]
    assert "Could not find 'camera/nonexist'" in r.stderr and "Available options in 'camera': " in r.stderr
    assert "cloth" in r.stderr and "search path" not in r.stderr


def test_help_says_what_the_stage_does_and_cfg_job_prints_the_settings(tmp_path):
    """--help printed Hydra's generic text and an 800-line config dump; --cfg job failed in the
    override check ('Error parsing override job')."""
    r = _probe(tmp_path, "--help")
    assert r.returncode == 0 and "Usage: python -m vidsim.cli.probe paths.out=" in r.stdout, r.stderr[-2000:]
    assert len(r.stdout.splitlines()) < 30
    r = _probe(tmp_path, "--cfg", "job", f"paths.out={tmp_path / 'results' / 'p'}", "seed=3")
    assert r.returncode == 0 and "seed: 3" in r.stdout and "probe ran" not in r.stdout, r.stderr[-2000:]


def test_a_clean_sweep_removes_the_last_sweeps_failed_csv(tmp_path):
    r = _probe(tmp_path, "-m", "seed=0,1")
    failed = tmp_path / "results" / "sweeps" / "probe" / "failed.csv"
    assert r.returncode == 2 and failed.is_file()
    r = _probe(tmp_path, "-m", "seed=0,2")
    assert r.returncode == 0 and not failed.exists(), r.stderr[-2000:]


def test_output_folder_must_lie_inside_results_and_be_given(tmp_path):
    """paths.out equal to the results folder would let a stage replace the whole results tree."""
    res = tmp_path / "results"
    r = _probe(tmp_path, f"paths.out={res}", "seed=0")
    assert r.returncode == 2 and "is the results folder itself" in r.stderr, r.stderr[-2000:]
    res.mkdir(parents=True, exist_ok=True)
    (res / "afile").write_text("x")  # a file where the output folder, or a parent of it, must go
    for out in (res / "afile", res / "afile" / "sub"):
        r = _probe(tmp_path, f"paths.out={out}", "seed=0")
        assert r.returncode == 2 and "is an existing file, not a folder" in r.stderr, r.stderr[-2000:]
        assert "probe ran" not in r.stdout
    r = _probe(tmp_path, "seed=0")  # no paths.out at all
    assert r.returncode == 2 and "Traceback" not in r.stderr and "paths.out is required" in r.stderr, r.stderr[-2000:]
