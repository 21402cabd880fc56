"""One small throw through the rigid CLIs (reality -> segment -> fit -> score), recovery checked
against the truth, and bad inputs that must end with one line naming the problem."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from vidsim.io.paths import REPO_ROOT
from conftest import assert_footage_holds_no_truth, truth_hidden

# a shorter clip than the study's (30 throw frames, 8 background frames), full 640x480, one start
SCENE = ["rigid.reality.n_frames=30", "rigid.reality.n_background=8", "log.progress=false", "log.rerun=false"]
FIT = ["rigid.fit.multistart=none", "rigid.fit.max_scale=0.5"]


def _cli(stage: str, results: Path, *args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1", PYOPENGL_PLATFORM="egl")
    return subprocess.run([sys.executable, "-m", f"vidsim.cli.{stage}", f"paths.results={results}", *args],
                          cwd=REPO_ROOT, capture_output=True, text=True, env=env, timeout=300)


def _ok(r: subprocess.CompletedProcess) -> None:
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]


def _one_line_error(r: subprocess.CompletedProcess, *words: str) -> str:
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-3000:]
    err = r.stderr.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    return err


@pytest.fixture(scope="module")
def throw(tmp_path_factory):
    res = tmp_path_factory.mktemp("rigid")
    foot = res / "footage" / "rigid_t7"
    _ok(_cli("reality_rigid", res, "rigid.seed=7", f"paths.out={foot}", *SCENE))
    return res, foot


@pytest.mark.slow
def test_throw_through_the_stages_is_recovered(throw):
    res, foot = throw
    out = res / "rigid" / "t7"
    # the truth and the ground-truth masks sit beside the footage folder, never in it
    assert (res / "footage" / "rigid_t7.truth.yaml").is_file()
    assert (res / "footage" / "rigid_t7.truth_masks.npz").is_file()
    meta = yaml.safe_load((foot / "meta.yaml").read_text())
    assert "initial_guess" in meta and "stand-in for the user's rough guess" in meta["initial_guess_protocol"]
    assert not {"omega_world", "effects", "camera"} & set(meta)
    assert (res / "footage" / "rigid_t7.reality.rrd").is_file()
    assert_footage_holds_no_truth(foot)
    with truth_hidden(foot):  # the estimator stages must not need it
        _ok(_cli("segment", res, f"paths.footage={foot}", f"paths.out={out}", *SCENE))
        with np.load(out / "masks.npz") as z:
            assert z["masks"].dtype == bool and z["masks"].shape == (38, 480, 640) and z["times"].shape == (38,)
        _ok(_cli("fit_rigid", res, f"paths.footage={foot}", f"paths.out={out}", *SCENE, *FIT))
    for f in ("fit.yaml", "overlay.mp4", "errors.png", "rigid.rrd"):
        assert (out / f).is_file(), f
    assert not (out / ".fit_rigid.stages.jsonl").exists()  # the checkpoint goes once fit.yaml is written
    _ok(_cli("score_rigid", res, f"paths.footage={foot}", f"paths.out={out}", *SCENE))
    s = yaml.safe_load((out / "score.yaml").read_text())
    e = s["errors"]
    # the criteria, from a guess 30 deg / 30 % / 20 % / 10 cm / 10 deg off
    assert s["success"], s
    assert e["orientation_deg"] < 5 and e["gravity_deg"] < 1 and e["mean_iou"] > 0.97
    assert s["segmentation"]["mean_iou"] > 0.95
    # the fit's initial state differs from the guess it started from (the descent did the work)
    fit = yaml.safe_load((out / "fit.yaml").read_text())
    g = meta["initial_guess"]
    assert np.linalg.norm(np.subtract(fit["position"], g["position"])) > 0.02
    _run_in_process("rigid_summary", res, f"rigid.paths.scores='{out / 'score.yaml'}'", f"paths.out={res / 'rigid'}")
    csv = (res / "rigid" / "summary.csv").read_text().splitlines()
    assert len(csv) == 2 and csv[1].startswith("t7,7,True")


def _run_in_process(stage: str, results: Path, *args: str) -> None:
    """Compose the stage's config and call its ``run`` (no process start-up: the error object itself)."""
    import importlib

    from hydra import compose, initialize_config_dir

    from vidsim.config import CONF_DIR

    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=[f"paths.results={results}", *args])
    importlib.import_module(f"vidsim.cli.{stage}").run(cfg)


