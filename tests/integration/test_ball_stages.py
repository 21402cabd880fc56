"""The real ball toss (../shared/data/tracklab_physics/verticalToss.webm) through the two stages that
read it, as the README reports them: rigid_ball (ball found in 96 % of in-view frames, perspective
free-flight RMS 1.57 px with the container's timestamps against 0.60 px at a constant 30 fps) and
gap_ball (frame timing named for the container's clock, nothing for the constant rate). Real data:
skipped where the shared data is absent."""

from __future__ import annotations

import json
import subprocess
import sys

import yaml

from vidsim.io.paths import REPO_ROOT


def _cli(stage: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", f"vidsim.cli.{stage}", *args, "log.rerun=false"], cwd=REPO_ROOT,
                          capture_output=True, text=True, timeout=300)


def test_real_toss_is_tracked_fitted_and_its_clock_diagnosed(tmp_path, shared_data):
    video = shared_data / "tracklab_physics" / "verticalToss.webm"
    common = [f"paths.results={tmp_path}", f"rigid.paths.video={video}"]
    r = _cli("rigid_ball", *common, f"paths.out={tmp_path / 'ball'}")
    assert r.returncode == 0, r.stderr[-2000:]
    doc = yaml.safe_load((tmp_path / "ball" / "ball.yaml").read_text())
    assert doc["in_view"]["found_fraction"] > 0.95 and len(doc["flights"]) == 3 and "warning" not in doc
    rms = doc["rms_px"]
    assert abs(rms["perspective_timestamps"] - 1.57) < 0.05 and abs(rms["perspective_constant_fps"] - 0.60) < 0.05
    r = _cli("gap_ball", *common, f"paths.out={tmp_path / 'gap'}")
    assert r.returncode == 0, r.stderr[-2000:]
    g = json.loads((tmp_path / "gap" / "ball_gap.json").read_text())["readings"]
    assert g["container_timestamps"]["named"] == ["time_jitter"]
    assert g["constant_30_fps"]["named"] == []
