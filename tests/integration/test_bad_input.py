"""Bad input, table-driven: every case ends with exit code 2 and ONE line that names the file,
field or value, no traceback, and no output left behind.

Each case mutates a valid footage folder (or the command line) and runs a real stage process.
Cases of the stage families (negative stiffness, empty silhouettes, unreachable sinks, ...) are
added to CASES by the same pattern.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Callable

import cv2
import numpy as np
import pytest
import yaml

from vidsim.io.footage import write_footage
from vidsim.video.camera import PinholeCamera, intrinsics


def _valid_footage(folder: Path) -> Path:
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 255, (4, 48, 64, 3), dtype=np.uint8)
    cam = PinholeCamera(intrinsics(60.0, None, 31.5, 23.5), width=64, height=48)
    write_footage(folder, frames, np.arange(4) / 30.0, {"camera": cam}, {"object": {"mass_kg": 0.2}})
    return folder


def _edit_yaml(path: Path, fn: Callable[[dict], None]) -> None:
    d = yaml.safe_load(path.read_text())
    fn(d)
    path.write_text(yaml.safe_dump(d))


def _truncated_video(f: Path, shared: Path | None) -> None:
    if shared is None:
        pytest.skip("real data folder absent")
    for p in (f / "frames").iterdir():
        p.unlink()
    (f / "frames").rmdir()
    (f / "times.csv").unlink()
    data = (shared / "tracklab_physics" / "verticalToss.webm").read_bytes()
    (f / "video.webm").write_bytes(data[: len(data) // 2])
    _edit_yaml(f / "calibration.yaml", lambda d: d["camera"].update(width=640, height=480))


def _binary_meta(f, _):
    (f / "meta.yaml").write_bytes(bytes(range(128, 256)) * 4)  # random-looking bytes, not UTF-8


def _n_frames_mismatch(f, _):
    _edit_yaml(f / "meta.yaml", lambda d: d.update(n_frames=50))


def _n_frames_text(f, _):
    _edit_yaml(f / "meta.yaml", lambda d: d.update(n_frames="4"))


def _zero_fps(f, _):
    _edit_yaml(f / "meta.yaml", lambda d: d.update(fps=0))


def _truncated_jpeg(f, _):
    for p in sorted((f / "frames").iterdir()):
        img = cv2.imread(str(p))
        p.unlink()
        cv2.imwrite(str(p.with_suffix(".jpg")), img)
    j = f / "frames" / "000001.jpg"
    data = j.read_bytes()
    j.write_bytes(data[: len(data) // 2])


def _zero_frames(f, _):
    for p in (f / "frames").iterdir():
        p.unlink()


def _sizes(f, _):
    cv2.imwrite(str(f / "frames" / "000002.png"), np.zeros((40, 64, 3), np.uint8))


def _backwards(f, _):
    (f / "times.csv").write_text("time_s\n0.0\n0.05\n0.04\n0.1\n")


def _singular_K(f, _):
    _edit_yaml(f / "calibration.yaml", lambda d: d["camera"].update(K=[[1, 0, 0], [0, 0, 0], [0, 0, 1]]))


def _size_mismatch(f, _):
    _edit_yaml(f / "calibration.yaml", lambda d: d["camera"].update(width=640))


def _corrupt_frame(f, _):
    (f / "frames" / "000001.png").write_bytes(b"not a png at all")


def _missing_calibration(f, _):
    (f / "calibration.yaml").unlink()


def _bad_yaml(f, _):
    (f / "meta.yaml").write_text("object: [unclosed\n")


def _nan_in_calibration(f, _):
    _edit_yaml(f / "calibration.yaml", lambda d: d["camera"].update(t=[0.0, float("nan"), 0.0]))


def _nothing(f, _):
    return None


# (id, mutate footage, extra overrides, text the one-line error must contain)
CASES = [
    ("truncated video", _truncated_video, [], "video.webm: video is truncated"),
    ("zero frames", _zero_frames, [], "zero frames"),
    ("frames of different sizes", _sizes, [], "000002.png: frame size 64x40 differs"),
    ("timestamps going backwards", _backwards, [], "times.csv: timestamps must increase"),
    ("singular camera matrix", _singular_K, [], "field 'K' is singular"),
    ("calibration vs frame size", _size_mismatch, [], "640x48 does not match the frames (64x48)"),
    ("corrupt frame", _corrupt_frame, [], "000001.png: not a readable image"),
    ("missing calibration file", _missing_calibration, [], "calibration.yaml: file is missing"),
    ("malformed YAML", _bad_yaml, [], "meta.yaml: not valid YAML"),
    ("NaN in calibration", _nan_in_calibration, [], "field 't' contains NaN"),
    ("missing meta.yaml field", _nothing, ["check.required_meta=[inertia]"], "meta.yaml: missing field(s) ['inertia']"),
    ("unknown config key", _nothing, ["camera.focal=3"], "camera.focal"),
    ("NaN config value", _nothing, ["camera.fx=nan"], "camera.fx = nan"),
    ("negative config value", _nothing, ["render.noise_sigma=-1"], "render.noise_sigma = -1"),
    ("negative noise of a family", _nothing, ["calibrate.noise_sigma=-1"], "calibrate.noise_sigma = -1"),
    ("path escaping results", _nothing, ["paths.out=../../outside"], "escapes the results folder"),
    ("negative stiffness", _nothing, ["cloth.reality.twin_params.stretch=-300"], "cloth.reality.twin_params.stretch = -300"),
    ("NaN in a cloth parameter", _nothing, ["cloth.reality.twin_params.bend=nan"], "cloth.reality.twin_params.bend = nan"),
    ("missing footage folder", None, [], "footage folder is missing"),
    # found by an audit of the stages' bad input (4 Dec 2026)
    ("meta.yaml not text", _binary_meta, [], "meta.yaml: not a text YAML file"),
    ("meta n_frames vs frames", _n_frames_mismatch, [], "field 'n_frames' = 50 but the folder holds 4 frames"),
    ("meta n_frames as text", _n_frames_text, [], "field 'n_frames' = '4': expected a whole number of frames"),
    ("zero frame rate in meta", _zero_fps, [], "field 'fps' = 0 is not valid"),
    ("truncated JPEG frame", _truncated_jpeg, [], "000001.jpg: truncated JPEG"),
    ("NaN in any setting", _nothing, ["fluid.flow.temporal_sigma=nan"], "fluid.flow.temporal_sigma = nan"),
    ("unknown key added with +", _nothing, ["+reality.fpss=3"], "reality.fpss (added with '+') is unknown"),
]


@pytest.mark.parametrize("name,mutate,overrides,expected", CASES, ids=[c[0] for c in CASES])
def test_bad_input_gives_one_clear_line(tmp_path, name, mutate, overrides, expected):
    from vidsim.io.paths import shared_data_dir

    shared = shared_data_dir() if shared_data_dir().is_dir() else None
    folder = tmp_path / "footage"
    if mutate is not None:
        _valid_footage(folder)
        mutate(folder, shared)
    results = tmp_path / "results"
    out = results / "check"
    r = subprocess.run(
        [sys.executable, "-m", "vidsim.cli.check_footage", f"paths.footage={folder}", f"paths.results={results}",
         f"paths.out={out}", *overrides],
        capture_output=True, text=True, timeout=120,
    )
    assert r.returncode == 2, f"{name}: exit code {r.returncode}, expected 2 (bad input)"
    assert "Traceback" not in r.stderr, r.stderr
    assert expected in r.stderr, r.stderr
    assert not out.exists() and not (tmp_path / "outside").exists(), "partial outputs left behind"
    lines = [ln for ln in r.stderr.splitlines() if ln.strip() and "OpenGL_accelerate" not in ln]
    assert len(lines) == 1, r.stderr


def test_valid_footage_passes(tmp_path):
    folder = _valid_footage(tmp_path / "footage")
    out = tmp_path / "results" / "check"
    r = subprocess.run([sys.executable, "-m", "vidsim.cli.check_footage", f"paths.footage={folder}",
                        f"paths.results={tmp_path / 'results'}", f"paths.out={out}"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    s = yaml.safe_load((out / "summary.yaml").read_text())
    assert s["n_frames"] == 4 and s["size_px"] == [64, 48]
    assert abs(s["frame_interval_s"]["median"] - 1 / 30) < 1e-9


@pytest.mark.parametrize("override,expected", [("cloth.reality.exposure=0", "cloth.reality.exposure must be in (0, 1]"),
                                               ("cloth.reality.fps=0", "cloth.reality.fps = 0.0 is not valid")])
def test_cloth_reality_settings_are_named_by_their_config_keys(tmp_path, override, expected):
    """Checked before anything is simulated, in the names a user sets (was 'FilmSettings.exposure',
    and 'fps, dt, size must be > 0' after the simulation had been set up)."""
    r = subprocess.run([sys.executable, "-m", "vidsim.cli.cloth_reality", f"paths.results={tmp_path}",
                        f"paths.out={tmp_path}/o", override], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and expected in r.stderr and "Traceback" not in r.stderr, r.stderr


@pytest.mark.parametrize("override", ["cloth.twin.perturb_sigma=-0.1", "cloth.twin.perturb_draws=-1",
                                      "cloth.twin.chaos_sigma=nan", "cloth.twin.chaos_draws=-2"])
def test_twin_score_perturbation_settings_are_checked_first(tmp_path, override):
    """A negative or non-finite scale or a negative draw count is refused by its name before any footage is read."""
    r = subprocess.run([sys.executable, "-m", "vidsim.cli.cloth_twin_score", f"paths.results={tmp_path}",
                        f"paths.out={tmp_path}/o", "cloth.twin.params=p.yaml", "cloth.twin.footage=f", override],
                       capture_output=True, text=True, timeout=120)
    key = override.split("=")[0]
    assert r.returncode == 2 and key in r.stderr and "Traceback" not in r.stderr, r.stderr


@pytest.mark.parametrize("module,override,expected", [
    ("reality_fluid", "fluid.reality.fps=0", "fluid.reality.fps=0.0: expected a finite number > 0"),
    ("reality_fluid", "fluid.reality.jacobi_iters=0", "fluid.reality.jacobi_iters=0: expected a whole number > 0"),
    ("fluid_piv_footage", "fluid.piv.fps=0", "fluid.piv.fps=0.0: expected a finite number > 0"),
    ("fluid_flow", "fluid.flow.arrow_step=0", "fluid.flow.arrow_step=0: expected a whole number > 0"),
])
def test_fluid_rates_and_counts_are_checked_before_any_work(tmp_path, module, override, expected):
    """A zero frame rate wrote times.csv = nan, inf, ... and exited 0; zero Jacobi iterations skipped the
    projection silently; a zero arrow step crashed after the flow was written (review, 5 Dec 2026)."""
    r = subprocess.run([sys.executable, "-m", f"vidsim.cli.{module}", f"paths.results={tmp_path}",
                        f"paths.out={tmp_path}/o", override], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and expected in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert not (tmp_path / "o").exists()


def test_a_malformed_stage_document_is_named_not_a_key_error(tmp_path):
    """A score.yaml with 'errors' but no 'success' gave KeyError: 'success' and a traceback (review,
    5 Dec 2026); the stage now names the file and the fields it lacks."""
    sc = tmp_path / "results" / "rigid" / "t1" / "score.yaml"
    sc.parent.mkdir(parents=True)
    sc.write_text(yaml.safe_dump({"errors": {"position_cm": 1.0}}))
    r = subprocess.run([sys.executable, "-m", "vidsim.cli.rigid_summary", f"paths.results={tmp_path / 'results'}",
                        f"paths.out={tmp_path / 'results' / 'rigid'}", f"rigid.paths.scores='{sc}'"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert "score.yaml: missing field(s)" in r.stderr and "'success'" in r.stderr
