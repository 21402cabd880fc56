"""Cloth stages through the CLI on a tiny twin reality: a fit, then a resume by replay.

The twin reality (the estimator's own simulator at a finer mesh with known parameters) is filmed
through ``reality_cloth`` with the calibration written by the calibration stage; ``fit_cloth``
estimates the stretch stiffness from it; running ``fit_cloth`` again on the same folder replays
every evaluation from ``evals.jsonl`` and simulates nothing.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import assert_footage_holds_no_truth, truth_hidden

ROOT = Path(__file__).resolve().parents[2]
FAST = ["log.rerun=false", "log.progress=false"]


def _run(mod: str, *args: str) -> str:
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    p = subprocess.run([sys.executable, "-m", mod, *args, *FAST], cwd=ROOT, env=env, capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    return p.stdout + p.stderr


@pytest.fixture(scope="module")
def twin_footage(tmp_path_factory):
    res = tmp_path_factory.mktemp("cloth")
    cal = res / "calibration" / "cloth"
    _run("vidsim.cli.calibrate", "camera=cloth", "projector=cloth", "calibrate=cloth", "cloth.calibration.n_views=6",
         "cloth.calibration.n_projector_views=6", f"paths.results={res}", f"paths.out={cal}")
    fp = res / "footage" / "cloth_twin_exp1"
    _run("vidsim.cli.cloth_reality", f"paths.results={res}", f"paths.calibration={cal / 'calibration.yaml'}",
         f"paths.out={fp}", "cloth.reality.kind=twin", "cloth.reality.motion=exp1", "cloth.reality.n_frames=20",
         "cloth.reality.twin_resolution=14", "cloth.reality.settle_s=0.5")
    return res, fp


def test_twin_fit_and_resume_by_replay(twin_footage):
    """The cloth_fit stage on twin footage, run blind (truth hidden) but given the truth's other
    eight cloth parameters as ``cloth.fit.fixed`` (read from truth.yaml before the run): only stretch
    is estimated, so its recovery is a 1-D identifiability check given the others, not blind
    estimation. Then the stage's resume by replay of its evaluation log."""
    res, fp = twin_footage
    meta = yaml.safe_load((fp / "meta.yaml").read_text())
    assert np.asarray(meta["corner_paths"]).shape == (20, 2, 3)
    truth = yaml.safe_load((fp.parent / f"{fp.name}.truth.yaml").read_text())
    assert "params" not in meta and truth["kind"] == "twin"
    out = res / "cloth" / "fit" / "twin_exp1"
    # held at their true values (density is known footage metadata): 1-D recoverability of stretch
    others = {k: v for k, v in truth["params"].items() if k not in ("stretch", "density")}
    args = [f"paths.results={res}", f"paths.footage={fp}", f"paths.out={out}", "cloth.model.resolution=10",
            "cloth.model.settle_s=0.5", "cloth.fit.estimate=[stretch]",
            *[f"+cloth.fit.fixed.{k}={v}" for k, v in others.items()],
            "cloth.fit.grid_params=[stretch]", "cloth.fit.grid_levels=4", "cloth.fit.budget=8", "cloth.fit.evals_per_T=4",
            "cloth.fit.step=0.1"]
    assert_footage_holds_no_truth(fp)
    with truth_hidden(fp):  # the estimator must not need it
        _run("vidsim.cli.cloth_fit", *args)
    fit = yaml.safe_load((out / "fit.yaml").read_text())
    assert 0 < fit["n_new_simulations"] <= fit["n_evals"]  # repeats within a run are cache hits too
    # stretch within a factor 2 of the twin's truth (300 N/m) from a 20-4000 N/m box, the others at truth
    assert abs(np.log(fit["params"]["stretch"] / truth["params"]["stretch"])) < np.log(2.0), (
        f"stretch {fit['params']['stretch']:.4g} N/m not within x2 of the true {truth['params']['stretch']} N/m "
        f"with the other parameters held at their true values {sorted(others)} (a 1-D recoverability "
        f"check, not blind estimation): {fit['params']}")
    # a second run of the stage (as after a kill) replays the log and simulates nothing
    _run("vidsim.cli.cloth_fit", *args)
    fit2 = yaml.safe_load((out / "fit.yaml").read_text())
    assert fit2["n_new_simulations"] == 0 and fit2["n_evals"] == fit["n_evals"]
    assert fit2["params"]["stretch"] == fit["params"]["stretch"]
    # a shorter run (another budget) in the same folder: the same candidates and log as in an empty
    # folder (the longer run's extra records go aside), the folder's history does not leak into the
    # selection (in this 1-D box another seed visits the same points, so the budget is what differs)
    _run("vidsim.cli.cloth_fit", *args, "cloth.fit.budget=2")
    alone = res / "cloth" / "fit" / "twin_exp1_short_alone"
    _run("vidsim.cli.cloth_fit", *[a for a in args if not a.startswith("paths.out=")], f"paths.out={alone}",
         "cloth.fit.budget=2")
    f_same, f_alone = (yaml.safe_load((d / "fit.yaml").read_text()) for d in (out, alone))
    assert f_same["candidates"] == f_alone["candidates"] and f_same["params"] == f_alone["params"]

    def keys(d: Path) -> set:
        return {json.loads(line).get("key") for line in (d / "evals.jsonl").read_text().splitlines()}

    assert keys(out) == keys(alone)
    assert (out / "evals.other-runs-1.jsonl").is_file()
    # changed model settings: the log is not replayed but moved aside
    log = _run("vidsim.cli.cloth_fit", *args, "cloth.model.settle_s=0.4")
    assert "not replayed" in log and (out / "evals.stale-1.jsonl").is_file()
    assert yaml.safe_load((out / "fit.yaml").read_text())["n_new_simulations"] > 0


