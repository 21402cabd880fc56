"""Config schemas: typos and non-physical values are errors that name the key."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException

from vidsim.config import CONF_DIR, camera_from_config, validate
from vidsim.errors import ConfigError


def _compose(*overrides: str):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose("config", overrides=["paths.out=/tmp/vidsim-test", *overrides])


def test_default_config_composes_and_validates():
    cfg = _compose()
    validate(cfg)
    cam = camera_from_config(cfg.camera)
    assert (cam.width, cam.height) == (640, 480)


@pytest.mark.parametrize("override", ["camera.fxx=3", "effects.dynamics.air_dragg=1", "render.noise=1"])
def test_misspelt_key_is_an_error_naming_it(override):
    key = override.split("=")[0]
    with pytest.raises(ConfigCompositionException, match=key.replace(".", r"\.")):
        _compose(override)


def test_wrong_type_is_an_error():
    with pytest.raises(ConfigCompositionException, match="camera.fx"):
        _compose("camera.fx=abc")


@pytest.mark.parametrize(
    "override,key",
    [
        ("camera.fx=-5", "camera.fx"),
        ("camera.fx=nan", "camera.fx"),
        ("reality.n_frames=0", "reality.n_frames"),
        ("effects.dynamics.air_drag=-1", "effects.dynamics.air_drag"),
        ("camera.target=[0,-3.5,1.1]", "camera.target"),
        ("render.backend=opengl", "render.backend"),
    ],
)
def test_non_physical_values_are_rejected(override, key):
    cfg = _compose(override)
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        validate(cfg)


def test_camera_from_config_looks_at_target():
    cfg = _compose("camera.roll_deg=0")
    cam = camera_from_config(cfg.camera)
    uv = cam.project(np.array(cfg.camera.target, float)[None])[0]
    assert np.allclose(uv, [(cam.width - 1) / 2, (cam.height - 1) / 2], atol=1e-6)
    # world up appears up in the image (smaller row index)
    above = cam.project(np.array(cfg.camera.target, float)[None] + [0, 0, 0.2])[0]
    assert above[1] < uv[1]


def test_cli_bad_key_gives_one_clear_line(tmp_path):
    r = subprocess.run(
        [sys.executable, "-m", "vidsim.cli.reality_demo", f"paths.results={tmp_path}", f"paths.out={tmp_path}/o", "camera.fxx=3"],
        capture_output=True, text=True, timeout=120,
    )
    assert r.returncode != 0
    assert "camera.fxx" in r.stderr
    assert "Traceback" not in r.stderr
    r = subprocess.run(
        [sys.executable, "-m", "vidsim.cli.reality_demo", f"paths.results={tmp_path}", f"paths.out={tmp_path}/o",
         "+reality.fpss=3"], capture_output=True, text=True, timeout=120,
    )
    assert r.returncode == 2 and "reality.fpss" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("override,bad", [("+rigid.fit.max_iter=5", "rigid.fit.max_iter"),
                                          ("++cloth.reality.wind.x=1", "cloth.reality.wind"),
                                          ("+fluid.flow.sigma=2", "fluid.flow.sigma")])
def test_a_key_added_with_plus_under_a_schema_is_an_error(override, bad):
    """Hydra adds any '+' key and the stage would ignore it silently (a typo passed as a setting);
    under free-form mappings (cloth.fit.fixed, gap.cloth.diagnose, gap cases) '+' is how settings
    are given and passes."""
    from vidsim.cli._app import unknown_added_key

    msg = unknown_added_key(_compose(override), [override])
    assert msg is not None and bad in msg and "unknown" in msg
    for ok in ("+cloth.fit.fixed.bend=1e-5", "+gap.cloth.diagnose.top_k=2", "+gap.cloth.scene.budget=31",
               "+gap.cases.magnus9={label: magnus, seed: 9}"):
        assert unknown_added_key(_compose(ok), [ok]) is None, ok


def test_cli_missing_calibration_names_the_file(tmp_path):
    missing = tmp_path / "nope" / "calibration.yaml"
    r = subprocess.run(
        [sys.executable, "-m", "vidsim.cli.reality_demo", f"paths.results={tmp_path}", f"paths.out={tmp_path}/o", f"paths.calibration={missing}"],
        capture_output=True, text=True, timeout=120,
    )
    assert r.returncode == 2
    assert str(missing) in r.stderr and "missing" in r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "o").exists()


def test_the_full_workflow_config_sets_every_key_the_quick_one_sets():
    """`--configfile workflow/config/full.yaml` is merged over quick.yaml (the Snakefile's configfile),
    nested mappings key by key: a key only quick.yaml sets would keep its quick value in the
    seed-scale study. Until 6 Dec 2026 quick's `overrides.select_cloth` (a joint polish after the
    selection) leaked into the full study that way."""
    import yaml

    from vidsim.config import CONF_DIR

    wf = Path(CONF_DIR).parent / "workflow" / "config"
    quick, full = (yaml.safe_load((wf / f"{n}.yaml").read_text()) for n in ("quick", "full"))

    def missing(a: dict, b: dict, path: str = "") -> list[str]:
        out = []
        for k, v in a.items():
            p = f"{path}.{k}" if path else str(k)
            if not isinstance(b, dict) or k not in b:
                out.append(p)
            elif isinstance(v, dict):
                out += missing(v, b[k], p)
        return out

    assert missing(quick, full) == []
    assert full["overrides"]["select_cloth"] == ""  # the seed's selection alone at full scale
