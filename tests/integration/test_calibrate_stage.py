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
