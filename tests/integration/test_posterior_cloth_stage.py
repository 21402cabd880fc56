"""Stage posterior_cloth through the CLI on a tiny twin reality (reality -> fits -> selection -> posterior).

A coarse twin (14x14 mesh, finer than the 10x10 model; 16 frames, every second one fitted) of the estimator's own simulator is filmed for exp1 and exp2,
each trial's stretch stiffness is fitted (the other eight cloth parameters held at their true values
from truth.yaml, ``cloth.fit.fixed``), the selection picks one, and the posterior stage samples its
surrogate posterior and checks it at 50 draws against the simulator. The interval for stretch is
therefore conditional on the others being known exactly: a 1-D recoverability check, not blind
estimation.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
FAST = ["log.rerun=false", "log.progress=false"]


def _run(mod: str, *args: str) -> str:
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    p = subprocess.run([sys.executable, "-m", mod, *args, *FAST], cwd=ROOT, env=env, capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    return p.stdout + p.stderr


@pytest.fixture(scope="module")
def tiny_twin(tmp_path_factory):
    res = tmp_path_factory.mktemp("postcloth")
    cal = res / "calibration" / "cloth"
    _run("vidsim.cli.calibrate", "camera=cloth", "projector=cloth", "calibrate=cloth", "cloth.calibration.n_views=6",
         "cloth.calibration.n_projector_views=6", f"paths.results={res}", f"paths.out={cal}")
    folders = []
    for trial in ("exp1", "exp2"):
        fp = res / "footage" / f"cloth_twin_{trial}"
        _run("vidsim.cli.cloth_reality", f"paths.results={res}", f"paths.calibration={cal / 'calibration.yaml'}",
             f"paths.out={fp}", "cloth.reality.kind=twin", f"cloth.reality.motion={trial}", "cloth.reality.n_frames=16",
             "cloth.reality.twin_resolution=14", "cloth.reality.settle_s=0.5")
        folders.append(fp)
    return res, folders


def test_posterior_cloth_stage_on_a_tiny_twin(tiny_twin):
    """Fits, selection and posterior of stretch alone, the other eight parameters fixed at their true
    values (1-D recoverability given the others, not blind estimation); then Table 1 with intervals."""
    res, folders = tiny_twin
    truth = yaml.safe_load((folders[0].parent / f"{folders[0].name}.truth.yaml").read_text())["params"]
    # every cloth parameter but stretch at its true value (density is known footage metadata)
    model = ["cloth.model.resolution=10", "cloth.model.settle_s=0.5", "cloth.model.frame_stride=2", "cloth.fit.estimate=[stretch]",
             "cloth.fit.grid_params=[stretch]", "cloth.fit.grid_levels=4", "cloth.fit.budget=6",
             "cloth.fit.evals_per_T=3", "cloth.fit.n_candidates=2",
             *[f"+cloth.fit.fixed.{k}={v}" for k, v in truth.items() if k not in ("stretch", "density")]]
    fits = []
    for fp in folders:
        out = res / "cloth" / "fit" / fp.name.replace("cloth_", "")
        _run("vidsim.cli.cloth_fit", f"paths.results={res}", f"paths.footage={fp}", f"paths.out={out}", *model)
        fits.append(out / "fit.yaml")
    sel = res / "cloth" / "select" / "twin"
    lists = f"[{','.join(map(str, fits))}]", f"[{','.join(map(str, folders))}]"
    _run("vidsim.cli.cloth_select", f"paths.results={res}", f"paths.out={sel}", f"cloth.select.fits={lists[0]}",
         f"cloth.select.footage={lists[1]}", *model)
    post = res / "posterior" / "cloth" / "twin"
    log = _run("vidsim.cli.posterior_cloth", f"paths.results={res}", f"paths.out={post}",
               f"posterior.cloth.params={sel / 'params.yaml'}", f"posterior.cloth.fits={lists[0]}",
               f"posterior.cloth.footage={lists[1]}", *model, "posterior.cloth.design_rounds=1", "posterior.cloth.n_jitter=3",
               "posterior.cloth.refine_rounds=0", "posterior.cloth.max_steps=3000", "posterior.cloth.n_walkers=8",
               "posterior.cloth.chunk=250")
    for f in ("summary.csv", "posterior.yaml", "corner.png", "correlation.png", "check.png", "chain.npz", "evals.jsonl"):
        assert (post / f).is_file(), f
    doc = yaml.safe_load((post / "posterior.yaml").read_text())
    d, ck = doc["diagnostics"], doc["surrogate_check"]
    assert doc["names"] == ["stretch"]
    # the fits' caches reproduce (same model settings) and train the surrogate
    assert all(c["used"] for c in doc["cache"]), doc["cache"]
    assert ck["n_draws"] == 50 and ck["n_failed"] == 0 and np.isfinite(ck["max_abs_error_logp"])
    assert isinstance(d["converged"], bool) and d["converged"] == (d["n_steps"] >= 50 * d["tau_max"])
    assert d["w"] > 0 and d["true_evaluations"] >= 50 + 2 * 4 + 1
    lines = (post / "summary.csv").read_text().splitlines()
    assert lines[0] == "name,unit,point,q05,median,q95,mean,sd"
    name, unit, point, q05, med, q95 = lines[1].split(",")[:6]
    assert name == "stretch" and unit == "N/m" and float(q05) <= float(med) <= float(q95)
    # the stretch of the twin (300 N/m) from a 20-4000 N/m box (a ratio of 200): a 90 % interval that holds
    # it and narrows the box at least 10-fold (it accepted an interval 2.7x beside the truth before; fixed
    # seeds, so this is deterministic: measured [104, 1051] N/m around a point of 146 with the 14x14 twin and
    # the corrected snooker move; [103, 869] with emcee's; [157, 484] with the twin on the model's own mesh)
    assert float(q95) / float(q05) < 20 and float(q05) <= truth["stretch"] <= float(q95), (
        f"{lines[1]}: the 90 % interval of stretch (true {truth['stretch']} N/m), the other parameters held at "
        "their true values (a 1-D recoverability check, not blind estimation)")
    assert "posterior_cloth: converged" in log
    # Table 1 with intervals: the selection beside its posterior (the estimated parameter with its
    # interval, the others marked fixed); a missing summary is a one-line error naming the file
    tab = res / "posterior" / "cloth" / "table1"
    out = _run("vidsim.cli.cloth_table1", f"paths.results={res}", f"paths.out={tab}", "cloth.table1.fabrics=[twin]",
               f"cloth.table1.params=[{sel / 'params.yaml'}]", f"cloth.table1.summaries=[{post / 'summary.csv'}]")
    assert "table1_cloth: 1 fabrics" in out and (tab / "table1_intervals.png").is_file()
    rows = {r.split(",")[1]: r.split(",") for r in (tab / "table1_intervals.csv").read_text().splitlines()[1:]}
    assert set(rows) == {"bend", "stretch", "shear", "bend_damping", "stretch_damping", "shear_damping", "drag_linear",
                         "drag_quad", "drag_degrade"}
    assert rows["stretch"][5:7] == [f"{float(q05):.5g}", f"{float(q95):.5g}"] and rows["bend"][-1] == "fixed"
    p = subprocess.run([sys.executable, "-m", "vidsim.cli.cloth_table1", f"paths.results={res}", f"paths.out={tab}_bad",
                        "cloth.table1.fabrics=[twin]", f"cloth.table1.params=[{sel / 'params.yaml'}]",
                        f"cloth.table1.summaries=[{res / 'nope.csv'}]"], cwd=ROOT, capture_output=True, text=True)
    assert p.returncode == 2 and "nope.csv" in p.stderr and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and not (tab.parent / "table1_bad").exists()
