"""The rigid config group: Hydra composition, mapping onto the optimiser/reality settings, named errors."""

from __future__ import annotations

import pytest
from hydra import compose, initialize_config_dir

from vidsim.config import CONF_DIR
from vidsim.config.rigid import validate_rigid
from vidsim.errors import ConfigError
from vidsim.reality.rigid import RigidRealityConfig
from vidsim.rigid.fit import FitConfig


def _cfg(*overrides: str):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose("config", overrides=["paths.out=x", *overrides])


def test_fit_settings_map_onto_the_optimiser():
    from vidsim.cli._rigid import fit_config

    c = _cfg("rigid.fit.max_scale=0.5", "rigid.fit.iter_scale=0.5", "rigid.fit.multistart=none")
    validate_rigid(c.rigid)
    fc = fit_config(c.rigid.fit, 9.80665)
    base = FitConfig()
    assert fc.multistart == "none" and fc.gravity == 9.80665
    assert max(s.scale for s in fc.screen + fc.refine + fc.final) == 0.5
    assert [s.maxiter for s in fc.final] == [round(s.maxiter / 2) for s in base.final]
    # defaults reproduce the optimiser's own defaults
    fd = fit_config(_cfg().rigid.fit, 9.81)
    assert fd.screen == base.screen and fd.refine == base.refine and fd.final == base.final


def test_reality_settings_map_onto_the_scene():
    c = _cfg("rigid.reality.n_frames=12", "rigid.reality.spin_max=6")
    from omegaconf import OmegaConf

    sc = RigidRealityConfig.from_schema(OmegaConf.to_container(c.rigid.reality))
    assert sc.n_frames == 12 and sc.spin == (4.0, 6.0)
    with pytest.raises(ValueError, match="unknown field"):
        RigidRealityConfig.from_schema({"n_frame": 3})


@pytest.mark.parametrize("override, key", [
    ("rigid.fit.multistart=random", "rigid.fit.multistart"),
    ("rigid.fit.max_scale=2", "rigid.fit.max_scale"),
    ("rigid.reality.fps=0", "rigid.reality.fps"),
    ("rigid.guess.orient_deg=-5", "rigid.guess.orient_deg"),
    ("rigid.reality.spin_min=20", "rigid.reality.spin_min"),
    ("rigid.overlay=avi", "rigid.overlay"),
])
def test_bad_values_name_the_key(override, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        validate_rigid(_cfg(override).rigid)
