"""Snakemake plans the cloth study per fabric: changing one fabric's config reruns only its jobs.

All planned outputs are created as empty files and recorded as up to date (``--touch``); a dry
run then plans nothing; after a change of linen's ``per_fabric`` overrides it plans linen's fits,
linen's selection and the validation (which reads every fabric), and nothing of satin's.
"""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(ROOT / ".venv" / "bin" / "snakemake")


def _smk(cfg: Path, *args: str) -> str:
    env = {**os.environ, "PATH": f"{ROOT / '.venv' / 'bin'}:{os.environ.get('PATH', '')}"}
    p = subprocess.run([SNAKEMAKE, "--profile", "workflow/profiles/default", "--configfile", str(cfg), *args], cwd=ROOT,
                       env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    return p.stdout + p.stderr


def _config(tmp: Path, per_fabric: dict) -> Path:
    cfg = {
        "results": str(tmp / "results"),
        "stages": {k: k == "cloth" for k in ("calibration_chessboard", "demo", "sweep_calibration", "rigid", "cloth",
                                             "fluid", "posterior", "gap")},
        "cloth": {"fabrics": ["linen", "satin"], "fit_trials": ["exp1", "exp2"], "held_out": "robot", "hydra": "",
                  "reality_hydra": "", "calibration_hydra": "", "per_fabric": per_fabric, "per_fabric_reality": {}},
    }
    p = tmp / "x.yaml"
    p.write_text(yaml.safe_dump(cfg))
    return p



def test_one_fabric_change_reruns_only_that_fabric(tmp_path):
    cfg = _config(tmp_path, {})
    summary = _smk(cfg, "--summary")
    outs = [line.split("\t")[0] for line in summary.splitlines()[1:] if line.startswith(str(tmp_path))]
    assert any("cloth/fit/satin_exp2/fit.yaml" in o for o in outs)
    for o in outs:
        Path(o).parent.mkdir(parents=True, exist_ok=True)
        Path(o).touch()
    _smk(cfg, "--touch", "-j1")
    assert "Nothing to be done" in _smk(cfg, "-n")
    cfg = _config(tmp_path, {"linen": "cloth.fit.seed=1"})
    plan = _smk(cfg, "-n", "-p")
    jobs = re.findall(r"^rule (\w+):\n(?:[^\n]*\n)*?\s+wildcards: ([^\n]*)|^rule (validate_cloth|all):", plan, re.M)
    planned = sorted({(a or c, b) for a, b, c in jobs})
    assert planned == [("all", ""), ("fit_cloth", "fabric=linen, trial=exp1"), ("fit_cloth", "fabric=linen, trial=exp2"),
                       ("select_cloth", "fabric=linen"), ("validate_cloth", "")], planned
