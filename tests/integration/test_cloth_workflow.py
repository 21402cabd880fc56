"""Snakemake plans the cloth study per fabric: changing one fabric's config reruns only its jobs.

All planned outputs are created as empty files and recorded as up to date (``--touch``); a dry
run then plans nothing; after a change of linen's ``per_fabric`` overrides it plans linen's fits,
linen's selection and profile, and the validation and skirt matrices (which read every fabric),
and nothing of satin's (its fits, its CMA-ES and joint fits of the method comparison) nor of the
twin's. A rule that shares another stage's settings (the joint fit shares the annealing fit's, the
CMA-ES selection the selection's) reads that stage's ``overrides:`` entry and then its own, and its
own entry reruns it alone.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")  # the test environment's own (venv or conda)


def _smk(cfg: Path, *args: str) -> str:
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}"}
    p = subprocess.run([SNAKEMAKE, "--profile", "workflow/profiles/default", "--configfile", str(cfg), *args], cwd=ROOT,
                       env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    return p.stdout + p.stderr


def _config(tmp: Path, per_fabric: dict, overrides: dict | None = None) -> Path:
    cfg = {
        "results": str(tmp / "results"),
        "stages": {k: k == "cloth" for k in ("calibration_chessboard", "demo", "sweep_calibration", "rigid", "cloth",
                                             "fluid", "posterior", "gap")},
        "cloth": {"fabrics": ["linen", "satin"], "fit_trials": ["exp1", "exp2"], "held_out": "robot", "hydra": "",
                  "reality_hydra": "", "calibration_hydra": "", "per_fabric": per_fabric, "per_fabric_reality": {},
                  "twins": ["twin"], "skirt": True, "compare": ["satin"]},
    }
    if overrides:
        cfg["overrides"] = overrides
    p = tmp / "x.yaml"
    p.write_text(yaml.safe_dump(cfg))
    return p



def _planned(cfg: Path) -> list[tuple[str, str]]:
    plan = _smk(cfg, "-n", "-p")
    jobs = []
    for block in re.split(r"^(?=(?:local)?rule \w+:)", plan, flags=re.M):
        m = re.match(r"(?:local)?rule (\w+):", block)
        if m:
            w = re.search(r"^\s+wildcards: ([^\n]*)", block, re.M)
            jobs.append((m.group(1), w.group(1) if w else ""))
    return sorted(set(jobs))


def test_one_fabric_change_reruns_only_that_fabric(tmp_path):
    cfg = _config(tmp_path, {})
    summary = _smk(cfg, "--summary")
    outs = [line.split("\t")[0] for line in summary.splitlines()[1:] if line.startswith(str(tmp_path))]
    for want in ("cloth/fit/satin_exp2/fit.yaml", "cloth/twin/twin/score.yaml", "cloth/skirt/matrix.png",
                 "cloth/compare/curves.png", "cloth/fit_joint/satin/fit.yaml", "cloth/fit_cmaes/satin_exp1/fit.yaml",
                 "footage/skirt_linen/meta.yaml", "cloth/profile/linen/profile.yaml"):
        assert any(want in o for o in outs), want
    for o in outs:
        Path(o).parent.mkdir(parents=True, exist_ok=True)
        Path(o).touch()
    _smk(cfg, "--touch", "--forceall", "-j1")  # --forceall: every job records its provenance (params)
    assert "Nothing to be done" in _smk(cfg, "-n")
    planned = _planned(_config(tmp_path, {"linen": "cloth.fit.seed=1"}))
    assert planned == [("all", ""), ("fit_cloth", "fabric=linen, trial=exp1"), ("fit_cloth", "fabric=linen, trial=exp2"),
                       ("profile_cloth", "fabric=linen"), ("select_cloth", "fabric=linen"), ("skirt_cloth", ""),
                       ("validate_cloth", "")], planned

    # a rule that shares another stage's settings reads that stage's `overrides:` entry and then its
    # own: the joint fit's own entry reruns the joint fit and the comparison that reads it, nothing else
    planned = _planned(_config(tmp_path, {}, {"fit_cloth_joint": "cloth.fit.seed=3"}))
    assert planned == [("all", ""), ("compare_cloth", ""), ("fit_cloth_joint", "fabric=satin")], planned
    # so does the CMA-ES selection, which shares the selection's settings (its own entry was ignored
    # until 6 Dec 2026)
    planned = _planned(_config(tmp_path, {}, {"select_cloth_cmaes": "cloth.select.polish_budget=7"}))
    assert planned == [("all", ""), ("compare_cloth", ""), ("select_cloth_cmaes", "fabric=satin")], planned
    # and the shared entry reaches the annealing, CMA-ES and joint fits alike
    planned = _planned(_config(tmp_path, {}, {"fit_cloth": "cloth.fit.seed=3"}))
    assert {r for r, _ in planned} >= {"fit_cloth", "fit_cloth_cmaes", "fit_cloth_joint"}, planned


def test_a_stage_override_wins_over_the_cloth_family_string(tmp_path):
    """Hydra keeps the last value of a key: the stage's own `overrides:` entry must come after the
    family string `cloth.hydra` (quick.yaml sets cloth.fit.budget=100 there), or it is ignored while
    the job still reruns (review, 5 Dec 2026)."""
    cfg = tmp_path / "o.yaml"
    cfg.write_text(yaml.safe_dump({"results": str(tmp_path / "results"),
                                   "overrides": {"fit_cloth": "cloth.fit.budget=300", "fit_cloth_joint": "cloth.fit.seed=5"}}))
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}"}
    p = subprocess.run([SNAKEMAKE, "-n", "-p", "--profile", "workflow/profiles/default", "--configfile",
                        "workflow/config/quick.yaml", str(cfg), "--",
                        str(tmp_path / "results/cloth/fit/linen_exp1/fit.yaml"),
                        str(tmp_path / "results/cloth/fit_joint/satin/fit.yaml")],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    cmds = [ln for ln in p.stdout.splitlines() if "vidsim.cli.cloth_fit" in ln]
    fit = next(c for c in cmds if "paths.out=" in c and "/fit/linen_exp1" in c)
    assert re.findall(r"cloth\.fit\.budget=(\d+)", fit)[-1] == "300", fit
    joint = next(c for c in cmds if "/fit_joint/satin" in c)
    # the joint fit reads the annealing fit's entry, then its own
    assert re.findall(r"cloth\.fit\.budget=(\d+)", joint)[-1] == "300" and joint.rstrip().find("cloth.fit.seed=5") > 0, joint
