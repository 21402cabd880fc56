"""Pieces the fluid stages rely on: footage labels, optimiser checkpoint/resume, flow colours,
the metrics table's target checks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vidsim.errors import ConfigError
from vidsim.fluid.edit import EditSpec
from vidsim.fluid.footage import FootageLabelError, footage_folder_name, resolve_footage
from vidsim.fluid.optimize import edit_field
from vidsim.fluid.report import metrics_rows, rows_to_csv
from vidsim.fluid.viz import arrow_grid, color_wheel, flow_to_color
from vidsim.io.atomic import write_npz

THREE = {
    "grid": {"height": 48, "width": 48},
    "sources": [{"name": "top", "box": [10, 2, 38, 4], "distribution": [["a", 0.3], ["b", 0.4], ["c", 0.3]]}],
    "sinks": [{"name": "a", "box": [1, 42, 12, 46]}, {"name": "b", "box": [18, 42, 30, 46]},
              {"name": "c", "box": [36, 42, 47, 46]}],
    "obstacles": [{"center": [24, 22], "radii": [6, 3]}],
    "weights": {"flow": 1.0, "smooth": 0.2, "neighborhood": 0.2},
    "optimizer": {"iterations": 40},
}


def test_footage_labels_resolve_to_the_reality_stages_folders(tmp_path):
    assert footage_folder_name("synthetic:waterfall") == "fluid_waterfall"
    assert footage_folder_name("piv:karman") == "piv_karman"
    assert resolve_footage("synthetic:flame", tmp_path) == tmp_path / "footage" / "fluid_flame"
    assert resolve_footage("my/own/footage", tmp_path) == Path("my/own/footage")
    with pytest.raises(FootageLabelError, match="unknown synthetic scene 'lava'"):
        resolve_footage("synthetic:lava", tmp_path)
    with pytest.raises(FootageLabelError, match="unknown PIV recording"):
        footage_folder_name("piv:nowhere")
    with pytest.raises(ConfigError, match="footage=''"):
        resolve_footage("", tmp_path)


def _video_field(rng: np.random.Generator) -> np.ndarray:
    v = np.zeros((48, 48, 2))
    v[..., 1] = 0.8
    return v + 0.1 * rng.standard_normal(v.shape)


class _Kill(Exception):
    pass


def test_optimiser_resumes_from_a_checkpoint_to_the_uninterrupted_result(tmp_path, rng):
    spec = EditSpec.from_dict(THREE)
    vf = _video_field(rng)
    ref = edit_field(vf, spec)
    assert ref.figures["iterations"] > 8, "the reference run must be long enough to interrupt"
    ckpt = tmp_path / "ckpt.npz"

    def killed_at_7(it, state):
        write_npz(ckpt, **state)  # what the stage writes (atomically) every checkpoint_every iterations
        if it == 7:
            raise _Kill

    with pytest.raises(_Kill):
        edit_field(vf, spec, on_iter=killed_at_7)
    with np.load(ckpt) as z:
        state = {k: z[k] for k in z.files}
    assert int(state["it"]) == 7
    seen = []
    res = edit_field(vf, spec, resume=state, on_iter=lambda it, s: seen.append(it))
    assert seen[0] == 8  # continues with the next iteration, none repeated
    np.testing.assert_array_equal(res.field, ref.field)  # bit-identical
    assert res.history == ref.history
    assert res.figures["iterations"] == ref.figures["iterations"]
    assert res.figures["fraction_in_desired_sink"] == ref.figures["fraction_in_desired_sink"] >= 0.98


def test_resume_state_of_another_grid_is_rejected(rng):
    spec = EditSpec.from_dict(THREE)
    with pytest.raises(ValueError, match="resume state field shape"):
        edit_field(_video_field(rng), spec, resume={"v": np.zeros((8, 8, 2)), "step": 0.5, "it": 1, "hist": [1.0]})


def test_flow_colours_code_direction_and_speed():
    f = np.zeros((2, 3, 2))
    f[0, 0] = (1, 0)     # right: red
    f[0, 1] = (-1, 0)    # left: cyan
    f[0, 2] = (0.5, 0)   # right at half speed: paler red
    f[1, 0] = (1e10, 0)  # unknown ground truth: black
    c = flow_to_color(f, max_speed=1.0).astype(int)
    assert c[0, 0, 0] == 255 and c[0, 0, 1] < 10 and c[0, 0, 2] < 10
    assert c[0, 1, 0] < 10 and c[0, 1, 1] == 255 and c[0, 1, 2] == 255
    assert c[0, 2, 0] == 255 and 100 < c[0, 2, 1] < 160
    assert (c[1, 0] == 0).all()
    assert (c[1, 1] == 255).all()  # zero flow: white
    w = color_wheel(33)
    assert w.shape == (33, 33, 3) and (w[0, 0] == 255).all()
    o, v = arrow_grid(np.ones((16, 16, 2)), 4, scale=2.0)
    assert o.shape == (16, 2) and np.allclose(v, 2.0) and o.min() == 2


def test_metrics_table_flags_missed_targets():
    edit = {"edit": "e", "footage": "fluid_x", "fraction_in_desired_sink": 0.97, "fraction_in_desired_sink_init": 0.5,
            "rendered_flow_epe_px": 0.6, "edited_speed_mean_px": 1.0, "rendered_flow_epe_rel": 0.6,
            "edited_speed_epe_mask_px": 1.0, "patch_distance_ratio": 1.4,
            "flicker_output": 1.0, "flicker_source": 2.0, "render_s_per_frame": 0.1, "optimise_s": 1.0}
    mb = {"method": "dis_fine", "epe_px": {"RubberWhale": {"dis_fine": 0.3, "dis_medium": 0.2}}}
    rows = {(r["item"], r["quantity"].split(" (")[0]): r["met"] for r in metrics_rows([edit, mb])}
    assert rows[("edit/e", "fraction of source particles whose streamline ends in the desired sink")] == "NO"
    assert rows[("edit/e", "rendered-flow EPE vs edited field px/frame")] == "NO"  # 0.6 px/frame > 0.5 x 1.0
    assert rows[("edit/e", "rendered-flow EPE / edited field's mean speed on the same pixels")] == "NO"
    ok = {r["quantity"].split(" (")[0]: r["met"] for r in metrics_rows([{**edit, "rendered_flow_epe_rel": 0.4}])}
    assert ok["rendered-flow EPE vs edited field px/frame"] == "yes"
    # a summary from before the relative target: the figure, no verdict
    old = {k: v for k, v in edit.items() if k not in ("rendered_flow_epe_rel", "edited_speed_epe_mask_px")}
    assert {r["quantity"].split(" (")[0]: r["met"] for r in metrics_rows([old])}[
        "rendered-flow EPE vs edited field px/frame"] == ""
    assert rows[("edit/e", "patch-distance ratio")] == "yes"
    assert rows[("edit/e", "flicker in static regions, output")] == "yes"
    assert rows[("middlebury/RubberWhale", "epe_px")] == "NO"
    timed = {**edit, "frames": 120, "arrival_frames_median": 400.0, "arrival_frames_max": 700.0,
             "fraction_arriving_within_render": 0.0}
    r = {x["quantity"]: x for x in metrics_rows([timed])}
    assert r["median frames for a particle to reach its sink along the field"]["value"] == 400.0
    assert r["fraction of particles reaching their sink within the 120 rendered frames"]["value"] == 0.0
    assert rows_to_csv(metrics_rows([mb])).startswith("item,quantity,value,target,met\n")
    # an obstacle in the footage: its rendered grey beside the footage's, without a verdict (the fill
    # is the footage's median at full opacity, so they agree by construction, however it was declared)
    grey = {"footage_obstacle_grey_source": 6.9, "footage_obstacle_grey_diff_max": 8.0}  # (an older summary's extra key)
    for go in (6.95, 14.7):
        r = {x["quantity"].split(" (")[0]: x for x in metrics_rows([{**edit, **grey, "footage_obstacle_grey_output": go}])}
        row = r["mean grey level inside the obstacles in the footage, output"]
        assert row["met"] == "" and row["value"] == go and row["target"].startswith("n/a (by construction")
    none = {**edit, "footage_obstacle_grey_output": float("nan"), "footage_obstacle_grey_source": float("nan")}
    assert not any("inside the obstacles" in x["quantity"] for x in metrics_rows([none]))
    # no static region in the output: flicker not measurable (no verdict), said so in the target
    flame = {**edit, "edit": "f", "flicker_output": float("nan"), "detail_ratio": 0.9, "flicker_mc_output": 1.1,
             "flicker_mc_source": 0.9}
    r = {x["quantity"].split(" (")[0]: x for x in metrics_rows([flame])}
    assert r["flicker in static regions, output"]["met"] == ""
    assert "not measurable" in r["flicker in static regions, output"]["target"]
    assert r["detail-contrast ratio output/source"]["value"] == 0.9
    assert r["detail-contrast ratio output/source"]["met"] == "yes"
    washed = {**flame, "detail_ratio": 0.7, "patch_distance_ratio": 1.6, "patch_coherence_ratio": 0.6,
              "patch_completeness_ratio": 1.6}
    r = {x["quantity"].split(" (")[0]: x for x in metrics_rows([washed])}
    assert r["detail-contrast ratio output/source"]["met"] == "NO"
    assert r["patch-distance ratio"]["met"] == "NO" and "completeness 1.600" in r["patch-distance ratio"]["quantity"]
    assert r["motion-compensated flicker, whole frame, output"]["value"] == 1.1
    with pytest.raises(ValueError, match="not a fluid_flow"):
        metrics_rows([{"something": 1}])


def _footage_with_a_still_dark_disc(disc: bool = True, dark_band: bool = False):
    """64x96 grey texture moving right 1 px/frame (8 frames) past a still dark disc with a faint
    still texture (radius 13 px,
    centre pixel (48.5, 30.5) = node (24, 15) at 2 px per node), optionally a still dark band
    along the top edge (a background, not a solid)."""
    import cv2

    from vidsim.fluid.flow import estimate_flow

    rng = np.random.default_rng(0)
    H, W = 64, 96
    tex = cv2.GaussianBlur(rng.uniform(0, 255, (H, W)).astype(np.float32), (0, 0), 1.2)
    tex = (tex - tex.mean()) / tex.std() * 30 + 110
    yy, xx = np.mgrid[0:H, 0:W]
    d = (xx - 48.5) ** 2 + (yy - 30.5) ** 2 <= 13**2
    solid = 6.0 + 0.05 * cv2.GaussianBlur(rng.uniform(0, 255, (H, W)).astype(np.float32), (0, 0), 1.2)  # faint, still
    fr = []
    for t in range(8):
        f = np.roll(tex, t, axis=1)
        if disc:
            f[d] = solid[d]
        if dark_band:
            f[:10] = solid[:10]
        fr.append(np.clip(f + rng.normal(0, 1, f.shape), 0, 255))
    frames = np.repeat(np.stack(fr).astype(np.uint8)[..., None], 3, -1)
    return frames, estimate_flow(frames)


def test_undeclared_still_dark_region_is_reported_until_declared():
    from vidsim.fluid.pipeline import undeclared_obstacles

    spec = {"grid": {"height": 32, "width": 48}, "downsample": 2,
            "sources": [{"box": [0, 12, 1, 31], "distribution": "out"}], "sinks": [{"name": "out", "box": [47, 12, 48, 31]}]}
    frames, flow = _footage_with_a_still_dark_disc()
    found = undeclared_obstacles(frames, flow, EditSpec.from_dict(spec))
    print(found)
    assert len(found) == 1 and np.hypot(found[0]["center"][0] - 24, found[0]["center"][1] - 15) < 3
    declared = {**spec, "obstacles": [{"center": [24.0, 15.0], "radii": [6.5, 6.5], "in_footage": True}]}
    assert undeclared_obstacles(frames, flow, EditSpec.from_dict(declared)) == []
    # declared as an obstacle the edit adds, it would be drawn over, not shown: still reported
    added = {**spec, "obstacles": [{"center": [24.0, 15.0], "radii": [6.5, 6.5]}]}
    assert undeclared_obstacles(frames, flow, EditSpec.from_dict(added)) == found
    # the edit warns and lists it in its figures
    from vidsim.fluid.pipeline import UndeclaredObstacleWarning, run_edit

    quick = {**spec, "optimizer": {"iterations": 2}, "render": {"frames": 2, "patch": 8, "overlap": 2}}
    with pytest.warns(UndeclaredObstacleWarning, match=r"around node \(24.0, 15.0\)"):
        r = run_edit(frames, EditSpec.from_dict(quick), np.random.default_rng(0), flow=flow)
    assert r["figures"]["undeclared_obstacles"] == found
    # no disc, only a still dark band along the frame's edge (a background): nothing to declare
    frames, flow = _footage_with_a_still_dark_disc(disc=False, dark_band=True)
    assert undeclared_obstacles(frames, flow, EditSpec.from_dict(spec)) == []
