"""EditSpec validation: bad configs fail with a message naming the key and value."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml

from vidsim.fluid.edit import EditSpec, EditSpecError

BASE = {
    "grid": {"height": 32, "width": 32},
    "sources": [{"name": "s", "box": [10, 2, 20, 3], "distribution": [["a", 0.5], ["b", 0.5]]}],
    "sinks": [{"name": "a", "box": [0, 28, 10, 31]}, {"name": "b", "box": [22, 28, 32, 31]}],
}


def _bad(mut, match):
    d = copy.deepcopy(BASE)
    mut(d)
    with pytest.raises(EditSpecError, match=match):
        EditSpec.from_dict(d)


def test_valid_and_rasterised():
    spec = EditSpec.from_dict(BASE)
    prob = spec.rasterize()
    assert prob.particles.shape == (10, 2)
    assert list(prob.desired) == [0] * 5 + [1] * 5  # left half to sink a, in order along x


def test_errors_name_the_key():
    _bad(lambda d: d.update(colour="red"), r"unknown key\(s\) \['colour'\]")
    _bad(lambda d: d["sources"][0].update(speed=3), r"sources\[0\]: unknown key")
    _bad(lambda d: d["sinks"][1].update(box=[22, 28, 40, 31]), r"sinks\[1\]\.box=\[22, 28, 40, 31\] lies outside")
    _bad(lambda d: d["sources"][0].update(distribution=[["a", 0.5], ["c", 0.5]]), r"names sink 'c'")
    _bad(lambda d: d["sources"][0].update(distribution=[["a", 0.5], ["b", 0.4]]), "sum to 0.9")
    _bad(lambda d: d.update(constraints=[{"stroke": {"points": [[1, 1], [40, 1]]}}]),
         r"constraints\[0\]\.stroke\.points\[1\]=\[40.0, 1.0\] lies outside")
    _bad(lambda d: d.update(constraints=[{"paste": {"from": [0, 0, 8, 8], "to": [28, 0]}}]),
         r"constraints\[0\]\.paste\.to \(pasted box\)")
    _bad(lambda d: d.update(optimizer={"init": "magic"}), r"optimizer\.init='magic'")
    _bad(lambda d: d.update(render={"mode": "paint"}), r"render\.mode='paint'")
    _bad(lambda d: d.update(render={"blend": "soft"}), r"render\.blend='soft', expected one of \['linear', 'variance', 'multiband'\]")
    _bad(lambda d: d.update(render={"velocity_noise": -0.1}), r"render\.velocity_noise=-0.1")
    # overlapping sinks (a inside b): both named, the overlap given
    _bad(lambda d: d["sinks"][1].update(box=[0, 26, 32, 32]),
         r"sinks\[0\] \('a', box \[0, 28, 10, 31\]\) and sinks\[1\] \('b', box \[0, 26, 32, 32\]\) overlap in "
         r"\[0, 28, 10, 31\]")
    _bad(lambda d: d["sinks"][1].update(box=[9, 30, 20, 32]), r"overlap in \[9, 30, 10, 31\]")  # corners overlap
    # a wall across the grid: sink b cannot be reached from the source
    _bad(lambda d: d.update(obstacles=[{"box": [0, 15, 32, 17]}]), "sink 'a' cannot be reached")


def test_obstacles_in_the_footage_apart_from_added_ones():
    d = copy.deepcopy(BASE)
    d["obstacles"] = [{"box": [2, 10, 6, 14], "in_footage": True}, {"center": [25.0, 12.0], "radii": [2.0, 2.0]}]
    spec = EditSpec.from_dict(d)
    assert [o.in_footage for o in spec.obstacles] == [True, False]
    shown, added = spec.solid_mask(in_footage=True), spec.solid_mask(in_footage=False)
    assert shown.sum() == 16 and shown[10:14, 2:6].all() and not (shown & added).any()
    assert np.array_equal(shown | added, spec.solid_mask())
    _bad(lambda d: d.update(obstacles=[{"box": [2, 10, 6, 14], "in_footage": "yes"}]),
         r"obstacles\[0\]\.in_footage='yes', expected true or false")


def test_added_obstacles_take_the_closest_footage_obstacle():
    """An added obstacle is drawn from the ``in_footage`` obstacle of its kind with the least
    deformation (|log sx| + |log sy| between the half-sizes), ties to the first declared; none
    without an ``in_footage`` obstacle. Half-sizes: an ellipse's radii + 1/2, a box's half side."""
    d = copy.deepcopy(BASE)
    d["obstacles"] = [{"center": [5.0, 12.0], "radii": [3.0, 1.5], "in_footage": True},   # 0
                      {"center": [5.0, 20.0], "radii": [1.5, 1.5], "in_footage": True},   # 1
                      {"box": [26, 10, 30, 13], "in_footage": True},                      # 2
                      {"center": [15.0, 12.0], "radii": [2.5, 1.0]},                      # 3: closest to 0
                      {"center": [15.0, 20.0], "radii": [1.0, 1.0]},                      # 4: closest to 1
                      {"box": [10, 15, 14, 19]}]   # 5: the box 2, though the ellipse 1 has its size
    spec = EditSpec.from_dict(d)
    assert spec.transplant_sources() == (None, None, None, 0, 1, 2)
    assert spec.obstacles[2].extent() == ((27.5, 11.0), (2.0, 1.5))
    assert spec.obstacles[3].extent() == ((15.0, 12.0), (3.0, 1.5))
    assert spec.obstacles[5].extent()[1] == spec.obstacles[1].extent()[1] == (2.0, 2.0)
    # a tie (two equal footage obstacles) goes to the first declared; no footage obstacle: none
    d["obstacles"] = [d["obstacles"][1], {"center": [25.0, 20.0], "radii": [1.5, 1.5], "in_footage": True},
                      {"center": [15.0, 20.0], "radii": [1.0, 1.0]}]
    assert EditSpec.from_dict(d).transplant_sources() == (None, None, 0)
    d["obstacles"] = [{"center": [15.0, 20.0], "radii": [1.0, 1.0]}]
    assert EditSpec.from_dict(d).transplant_sources() == (None,)


def test_added_obstacles_switch():
    assert EditSpec.from_dict(BASE).render.added_obstacles == "transplant"
    d = copy.deepcopy(BASE)
    d["render"] = {"added_obstacles": "patches"}
    assert EditSpec.from_dict(d).render.added_obstacles == "patches"
    _bad(lambda d: d.update(render={"added_obstacles": "paint"}),
         r"render\.added_obstacles='paint', expected one of \['transplant', 'patches'\]")
    _bad(lambda d: d.update(render={"added_obstacle": "patches"}), r"render: unknown key\(s\) \['added_obstacle'\]")


def test_touching_sinks_are_accepted():
    d = copy.deepcopy(BASE)
    d["sinks"][1]["box"] = [10, 28, 32, 31]  # shares the edge x = 10 with sink a, no node in both
    prob = EditSpec.from_dict(d).rasterize()
    assert (prob.sink_id[28:31, :10] == 0).all() and (prob.sink_id[28:31, 10:] == 1).all()


def test_doc_examples_validate():
    root = Path(__file__).resolve().parents[3] / "docs" / "fluid_edits"
    files = sorted(root.glob("*.yaml"))
    assert len(files) >= 4
    for f in files:
        d = yaml.safe_load(f.read_text())
        EditSpec.from_dict(d)
