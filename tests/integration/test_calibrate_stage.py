"""The calibrate stage: a scene's camera and projector recovered from rendered target images."""

from __future__ import annotations

import csv
import subprocess
import sys

import yaml


def test_calibrate_stage_recovers_camera_and_projector(tmp_path):
    out = tmp_path / "calib"
    r = subprocess.run([sys.executable, "-m", "vidsim.cli.calibrate", f"paths.results={tmp_path}", f"paths.out={out}", "projector=stripes",
                        "log.rerun=false"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    calib = yaml.safe_load((out / "calibration.yaml").read_text())
    assert {"camera", "projector"} <= set(calib)
    assert calib["rms_px"] < 0.5 and calib["projector_rms_px"] < 0.5
    rows = {row["quantity"]: row for row in csv.DictReader((out / "summary.csv").open())}
    assert abs(float(rows["camera_fx"]["difference"])) < 0.005 * 700
    assert float(rows["camera_scene_reprojection_px_median"]["estimated"]) < 0.5
    assert abs(float(rows["projector_fx"]["difference"])) < 0.01 * 900
    assert float(rows["projector_centre_m"]["difference"]) < 0.03
    assert float(rows["projector_scene_reprojection_px_median"]["estimated"]) < 1.5


def test_calibrate_real_reproduces_opencvs_reference_and_takes_your_own_board(tmp_path, shared_data):
    """The real chessboard set through the stage: OpenCV's reference result (RMS 0.3926 px, fx 535.9)
    with the defaults; with calibrate.real.* another image set is calibrated without a reference."""
    board = shared_data / "opencv_chessboard"
    common = [f"paths.results={tmp_path}", f"paths.footage={board}", "log.rerun=false"]
    r = subprocess.run([sys.executable, "-m", "vidsim.cli.calibrate_real", f"paths.out={tmp_path / 'ref'}", *common],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    rows = {row["quantity"]: row for row in csv.DictReader((tmp_path / "ref" / "summary.csv").open())}
    assert abs(float(rows["rms_px"]["vidsim"]) - 0.3926) < 0.001 and abs(float(rows["fx"]["difference"])) < 0.5
    cam = yaml.safe_load((tmp_path / "ref" / "calibration.yaml").read_text())["camera"]
    assert (cam["width"], cam["height"]) == (640, 480)
    # "your own board": the right-hand images, aspect ratio free; no reference column
    r = subprocess.run([sys.executable, "-m", "vidsim.cli.calibrate_real", f"paths.out={tmp_path / 'own'}", *common,
                        "calibrate.real.glob=right*", "calibrate.real.fix_aspect=false"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    rows = {row["quantity"]: row for row in csv.DictReader((tmp_path / "own" / "summary.csv").open())}
    assert set(next(iter(rows.values()))) == {"quantity", "vidsim"}
    assert float(rows["rms_px"]["vidsim"]) < 1.0 and float(rows["fx"]["vidsim"]) != float(rows["fy"]["vidsim"])
    r = subprocess.run([sys.executable, "-m", "vidsim.cli.calibrate_real", f"paths.out={tmp_path / 'none'}", *common,
                        "calibrate.real.glob=nothing*"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "no images match calibrate.real.glob = 'nothing*'" in r.stderr, r.stderr[-2000:]
