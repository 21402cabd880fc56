"""The Snakemake DAG: lint-clean, the default target plans, and a config change reruns only its jobs."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from vidsim.io.paths import REPO_ROOT, shared_data_dir

SNAKEMAKE = [sys.executable, "-m", "snakemake"]
FAMILIES = ("calibration_chessboard", "demo", "sweep_calibration", "rigid", "cloth", "fluid", "posterior", "gap")


def only(*on: str) -> str:
    """A `stages:` mapping with only these families on (--configfile merges into quick.yaml key by key)."""
    return "{" + ", ".join(f"{f}: {'true' if f in on else 'false'}" for f in FAMILIES) + "}"



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
    real = shared_data_dir().is_dir()
    for rule in ("calibrate_scene", "reality_demo", "fit_cloth", "skirt_cloth", "fluid_edit", "fit_rigid") + (
            ("calibrate_chessboard", "rigid_ball", "fluid_middlebury") if real else ()):
        assert f"rule {rule}:" in out, rule


def test_dry_run_without_real_data_skips_only_their_stages(tmp_path):
    """A machine without ../shared/data still plans the synthetic study and says what it left out."""
    r = _smk("-n", "--profile", "workflow/profiles/default", "--config", f"results={tmp_path}/results",
             f"shared_data={tmp_path}/absent")
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-3000:]
    assert f"real data {tmp_path}/absent/opencv_chessboard is absent" in out
    assert "rule calibrate_chessboard:" not in out and "rule fluid_piv_footage:" not in out
    assert "rule fit_cloth:" in out and "rule fit_rigid:" in out


def _job_total(out: str) -> int:
    return int(next(line.split()[1] for line in out.splitlines() if line.startswith("total ")))


def test_slurm_profile_plans_the_same_jobs_as_the_local_one(tmp_path):
    """The SLURM profile (no cluster here, so a dry run only: the slurm executor plugin loads, the
    profile's keys are valid and its resources resolve) plans the same DAG as the local profile."""
    cfg = ("--config", f"results={tmp_path}/results")
    local = _smk("-n", "--profile", "workflow/profiles/default", *cfg)
    slurm = _smk("-n", "--profile", "workflow/profiles/slurm", *cfg)
    assert local.returncode == 0 and slurm.returncode == 0, slurm.stdout[-3000:] + slurm.stderr[-3000:]
    lo, sl = local.stdout + local.stderr, slurm.stdout + slurm.stderr
    assert _job_total(sl) == _job_total(lo) > 50
    assert _planned_jobs(sl) == _planned_jobs(lo)


@pytest.mark.slow
def test_cluster_generic_executor_runs_jobs_as_separate_processes(tmp_path, shared_data):
    """The cluster path on one machine: each job submitted through a submit script, run detached."""
    res = tmp_path / "results"
    logs = tmp_path / "cluster-logs"
    env = _env()
    env["VIDSIM_CLUSTER_LOGS"] = str(logs)
    cfg = tmp_path / "only_chessboard.yaml"
    cfg.write_text(f"results: {res}\nshared_data: {shared_data}\nstages: {only('calibration_chessboard')}\n")
    r = subprocess.run(
        [*SNAKEMAKE, "--profile", "workflow/profiles/cluster-local", "--configfile", str(cfg)],
        cwd=REPO_ROOT, capture_output=True, text=True, env=env, timeout=600,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    calib = res / "calibration" / "chessboard" / "calibration.yaml"
    assert calib.is_file()
    assert not (res / "footage").exists()  # only the requested stage ran
    # the job really went through the submit script: its job script's output is in the log folder
    outs = list(logs.glob("*.out"))
    assert outs, "no job was submitted through the submit script"
    import yaml

    K = yaml.safe_load(calib.read_text())["camera"]["K"]
    assert abs(K[0][0] - 535.9) < 1.0


def _planned_jobs(out: str) -> set[str]:
    """Rule names in the job-count table of a dry run."""
    jobs, in_table = set(), False
    for line in out.splitlines():
        if line.startswith("job ") and "count" in line:
            in_table = True
            continue
        if in_table:
            parts = line.split()
            if not parts or parts[0] == "total":
                break
            if parts[0].startswith("-"):
                continue
            jobs.add(parts[0])
    return jobs


@pytest.mark.slow
def test_changing_one_stage_config_reruns_only_its_dependents(tmp_path, shared_data):
    # the workflow and its Hydra configs copied, so that a conf/ file can be edited (the stages
    # themselves compose the package's conf/, unchanged)
    wf = tmp_path / "wf"
    wf.mkdir()
    for f in ("Snakefile", "env.yml"):
        shutil.copy(REPO_ROOT / f, wf)
    for d in ("workflow", "conf", "docs/fluid_edits"):  # the fluid rules read their edits at parse time
        shutil.copytree(REPO_ROOT / d, wf / d)
    res = tmp_path / "results"
    base = (f"results: {res}\nshared_data: {shared_data}\nhydra_overrides: 'log.rerun=false'\n"
            f"stages: {only('calibration_chessboard', 'demo')}\n")
    cfg = tmp_path / "a.yaml"
    cfg.write_text(base + "overrides: {calibrate_scene: '', reality_demo: ''}\n")
    r = _smk("--profile", "workflow/profiles/default", "--configfile", str(cfg), "--cores", "2", cwd=wf)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    # the README's command builds the report after the run: without a warning per job (with
    # Snakemake's default disk_mb, max(2 * input.size_mb, 1000), snakemake 9.27 printed an
    # un-awaited-coroutine RuntimeWarning per job here; the profiles now set disk_mb)
    r = _smk("--profile", "workflow/profiles/default", "--configfile", str(cfg), "--report",
             str(tmp_path / "report.html"), cwd=wf)
    assert r.returncode == 0 and (tmp_path / "report.html").stat().st_size > 0, r.stderr[-3000:]
    assert "Warning" not in r.stdout + r.stderr, (r.stdout + r.stderr)[-3000:]
    # nothing changed: nothing to do
    r = _smk("-n", "--profile", "workflow/profiles/default", "--configfile", str(cfg), cwd=wf)
    # (an empty job table alone would also pass for a dry run that failed: its code and message too)
    assert r.returncode == 0 and "Nothing to be done" in r.stdout + r.stderr, (r.stdout + r.stderr)[-3000:]
    assert _planned_jobs(r.stdout + r.stderr) == set(), r.stdout
    # one value of the footage stage changes: it (and `all`) rerun, the calibrations do not
    cfg.write_text(base + "overrides: {calibrate_scene: '', reality_demo: 'render.noise_sigma=4'}\n")
    r = _smk("-n", "--profile", "workflow/profiles/default", "--configfile", str(cfg), cwd=wf)
    assert _planned_jobs(r.stdout + r.stderr) == {"reality_demo", "all"}, r.stdout
    # the scene calibration changes: the footage made from it reruns too, the chessboard does not
    cfg.write_text(base + "overrides: {calibrate_scene: 'calibrate.n_views=8', reality_demo: ''}\n")
    r = _smk("-n", "--profile", "workflow/profiles/default", "--configfile", str(cfg), cwd=wf)
    assert _planned_jobs(r.stdout + r.stderr) == {"calibrate_scene", "reality_demo", "all"}, r.stdout
    # a Hydra config file changes: the render group reruns the footage, not the calibrations
    # (before 5 Dec 2026 editing conf/ reran nothing)
    cfg.write_text(base + "overrides: {calibrate_scene: '', reality_demo: ''}\n")
    with open(wf / "conf" / "render" / "default.yaml", "a") as f:
        f.write("noise_sigma: 3.0\n")
    r = _smk("-n", "--profile", "workflow/profiles/default", "--configfile", str(cfg), cwd=wf)
    assert _planned_jobs(r.stdout + r.stderr) == {"reality_demo", "all"}, r.stdout


def test_your_own_recording_runs_as_a_rigid_case_without_reality_or_scoring(tmp_path):
    """rigid.cases.<name>: {footage: <folder>} segments, fits and diagnoses your own recording in the DAG;
    no reality job films it and nothing scores it (it has no truth). A case with both or neither of seed
    and footage is refused at parse time."""
    mine = tmp_path / "my_toss"
    mine.mkdir()
    (mine / "meta.yaml").write_text("object: {}\n")  # only its existence matters to the plan
    cfg = tmp_path / "own.yaml"
    cfg.write_text(f"results: {tmp_path / 'results'}\nstages: {only('rigid', 'gap')}\n"
                   f"rigid: {{cases: {{mine: {{footage: {mine}}}}}, ball: false}}\n"
                   "gap: {suite_cases: null, diagnose_cases: [mine], cloth_suite_cases: null, ball: false}\n")
    r = _smk("-n", "--profile", "workflow/profiles/default", "--configfile", str(cfg), "--forceall")
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-3000:]
    assert f"paths.footage={mine} " in out and f"{tmp_path / 'results'}/rigid/mine/fit.yaml" in out
    assert f"{tmp_path / 'results'}/gap/rigid_mine/diagnosis.json" in out
    assert "footage/rigid_mine" not in out and "rigid/mine/score.yaml" not in out
    cfg.write_text(f"results: {tmp_path / 'results'}\nstages: {only('rigid')}\n"
                   f"rigid: {{cases: {{bad: {{seed: 3, footage: {mine}}}}}}}\n")
    r = _smk("-n", "--profile", "workflow/profiles/default", "--configfile", str(cfg))
    assert r.returncode != 0 and "rigid.cases.bad: give either seed" in r.stdout + r.stderr


def test_unknown_names_fail_at_parse_time(tmp_path):
    """An unknown PIV recording is an error naming it (it had fallen through to the demo rule and
    become tumbling-box footage), and a sweep plotted along a column its table lacks is refused
    before any point runs (it had failed in the collect job after every point)."""
    cfg = tmp_path / "piv.yaml"
    cfg.write_text(f"results: {tmp_path}/results\nfluid: {{piv: [karman, cylinder]}}\n")
    r = _smk("-n", "--profile", "workflow/profiles/default", "--configfile", str(cfg))
    assert r.returncode != 0 and "unknown PIV recording 'cylinder'" in r.stdout + r.stderr, r.stdout[-2000:] + r.stderr[-2000:]
    table = tmp_path / "my.tsv"
    table.write_text("calibrate__n_views\tcamera__fx\n4\t500\n8\t500\n")
    cfg = tmp_path / "sweep.yaml"
    cfg.write_text(f"results: {tmp_path}/results\nsweep_calibration: {{table: {table}, x: calibrate__noise_sigma}}\n")
    r = _smk("-n", "--profile", "workflow/profiles/default", "--configfile", str(cfg))
    out = r.stdout + r.stderr
    assert r.returncode != 0 and "sweep_calibration.x = 'calibrate__noise_sigma' is not a column" in out, out[-2000:]
    cfg.write_text(f"results: {tmp_path}/results\nsweep_calibration: {{table: {table}}}\n")
    r = _smk("-n", "-p", "--profile", "workflow/profiles/default", "--configfile", str(cfg))
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-2000:]
    assert "--x calibrate__n_views --group camera__fx" in out, out[-3000:]  # the table's own first two columns