@pytest.mark.slow
def test_bad_inputs_are_named(throw):
    from vidsim.errors import VidsimError
    from vidsim.io.atomic import write_npz

    res, foot = throw
    # footage in which no frame shows the object: the background frames only, repeated
    empty = res / "footage" / "rigid_empty"
    shutil.copytree(foot, empty, ignore=shutil.ignore_patterns("*.rrd", "contact_sheet.png"))
    frames = sorted((empty / "frames").iterdir())
    for p in frames[8:]:
        shutil.copy(frames[0], p)
    with pytest.raises(VidsimError, match="rigid_empty.*empty silhouette in every frame"):
        _run_in_process("segment", res, f"paths.footage={empty}", f"paths.out={res / 'rigid' / 'empty'}", *SCENE)
    # the fit given all-empty masks names the masks file
    times = np.loadtxt(foot / "times.csv", skiprows=1)
    write_npz(res / "rigid" / "empty" / "masks.npz", masks=np.zeros((len(times), 480, 640), bool), times=times)
    with pytest.raises(VidsimError, match="masks.npz.*empty silhouette"):
        _run_in_process("fit_rigid", res, f"paths.footage={foot}", f"paths.out={res / 'rigid' / 'empty'}", *SCENE)

    def with_meta(name: str, edit) -> Path:
        d = res / "footage" / f"rigid_{name}"
        shutil.copytree(foot, d, ignore=shutil.ignore_patterns("*.rrd", "contact_sheet.png"))
        meta = yaml.safe_load((foot / "meta.yaml").read_text())
        edit(meta)
        (d / "meta.yaml").write_text(yaml.safe_dump(meta))
        return d

    # silhouettes of this throw that need no other test's output (the segment stage's masks are
    # written by test_throw_through_the_stages_is_recovered): the bad metas below must be named
    # before any fitting, so which valid silhouettes they come with does not matter
    with np.load(res / "footage" / "rigid_t7.truth_masks.npz") as z:
        write_npz(res / "rigid" / "given" / "masks.npz", masks=z["masks"], times=z["times"])
    masks_arg = f"rigid.paths.masks={res / 'rigid' / 'given' / 'masks.npz'}"
    cases = [
        ("noobject", lambda m: m.pop("object"), r"meta\.yaml: missing field 'object'"),
        ("badmass", lambda m: m["object"].update(mass=-1.0), r"meta\.yaml: object: body: 'mass' must be positive.*-1\.0"),
        # a word where a number belongs was numpy's traceback; a NaN t0 a motionless "fit" with no error
        ("wordtilt", lambda m: m["initial_guess"].update(tilt="abc"),
         r"meta\.yaml.*initial guess: 'tilt' must be a number \(rad\), got 'abc'"),
        ("nant0", lambda m: m["initial_guess"].update(t0=float("nan")),
         r"meta\.yaml.*initial guess: 't0' must be a finite number \(s\), got nan"),
        # the last case is also run through the command line below
        ("nogravity", lambda m: m.update(gravity_magnitude=0.0), r"meta\.yaml: field 'gravity_magnitude' = 0\.0"),
    ]
    for name, edit, pattern in cases:
        d = with_meta(name, edit)
        args = (f"paths.footage={d}", masks_arg, f"paths.out={res / 'rigid' / name}", *SCENE)
        with pytest.raises(VidsimError, match=pattern):
            _run_in_process("fit_rigid", res, *args)
        assert not (res / "rigid" / name / "fit.yaml").exists()
    # through the command line: one line on stderr, exit code 2, no traceback
    r = _cli("fit_rigid", res, *args)
    _one_line_error(r, "meta.yaml", "gravity_magnitude", "0.0")
    r = _cli("fit_rigid", res, f"paths.footage={res / 'footage' / 'rigid_wordtilt'}", masks_arg,
             f"paths.out={res / 'rigid' / 'wordtilt'}", *SCENE)
    _one_line_error(r, "meta.yaml", "'tilt' must be a number (rad)", "'abc'")
