"""The tests' guard against footage that carries its truth (tests/conftest.py): it must catch a
planted leak and must not cry wolf over a number that only happens to equal a truth value."""

from __future__ import annotations

import re

import pytest
import yaml
from conftest import assert_footage_holds_no_truth

TRUTH = {
    "kind": "twin",
    "params": {"bend": 3e-06, "stretch": 300.0, "shear": 40.0, "density": 0.2},
    "position": [-0.274960933294733, 0.5426966754661362, 3.299651572695835],
    "camera": {"K": [[560.0, 0.0, 159.5], [0, 560.0, 119.5], [0, 0, 1]],
               "R": [[0.7666863181787941, 0.6420218761985024, 0.0], [0, 0, -1], [0.6420218761985024, -0.7666863181787941, 0]],
               "t": [0.0, 0.8200000000000002, 1.6043067038443741]},
}
CLEAN_META = {"scene": "cloth", "areal_density": 0.2, "size_m": 0.3, "projector_pattern": {"period_px": 10.0},
              "object": {"width_px": 300, "shear_note": 40}}


def footage(tmp_path, meta: dict, times: str = "frame,t\n0,0.0\n1,0.0333\n") -> str:
    folder = tmp_path / "cloth_twin_exp1"
    folder.mkdir()
    (folder / "meta.yaml").write_text(yaml.safe_dump(meta))
    (folder / "times.csv").write_text(times)
    (tmp_path / "cloth_twin_exp1.truth.yaml").write_text(yaml.safe_dump(TRUTH))
    return str(folder)


def test_clean_footage_passes_though_round_numbers_coincide(tmp_path):
    # 300, 40, 0.2 (the measured areal density) and 560 stand in the folder under other names
    assert_footage_holds_no_truth(footage(tmp_path, {**CLEAN_META, "focal_px": 560.0}))


@pytest.mark.parametrize("leak, field", [
    ({"fabric": {"stretch": 300.0}}, "params.stretch"),                     # a round target under its own name
    ({"initial_guess": {"p": [0.1, 0.5426966754661362]}}, "position[1]"),  # a distinctive one anywhere
    ({"camera": {"t": [0.0, 0.82, 1.6043067038443741]}}, "camera.t[2]"),   # the true pose
])
def test_planted_leak_in_meta_is_caught(tmp_path, leak, field):
    with pytest.raises(AssertionError, match=r"meta\.yaml holds the truth .*" + re.escape(field)):
        assert_footage_holds_no_truth(footage(tmp_path, {**CLEAN_META, **leak}))


def test_planted_leak_in_csv_is_caught(tmp_path):
    with pytest.raises(AssertionError, match=r"times\.csv holds the truth .*position\[2\]"):
        assert_footage_holds_no_truth(footage(tmp_path, CLEAN_META, "frame,t\n0,3.299651572695835\n"))
