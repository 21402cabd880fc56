"""The gap stages on bad input: exit code 2, one line naming the file, key or value, no output left."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from vidsim.io.footage import write_footage
from vidsim.rigid.body import t_object
from vidsim.video.camera import PinholeCamera, intrinsics


def _run(mod: str, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", mod, f"paths.results={cwd}", "log.rerun=false", *args],
                          capture_output=True, text=True, timeout=120)


def _one_line(p: subprocess.CompletedProcess) -> str:
    assert p.returncode == 2, p.stderr[-2000:]
    lines = [x for x in p.stderr.strip().splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in p.stderr, p.stderr[-2000:]
    return lines[0]


def test_diagnose_missing_footage_and_fit(tmp_path):
    line = _one_line(_run("vidsim.cli.diagnose", f"paths.out={tmp_path}/d", f"paths.footage={tmp_path}/nope",
                          f"gap.paths.masks={tmp_path}/m.npz", f"gap.paths.fit={tmp_path}/fit.yaml", cwd=tmp_path))
    assert "nope" in line and "missing" in line
    fo = tmp_path / "fo"
    cam = PinholeCamera(intrinsics(60.0, None, 31.5, 23.5), width=64, height=48)
    write_footage(fo, np.zeros((10, 48, 64, 3), np.uint8), np.arange(10) / 30.0, {"camera": cam},
                  {"object": t_object()[0].to_meta()})
    np.savez(tmp_path / "m.npz", masks=np.zeros((10, 48, 64), bool), times=np.arange(10) / 30.0)
    (tmp_path / "fit.yaml").write_text("position: [0, 0, 3]\nquaternion: [1, 0, 0, 0]\n")
    line = _one_line(_run("vidsim.cli.diagnose", f"paths.out={tmp_path}/d", f"paths.footage={fo}",
                          f"gap.paths.masks={tmp_path}/m.npz", f"gap.paths.fit={tmp_path}/fit.yaml", cwd=tmp_path))
    assert "fit.yaml" in line and "velocity" in line
    full = ("position: [0, 0, 3]\nquaternion: [1, 0, 0, 0]\nvelocity: fast\nomega_world: [0, 0, 1]\n"
            "tilt: 0\nroll: 0\nt0: 0.1\n")
    (tmp_path / "fit.yaml").write_text(full)
    line = _one_line(_run("vidsim.cli.diagnose", f"paths.out={tmp_path}/d", f"paths.footage={fo}",
                          f"gap.paths.masks={tmp_path}/m.npz", f"gap.paths.fit={tmp_path}/fit.yaml", cwd=tmp_path))
    assert "field 'velocity' = 'fast' is not numeric" in line
    (tmp_path / "fit.yaml").write_text(full.replace("fast", "[1, 0, 2]"))
    np.savez(tmp_path / "m.npz", masks=np.ones((10, 24, 32), bool), times=np.arange(10) / 30.0)
    line = _one_line(_run("vidsim.cli.diagnose", f"paths.out={tmp_path}/d", f"paths.footage={fo}",
                          f"gap.paths.masks={tmp_path}/m.npz", f"gap.paths.fit={tmp_path}/fit.yaml", cwd=tmp_path))
    assert "m.npz: masks are 32x24 but the camera is 64x48" in line
    assert not (tmp_path / "d").exists()


def test_suite_unknown_case_and_bad_candidate(tmp_path):
    line = _one_line(_run("vidsim.cli.gap_suite", f"paths.out={tmp_path}/s", "gap.only=[no_such_case]", cwd=tmp_path))
    assert "no_such_case" in line
    line = _one_line(_run("vidsim.cli.gap_suite", f"paths.out={tmp_path}/s", "gap.only=[null_a]",
                          "gap.diagnose.candidates=[lens_k1,warp_drive]", cwd=tmp_path))
    assert "warp_drive" in line
    assert not (tmp_path / "s").exists()


def test_cloth_suite_unknown_case_setting_and_label(tmp_path):
    line = _one_line(_run("vidsim.cli.gap_cloth_suite", f"paths.out={tmp_path}/c", "gap.cloth.only=[no_such_case]",
                          cwd=tmp_path))
    assert "no_such_case" in line
    line = _one_line(_run("vidsim.cli.gap_cloth_suite", f"paths.out={tmp_path}/c", "+gap.cloth.diagnose.topk=1",
                          cwd=tmp_path))
    assert "topk" in line and "top_k" in line
    line = _one_line(_run("vidsim.cli.gap_cloth_suite", f"paths.out={tmp_path}/c",
                          "+gap.cloth.cases.bad={label: warp_drive, seed: 1}", "gap.cloth.only=[bad]", cwd=tmp_path))
    assert "warp_drive" in line
    # a case's own twin parameters are checked before anything is filmed
    line = _one_line(_run("vidsim.cli.gap_cloth_suite", f"paths.out={tmp_path}/c",
                          "+gap.cloth.cases.bad={label: none, seed: 1, twin_params: {stiffness: 3.0}}",
                          "gap.cloth.only=[null_a,bad]", cwd=tmp_path))
    assert "gap.cloth.cases.bad" in line and "stiffness" in line
    assert not (tmp_path / "c").exists()


def test_diagnose_cloth_missing_footage_fit_and_bad_names(tmp_path):
    line = _one_line(_run("vidsim.cli.diagnose_cloth", f"paths.out={tmp_path}/d", f"paths.footage={tmp_path}/nope",
                          f"gap.paths.fit={tmp_path}/params.yaml", cwd=tmp_path))
    assert "nope" in line and "missing" in line
    fo = tmp_path / "fo"
    fo.mkdir()
    line = _one_line(_run("vidsim.cli.diagnose_cloth", f"paths.out={tmp_path}/d", f"paths.footage={fo}",
                          f"gap.paths.fit={tmp_path}/params.yaml", cwd=tmp_path))
    assert "params.yaml" in line and "missing" in line
    (tmp_path / "params.yaml").write_text("chosen: exp1\n")
    line = _one_line(_run("vidsim.cli.diagnose_cloth", f"paths.out={tmp_path}/d", f"paths.footage={fo}",
                          f"gap.paths.fit={tmp_path}/params.yaml", cwd=tmp_path))
    assert "params.yaml" in line and "'params'" in line
    (tmp_path / "params.yaml").write_text("params: {stretch: 300.0}\nestimated: [stretch, stiffnes]\n")
    line = _one_line(_run("vidsim.cli.diagnose_cloth", f"paths.out={tmp_path}/d", f"paths.footage={fo}",
                          f"gap.paths.fit={tmp_path}/params.yaml", cwd=tmp_path))
    assert "stiffnes" in line
    (tmp_path / "params.yaml").write_text("params: {stretch: 300.0}\n")
    line = _one_line(_run("vidsim.cli.diagnose_cloth", f"paths.out={tmp_path}/d", f"paths.footage={fo}",
                          f"gap.paths.fit={tmp_path}/params.yaml", "+gap.cloth.diagnose.topk=1", cwd=tmp_path))
    assert "topk" in line and "top_k" in line
    assert not (tmp_path / "d").exists()


def test_diagnose_cloth_reads_the_estimated_names(tmp_path):
    """The fit file's own list wins; else cloth.fit.estimate; an empty one means the whole space."""
    from omegaconf import OmegaConf

    from vidsim.cli.diagnose_cloth import read_fit
    from vidsim.config.cloth import ClothConfig

    cfg = OmegaConf.create({"cloth": OmegaConf.structured(ClothConfig())})
    f = tmp_path / "fit.yaml"
    f.write_text("params: {stretch: 300.0, bend: 3.0e-6}\nestimated: [stretch]\n")
    p, est = read_fit(str(f), cfg)
    assert est == ["stretch"] and p.stretch == 300.0 and p.bend == 3.0e-6
    f.write_text("params: {stretch: 300.0}\n")
    assert read_fit(str(f), cfg)[1] == list(cfg.cloth.fit.space) and len(list(cfg.cloth.fit.space)) == 9
    cfg.cloth.fit.estimate = ["bend", "shear"]
    assert read_fit(str(f), cfg)[1] == ["bend", "shear"]