def test_diagnose_cloth_stage_on_twin_footage(twin_footage):
    """The cloth diagnosis stage on a swatch footage folder: it reads the footage (never the truth
    file), writes its three outputs atomically, and its gap measure ranks a deliberately poor fit
    (stretch twice the twin's) worse than the twin's own parameters. (Its trust-region base refit
    does not repair the poor stretch here: the model's response at 1e-3 px steps is chaotic,
    docs/gap.md, item 1; the held-out excess alone, 3 frames, does not separate the two.)"""
    res, fp = twin_footage
    truth = yaml.safe_load((fp.parent / f"{fp.name}.truth.yaml").read_text())["params"]
    true_p = {k: v for k, v in truth.items() if k != "density"}
    gaps = {}
    for name, params in (("poor", {**true_p, "stretch": 2.0 * truth["stretch"]}), ("true", true_p)):
        fit = res / f"{name}_fit.yaml"
        fit.write_text(yaml.safe_dump({"params": params, "estimated": ["stretch"]}))
        out = res / "gap" / f"cloth_twin_{name}"
        with truth_hidden(fp):
            log = _run("vidsim.cli.diagnose_cloth", f"paths.results={res}", f"paths.footage={fp}", f"gap.paths.fit={fit}",
                       f"paths.out={out}", "cloth.model.resolution=10", "cloth.model.settle_s=0.5",
                       "cloth.model.frame_stride=2", "+gap.cloth.diagnose.top_k=1", "+gap.cloth.diagnose.pairs=false",
                       "+gap.cloth.diagnose.candidates=[wind,time_offset,lens_k1]")
        assert "diagnose_cloth cloth_twin_exp1:" in log
        d = json.loads((out / "diagnosis.json").read_text())
        assert (out / "diagnosis.png").is_file() and (out / "diagnosis.rrd").is_file()
        assert not (out.parent / f".{out.name}.part").exists()
        assert not (out.parent / f".{out.name}.passes").exists()  # the passes' checkpoint, gone once written
        assert d["frames"] == list(range(0, 20, 2)) and len(d["gap_per_frame_px"]) == 10
        assert d["inputs"]["estimated"] == ["stretch"]
        assert set(d["screen"]) >= {"wind", "time_offset", "lens_k1"}
        floor = d["noise_floor_heldout_px"]
        assert np.isfinite(floor) and floor > 0
        # the default diagnosis runs two passes (near the grips: time_offset, lens_k1; the outline:
        # all three); the outline's gap is the one that sees the whole swatch
        assert set(d["passes"]) == {"grips", "outline"} and d["region"] == "split"
        assert {v["region"] for v in d["refits"].values()} <= {"grips", "outline"}
        gaps[name] = float(np.mean(d["passes"]["outline"]["gap_per_frame_px"]))
    # measured 517 vs 392 px per frame (3 Dec 2026)
    assert gaps["poor"] > 1.15 * gaps["true"], gaps
