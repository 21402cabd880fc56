"""Stage posterior_rigid end to end on a small synthetic throw (fast rasteriser, 320x240, 20 frames)."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from vidsim.io.atomic import write_npz, write_yaml
from vidsim.io.footage import write_footage
from vidsim.posterior.rigid import to_natural, truth_params
from vidsim.reality.rigid import RigidRealityConfig, make_throw
from vidsim.rigid.body import BoxBody
from vidsim.rigid.evaluate import perturbed_guess
from vidsim.rigid.fit import Stage, fit_throw
from vidsim.rigid.outputs import fit_to_dict

ENV = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "PYOPENGL_PLATFORM": "egl"}


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    root = tmp_path_factory.mktemp("post")
    sc = RigidRealityConfig(n_frames=20, n_background=2, width=320, height=240, focal=320.0)
    th = make_throw(11, sc, render=False)
    body = BoxBody.from_meta(th.meta["object"])
    guess = perturbed_guess(th.truth, np.random.default_rng(11), orient_deg=5.0, omega_rel=0.1, vel_rel=0.05,
                            pos_m=0.02, grav_deg=2.0)
    fc = {"multistart": "none", "screen": [Stage(0.5, None, 20, 0.3)], "screen_keep": [1], "refine": [],
          "final": [Stage(1.0, None, 40, 0.0)]}
    res = fit_throw(th.masks, th.times, th.camera, body, guess, fc)
    foot = root / "footage" / "rigid_t"
    write_footage(foot, th.frames, th.times, {"camera": th.camera}, th.meta)
    d = fit_to_dict(res, body)
    d["object"] = th.meta["object"]
    write_yaml(root / "rigid" / "fit.yaml", d)
    write_npz(root / "rigid" / "masks.npz", masks=th.masks, times=th.times)
    return root, th, body


def _run(root: Path, *extra: str, out: str = "t", walkers: int = 28) -> subprocess.CompletedProcess:
    args = [sys.executable, "-m", "vidsim.cli.posterior_rigid", f"paths.results={root}",
            f"paths.footage={root}/footage/rigid_t", f"posterior.paths.fit={root}/rigid/fit.yaml",
            f"posterior.paths.masks={root}/rigid/masks.npz", f"paths.out={root}/posterior/rigid/{out}",
            "posterior.rigid.n_design=160", "posterior.rigid.design_iters=1", "posterior.rigid.chunk=50",
            f"posterior.rigid.n_walkers={walkers}", "posterior.rigid.min_steps=100", "posterior.rigid.max_steps=100",
            "posterior.draws_logged=3", *extra]
    return subprocess.run(args, capture_output=True, text=True, env=ENV, timeout=300)


def test_stage_writes_outputs_and_flags_short_chain(case) -> None:
    root, th, body = case
    r = _run(root)
    assert r.returncode == 0, r.stderr[-2000:]
    out = root / "posterior" / "rigid" / "t"
    for f in ("summary.csv", "posterior.yaml", "corner.png", "correlation.png", "chain.npz", "posterior.rrd"):
        assert (out / f).is_file(), f
    assert "posterior_rigid chain chunks" in r.stderr  # progress lines
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert [x["name"] for x in rows][:3] == ["x", "y", "z"] and len(rows) == 14
    d = yaml.safe_load((out / "posterior.yaml").read_text())
    diag = d["diagnostics"]
    # 100 steps are far fewer than 50 autocorrelation times: reported, not accepted
    assert diag["converged"] is False and diag["steps_per_tau"] < 50
    assert diag["n_steps"] == 100 and diag["noise"]["model"] == "sandwich"
    # the truth lies inside most 90 % intervals (a posterior that missed it would fail here)
    tp = to_natural(truth_params(th.truth, np.asarray(d["q_base"]), body.symmetries))
    inside = [float(x["q05"]) <= t <= float(x["q95"]) for x, t in zip(rows, tp)]
    assert sum(inside) >= 9, inside
    # intervals are not absurdly wide: position known to within a few centimetres
    assert all(float(x["q95"]) - float(x["q05"]) < 0.05 for x in rows[:3])


def test_stage_bad_input_is_one_line(case) -> None:
    root, _, _ = case
    r = _run(root, "posterior.paths.fit=")
    assert r.returncode == 2 and "posterior.paths.fit" in r.stderr and "Traceback" not in r.stderr


def test_stage_with_drag_nuisance(case) -> None:
    """``posterior.rigid.discrepancy=[quadratic_drag]``: the drag coefficient is sampled inside its prior
    and reported after the 14 parameters (no drag in this reality: its interval starts near 0).

    The stage's wiring and report only: at 100 steps the interval is mostly the walkers' start, and
    a drag that did not reach the model gave a similar one (q05 / median / q95 0.021 / 0.23 / 1.08
    against 0.025 / 0.42 / 1.59; test review, 6 Dec 2026). That the nuisance reaches the model is
    checked by ``tests/unit/posterior/test_posterior_discrepancy.py``, which fails on that defect."""
    root, th, body = case
    r = _run(root, "posterior.rigid.discrepancy=[quadratic_drag]", out="d", walkers=30)
    assert r.returncode == 0, r.stderr[-2000:]
    out = root / "posterior" / "rigid" / "d"
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert len(rows) == 15 and rows[-1]["name"] == "quadratic_drag" and rows[-1]["unit"] == "kg/m^3"
    q05, med, q95 = (float(rows[-1][k]) for k in ("q05", "median", "q95"))
    assert 0.0 <= q05 <= med <= q95 <= 5.0
    # no drag in this reality: the interval starts near 0 (its lower tenth of the prior), not somewhere inside
    assert q05 < 0.5, (q05, med, q95)
    d = yaml.safe_load((out / "posterior.yaml").read_text())
    assert d["diagnostics"]["discrepancy"]["effects"] == ["quadratic_drag"]
    assert d["diagnostics"]["discrepancy"]["bounds"] == [[0.0, 5.0]]


@pytest.mark.parametrize("arg, what", [("posterior.rigid.discrepancy=[quadratic_drgg]", "quadratic_drgg"),
                                       ("posterior.rigid.discrepancy_upper={angular_drag: 1.0}", "angular_drag")])
def test_stage_bad_discrepancy_is_one_line(case, arg: str, what: str) -> None:
    root, _, _ = case
    r = _run(root, arg)
    assert r.returncode == 2 and "posterior.rigid.discrepancy" in r.stderr and what in r.stderr, r.stderr[-500:]
    assert "Traceback" not in r.stderr


def test_stage_bad_holdout_confidence_is_one_line(case) -> None:
    root, _, _ = case
    r = _run(root, "posterior.rigid.holdout_confidence=1.5")
    assert r.returncode == 2 and "posterior.rigid" in r.stderr and "holdout_confidence = 1.5" in r.stderr, r.stderr[-500:]
    assert "Traceback" not in r.stderr
