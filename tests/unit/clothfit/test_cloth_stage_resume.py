"""score_cloth_twin, skirt_cloth, validate_cloth and compare_cloth resume within a run: every simulation is logged as it finishes
(:class:`vidsim.cli.cloth_common.LoggedScores`, the fits' evaluation-log mechanism); a run killed
partway and run again writes the uninterrupted run's outputs bit for bit and simulates only what
was not logged; a changed setting does not replay the old scores.

The footage is filmed in memory (a twin swatch, 14 frames at the tests' smallest settings) and
handed to the stages through ``load_trial``: the stages' own reading of footage folders is tested
in tests/integration/test_cloth_study_stages.py.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml
from omegaconf import OmegaConf

import vidsim.cli.cloth_common as common
import vidsim.cli.cloth_compare as compare_stage
import vidsim.cli.cloth_skirt as skirt_stage
import vidsim.cli.cloth_twin_score as twin_stage
import vidsim.cli.cloth_validate as validate_stage
from vidsim.cli.cloth_common import params_dict
from vidsim.cloth import ClothParams
from vidsim.clothfit.features import FeatureSettings, extract_features
from vidsim.clothfit.film import FilmSettings, film_cloth, twin_swatch
from vidsim.clothfit.objective import ClothObjective, Trial
from vidsim.config import CONF_DIR, camera_from_config, projector_from_config
from vidsim.config.cloth import ClothConfig
from vidsim.reality.cloth import corner_paths, swatch_motion
from vidsim.render.projector import Projector

SOFT = ClothParams(bend=3e-6, stretch=300.0, shear=40.0, bend_damping=3e-8, stretch_damping=3e-3,
                   shear_damping=3e-3, drag_linear=0.4, drag_quad=0.8, drag_degrade=0.2, density=0.2)
STIFF = dataclasses.replace(SOFT, bend=9e-5, stretch=3000.0)
MODEL = ["cloth.model.resolution=7", "cloth.model.settle_s=0.4", "cloth.fit.estimate=[stretch,drag_quad]",
         "log.rerun=false", "log.progress=false"]


def _film(params: ClothParams, motion: str, name: str) -> tuple[Trial, np.ndarray]:
    cfg = OmegaConf.structured(ClothConfig())
    cam = camera_from_config(cfg.camera)
    proj = Projector(projector_from_config(cfg.projector), period_px=cfg.projector.period_px,
                     power=cfg.projector.power, ambient=cfg.projector.ambient)
    mot = swatch_motion(motion)
    V, F, cp, ok, failure = twin_swatch(params, lambda t: corner_paths(mot, t), n_frames=14, fps=30.0, resolution=9,
                                        settle_s=0.4)
    assert ok, failure
    frames = film_cloth(V, F, cam, proj, np.random.default_rng(3), FilmSettings(n_background=4))
    feat = extract_features(frames, np.arange(4), FeatureSettings())
    return Trial(name, feat, np.arange(14) / 30.0, cp, cam, proj, 0.3, params.density), frames[4:]


@pytest.fixture(scope="module")
def footage():
    return {"soft": _film(SOFT, "exp1", "soft"), "stiff": _film(STIFF, "robot", "stiff")}


@pytest.fixture
def sims(monkeypatch, footage):
    """Serve the filmed trials as footage folders; count the simulations; kill the stage at a given one."""
    state = {"n": 0, "kill_at": None}

    def load_trial(folder, cfg, name=None, with_frames=False):
        tr, frames = footage[str(folder).rsplit("/", 1)[-1]]
        return (tr, frames) if with_frames else tr

    real = ClothObjective.evaluate_params

    def counted(self, params, keep=False):
        if state["kill_at"] is not None and state["n"] == state["kill_at"]:
            raise KeyboardInterrupt("killed")
        state["n"] += 1
        return real(self, params, keep)

    monkeypatch.setattr(common, "load_trial", load_trial)
    monkeypatch.setattr(twin_stage, "load_trial", load_trial)
    monkeypatch.setattr(compare_stage, "load_trial", load_trial)
    monkeypatch.setattr(ClothObjective, "evaluate_params", counted)
    monkeypatch.setattr(skirt_stage, "_tris", lambda tr, cfg: np.zeros((0, 3), int))
    return state


def _cfg(*overrides: str):
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose("config", overrides=[*MODEL, *overrides])


def _run_killed(run, cfg, sims, at: int) -> None:
    sims["n"], sims["kill_at"] = 0, at
    with pytest.raises(KeyboardInterrupt):
        run(cfg)
    sims["n"], sims["kill_at"] = 0, None


def test_twin_score_resumes_bit_identical_and_recomputes_after_a_setting_change(tmp_path, sims, monkeypatch):
    est = tmp_path / "params.yaml"
    est.write_text(yaml.safe_dump({"params": params_dict(dataclasses.replace(SOFT, stretch=330.0, drag_quad=0.7))}))
    monkeypatch.setattr(twin_stage, "read_truth", lambda folder: {"kind": "twin", "params": params_dict(SOFT)})
    args = [f"paths.results={tmp_path}", f"cloth.twin.params={est}", "cloth.twin.profile=",
            f"cloth.twin.footage={tmp_path / 'soft'}", "cloth.twin.perturb_draws=4", "cloth.twin.chaos_draws=2"]
    whole = tmp_path / "whole"
    twin_stage.run(_cfg(*args, f"paths.out={whole}"))
    assert sims["n"] == 10  # estimate, truth, 4 perturbed truths, 2 moved copies of each side
    assert not (whole / ".score_cloth_twin.checkpoint").exists()
    out = tmp_path / "resumed"
    _run_killed(twin_stage.run, _cfg(*args, f"paths.out={out}"), sims, at=4)
    log = out / ".score_cloth_twin.checkpoint" / "evals.jsonl"
    assert len(log.read_text().splitlines()) == 1 + 4  # the context line and the 4 finished simulations
    twin_stage.run(_cfg(*args, f"paths.out={out}"))
    assert sims["n"] == 6  # only the six simulations not logged
    for f in ("score.yaml", "errors.csv"):
        assert (out / f).read_bytes() == (whole / f).read_bytes()
    assert not (out / ".score_cloth_twin.checkpoint").exists()
    # killed again, then rerun with another metric weight: the log is of another objective, not replayed
    _run_killed(twin_stage.run, _cfg(*args, f"paths.out={out}"), sims, at=3)
    twin_stage.run(_cfg(*args, f"paths.out={out}", "cloth.fit.alpha=0.2"))
    assert sims["n"] == 10 and not (out / ".score_cloth_twin.checkpoint").exists()  # all again; the moved-aside log removed too
    changed = yaml.safe_load((out / "score.yaml").read_text())["heldout"]
    assert changed["error_selected"] != yaml.safe_load((whole / "score.yaml").read_text())["heldout"]["error_selected"]


def test_skirt_matrix_resumes_bit_identical_and_recomputes_after_a_setting_change(tmp_path, sims):
    files = []
    for name, p in (("soft", SOFT), ("stiff", STIFF)):
        (tmp_path / f"{name}.yaml").write_text(yaml.safe_dump({"params": params_dict(p)}))
        files.append(str(tmp_path / f"{name}.yaml"))
    args = [f"paths.results={tmp_path}", "cloth.skirt.fabrics=[soft,stiff]", f"cloth.skirt.params=[{','.join(files)}]",
            f"cloth.skirt.footage=[{tmp_path / 'soft'},{tmp_path / 'stiff'}]", "cloth.skirt.fps=30"]
    whole = tmp_path / "whole"
    skirt_stage.run(_cfg(*args, f"paths.out={whole}"))
    assert sims["n"] == 4
    doc = yaml.safe_load((whole / "skirt.yaml").read_text())
    assert doc["diagonal_wins"] == 2, doc["matrix"]  # each twin's truth explains its own footage best
    assert not (whole / ".skirt_cloth.checkpoint").exists()
    out = tmp_path / "resumed"
    _run_killed(skirt_stage.run, _cfg(*args, f"paths.out={out}"), sims, at=3)  # the second column's diagonal unfinished
    skirt_stage.run(_cfg(*args, f"paths.out={out}"))
    # the first column's two cells replayed except its diagonal (its images make the video), the
    # second column's first cell replayed: 1 + 1 (the second diagonal) simulated
    assert sims["n"] == 2
    for f in ("skirt.yaml", "matrix.csv"):
        assert (out / f).read_bytes() == (whole / f).read_bytes()
    assert not (out / ".skirt_cloth.checkpoint").exists()
    _run_killed(skirt_stage.run, _cfg(*args, f"paths.out={out}"), sims, at=3)
    skirt_stage.run(_cfg(*args, f"paths.out={out}", "cloth.fit.alpha=0.2"))
    assert sims["n"] == 4  # every cell again: the logs were written for another objective
    assert yaml.safe_load((out / "skirt.yaml").read_text())["matrix"] != doc["matrix"]


def _validation_args(tmp_path, *extra: str) -> list[str]:
    files = []
    for name, p in (("soft", SOFT), ("stiff", STIFF)):
        (tmp_path / f"{name}.yaml").write_text(yaml.safe_dump({"params": params_dict(p), "trials": [], "rows": []}))
        files.append(str(tmp_path / f"{name}.yaml"))
    return [f"paths.results={tmp_path}", "cloth.validate.fabrics=[soft,stiff]",
            f"cloth.validate.params=[{','.join(files)}]", f"cloth.validate.footage=[{tmp_path / 'soft'},{tmp_path / 'stiff'}]",
            *extra]


def test_validation_matrix_resumes_bit_identical(tmp_path, sims):
    args = _validation_args(tmp_path, "cloth.validate.chaos_draws=2")
    whole = tmp_path / "whole"
    validate_stage.run(_cfg(*args, f"paths.out={whole}"))
    # 4 cells of the sets themselves, then 4 of their moved copies (one evaluation each, 2 simulations)
    assert sims["n"] == 8 and not (whole / ".validate_cloth.checkpoint").exists()
    out = tmp_path / "resumed"
    _run_killed(validate_stage.run, _cfg(*args, f"paths.out={out}"), sims, at=3)
    assert len(list((out / ".validate_cloth.checkpoint").glob("column*.jsonl"))) == 2
    validate_stage.run(_cfg(*args, f"paths.out={out}"))
    assert sims["n"] == 1 + 4  # the set's cell not logged (no diagonal kept for videos here), then the copies
    for f in ("validation.yaml", "matrix.csv", "matrix_copies.csv"):
        assert (out / f).read_bytes() == (whole / f).read_bytes()
    # killed among the copies: only the copies' cells not logged are simulated again
    _run_killed(validate_stage.run, _cfg(*args, f"paths.out={out}"), sims, at=6)
    validate_stage.run(_cfg(*args, f"paths.out={out}"))
    assert sims["n"] == 2
    for f in ("validation.yaml", "matrix.csv", "matrix_copies.csv"):
        assert (out / f).read_bytes() == (whole / f).read_bytes()
    assert not (out / ".validate_cloth.checkpoint").exists()


def test_validation_verdicts_follow_the_copies_paired_differences(tmp_path, sims):
    """Each column's verdict (won / lost / undecided) follows from the paired t over the moved
    copies against the best other set; the matrix stays the sets' own errors; draws 0 gives no
    copies, each footage paired with the other twin's truth loses decidedly, and one copy (no test
    possible) or a spread outside (0, 1] is refused before any simulation."""
    whole = tmp_path / "v3"
    validate_stage.run(_cfg(*_validation_args(tmp_path, "cloth.validate.chaos_draws=3"), f"paths.out={whole}"))
    doc = yaml.safe_load((whole / "validation.yaml").read_text())
    E, Ec = np.array(doc["matrix"]), np.array(doc["copies"]["matrix_mean"])
    assert doc["copies"]["draws"] == 3 and Ec.shape == E.shape == (2, 2)
    assert not np.allclose(Ec, E, rtol=1e-12)  # the copies are moved sets, not the sets again
    for j, fab in enumerate(("soft", "stiff")):
        m = doc["verdicts"][fab]
        assert m["copies"] == 3 and m["rival"] == ("stiff", "soft")[j]
        assert m["cut"] == pytest.approx(4.303, abs=1e-3)  # Student's t at 95 %, 2 degrees of freedom
        want = ("won" if m["margin"] + m["cut"] * m["se"] < 0 else "lost" if m["margin"] - m["cut"] * m["se"] > 0
                else "undecided")
        assert m["verdict"] == want, (fab, m)
        assert m["margin"] == pytest.approx(Ec[j, j] - Ec[1 - j, j], rel=1e-9)
    assert doc["decided"] == {k: sum(v["verdict"] == k for v in doc["verdicts"].values()) for k in ("won", "lost", "undecided")}
    # the stiff twin's truth explains its own (non-chaotic) footage better than the soft truth in every copy
    assert doc["verdicts"]["stiff"]["verdict"] == "won", doc["verdicts"]
    sims["n"] = 0
    validate_stage.run(_cfg(*_validation_args(tmp_path, "cloth.validate.chaos_draws=0"), f"paths.out={tmp_path / 'v0'}"))
    doc0 = yaml.safe_load((tmp_path / "v0" / "validation.yaml").read_text())
    assert sims["n"] == 4 and doc0["verdicts"] == {} and doc0["decided"] is None and doc0["matrix"] == doc["matrix"]
    assert not (tmp_path / "v0" / "matrix_copies.csv").exists()
    # each footage paired with the *other* twin's truth: both columns are lost, and decided so
    sims["n"] = 0
    sw = tmp_path / "swapped"
    sw.mkdir()
    for name, p in (("soft", STIFF), ("stiff", SOFT)):
        (sw / f"{name}.yaml").write_text(yaml.safe_dump({"params": params_dict(p), "trials": [], "rows": []}))
    validate_stage.run(_cfg(*_validation_args(tmp_path, "cloth.validate.chaos_draws=3"), f"paths.out={tmp_path / 'vs'}",
                            f"cloth.validate.params=[{sw / 'soft.yaml'},{sw / 'stiff.yaml'}]"))
    docs = yaml.safe_load((tmp_path / "vs" / "validation.yaml").read_text())
    assert docs["diagonal_wins"] == 0 and docs["decided"] == {"won": 0, "lost": 2, "undecided": 0}, docs["verdicts"]
    sims["n"] = 0
    for bad, msg in (("cloth.validate.chaos_draws=1", "cloth.validate.chaos_draws = 1"),
                     ("cloth.validate.chaos_sigma=0", "cloth.validate.chaos_sigma = 0"),
                     ("cloth.validate.chaos_sigma=2", "cloth.validate.chaos_sigma = 2")):
        with pytest.raises(common.ClothStageError, match=msg):
            validate_stage.run(_cfg(*_validation_args(tmp_path, bad), f"paths.out={tmp_path / 'v1'}"))
    assert sims["n"] == 0


def test_method_comparison_resumes_bit_identical(tmp_path, sims):
    """compare_cloth logs each held-out simulation (the three estimates, then their moved copies): a
    run killed among the copies simulates only what was not logged and writes the same tables."""
    sets = {"anneal": dataclasses.replace(STIFF, stretch=2700.0), "cmaes": SOFT, "joint": STIFF}
    files = {}
    for m, p in sets.items():
        files[m] = tmp_path / f"{m}.yaml"
        files[m].write_text(yaml.safe_dump({"params": params_dict(p), "rows": [],
                                            "trial_simulations": {"selection": 4, "polish": 0}}))
    trace = tmp_path / "trace.csv"
    trace.write_text("evaluation,phase,energy,best_so_far,simulated\n0,grid,2.0,2.0,1\n1,anneal,1.0,1.0,1\n")
    args = [f"paths.results={tmp_path}", "cloth.compare.fabrics=[stiff]", f"cloth.compare.heldout=[{tmp_path / 'stiff'}]",
            *[f"cloth.compare.{m}=[{files[m]}]" for m in sets], f"cloth.compare.anneal_traces=[{trace},{trace}]",
            f"cloth.compare.cmaes_traces=[{trace},{trace}]", f"cloth.compare.joint_traces=[{trace}]",
            "cloth.compare.chaos_draws=2"]
    whole = tmp_path / "whole"
    compare_stage.run(_cfg(*args, f"paths.out={whole}"))
    assert sims["n"] == 6 and not (whole / ".compare_cloth.checkpoint").exists()  # 3 estimates, then their copies
    doc = yaml.safe_load((whole / "compare.yaml").read_text())
    err = dict(zip(doc["methods"], doc["heldout_error"][0]))
    assert err["cmaes"] > 1.5 * max(err["anneal"], err["joint"]), err  # the soft twin's set, far off the stiff footage
    out = tmp_path / "resumed"
    _run_killed(compare_stage.run, _cfg(*args, f"paths.out={out}"), sims, at=4)  # killed at the second copy
    assert len((out / ".compare_cloth.checkpoint" / "copies" / "fabric0.jsonl").read_text().splitlines()) == 1 + 1
    compare_stage.run(_cfg(*args, f"paths.out={out}"))
    assert sims["n"] == 2  # the two copies not logged
    for f in ("compare.yaml", "compare.csv"):
        assert (out / f).read_bytes() == (whole / f).read_bytes()
    assert not (out / ".compare_cloth.checkpoint").exists()
