"""fit.yaml and masks.npz formats: exact round trip through YAML, named errors on malformed input."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from vidsim.rigid.body import BoxBody, RigidBodyError, t_object
from vidsim.rigid.dynamics import gravity_vector, simulate
from vidsim.rigid.fit import Candidate, FitResult
from vidsim.rigid.outputs import check_masks, fit_from_dict, fit_to_dict, masks_from_npz, simulated_states


def _fit(rng) -> tuple[FitResult, BoxBody]:
    body, _ = t_object()
    p = np.concatenate([[0.1, -0.3, 3.5], [0, 0, 0], [0.4, -4.0, 0.2], rng.normal(size=3) * 5, [0.05, -0.02]])
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    times = 1.0 + np.arange(12) / 30.0
    st = simulate(p, q, body.inertia, times, 1.0, 1.0 / 120, sensitivities=False, g=9.80665).states
    alt = Candidate(p + 0.01, -q, 3.25, 0.91, rng.uniform(size=12), [5.0, 4.0, 3.25], 7)
    res = FitResult(p, q, 1.0, times, np.arange(30, 42), st, rng.uniform(0.9, 1.0, 12), 0.95,
                    [9.0, 2.0, 1.1], [alt], True, 12.5, 30, [0], 9.80665, 1.0 / 120)
    return res, body


def test_fit_dict_round_trips_exactly_through_yaml(rng):
    res, body = _fit(rng)
    d = yaml.safe_load(yaml.safe_dump(fit_to_dict(res, body), sort_keys=False))
    back = fit_from_dict(d)
    for name in ("params", "q0", "times", "frames", "states", "iou"):
        assert np.array_equal(getattr(back, name), getattr(res, name)), name
    assert (back.t0, back.mean_iou, back.history, back.ambiguous, back.seconds, back.n_starts, back.distinct, back.gravity, back.hmax) == \
        (res.t0, res.mean_iou, res.history, res.ambiguous, res.seconds, res.n_starts, res.distinct, res.gravity, res.hmax)
    a, b = back.alternatives[0], res.alternatives[0]
    assert np.array_equal(a.params, b.params) and np.array_equal(a.q_base, b.q_base)
    assert (a.cost, a.mean_iou, a.history, a.start) == (b.cost, b.mean_iou, b.history, b.start)
    # named parameters agree with the raw vector, the body rebuilds, the states re-simulate
    assert d["velocity"] == res.params[6:9].tolist()
    assert np.allclose(d["gravity_direction"], gravity_vector(res.params[12], res.params[13], 1.0))
    body2 = BoxBody.from_meta(d["object"])
    assert np.array_equal(body2.inertia, body.inertia)
    assert np.allclose(simulated_states(back, body2, back.times), res.states, atol=1e-12)
    # the stored gravity magnitude is used: Earth's would move the body elsewhere
    earth = simulate(back.params, back.q0, body2.inertia, back.times, back.t0, back.hmax, sensitivities=False).states
    assert np.abs(earth[-1, :3] - res.states[-1, :3]).max() > 1e-4


def test_fit_dict_errors_name_the_field(rng):
    res, body = _fit(rng)
    d = fit_to_dict(res, body)
    with pytest.raises(RigidBodyError, match="'params'"):
        fit_from_dict({k: v for k, v in d.items() if k != "params"})
    with pytest.raises(RigidBodyError, match="'states'"):
        fit_from_dict({**d, "states": d["states"][:-1]})
    with pytest.raises(RigidBodyError, match="format"):
        fit_from_dict({**d, "format": "something/2"})


def test_masks_format_checks():
    m = np.zeros((4, 6, 8), np.uint8)
    m[1, 2:4, 3:5] = 1
    masks, times = masks_from_npz({"masks": m, "times": np.arange(4) / 30.0})
    assert masks.dtype == bool and masks.sum() == 4 and times.dtype == np.float64
    with pytest.raises(RigidBodyError, match="'times'"):
        masks_from_npz({"masks": m})
    with pytest.raises(RigidBodyError, match="'times'"):
        check_masks(m, np.arange(3) / 30.0)
    with pytest.raises(RigidBodyError, match="increasing"):
        check_masks(m, np.array([0.0, 0.1, 0.1, 0.2]))


def test_an_unchecked_two_solution_report_is_null_not_false(rng):
    """With one refined candidate (multistart=none) fit.yaml said `ambiguous: false` as if the
    two-solution check had been made; it is null with a note, and readers keep the null."""
    res, body = _fit(rng)
    res.alternatives, res.distinct, res.ambiguous = [], [], None
    d = yaml.safe_load(yaml.safe_dump(fit_to_dict(res, body), sort_keys=False))
    assert d["ambiguous"] is None and d["ambiguous_note"].startswith("not checked: 1 candidate(s) refined")
    assert fit_from_dict(d).ambiguous is None
    checked = fit_to_dict(_fit(rng)[0], body)
    assert checked["ambiguous"] is True and "ambiguous_note" not in checked
    assert fit_from_dict({k: v for k, v in d.items() if k != "ambiguous"}).ambiguous is False  # older files
    with pytest.raises(RigidBodyError, match=r"'ambiguous' must be true, false or null .*got 'maybe'"):
        fit_from_dict({**d, "ambiguous": "maybe"})


def test_rigid_summary_reads_an_unchecked_ambiguity(tmp_path):
    from hydra import compose, initialize_config_dir

    from vidsim.cli import rigid_summary
    from vidsim.config import CONF_DIR

    errors = {"orientation_deg": 0.2, "omega_rel": 0.003, "position_rel_range": 0.001, "velocity_rel": 0.001,
              "gravity_deg": 0.05, "mean_iou": 0.99, "mean_iou_footage": 0.98}
    paths = []
    for case, amb in (("a", None), ("b", False), ("c", True)):
        p = tmp_path / case / "score.yaml"
        p.parent.mkdir()
        p.write_text(yaml.safe_dump({"seed": 1, "success": True, "errors": errors, "segmentation": {"mean_iou": 0.97},
                                     "fit": {"seconds": 1.0, "n_starts": 1, "ambiguous": amb}, "effects_on": {}}))
        paths.append(str(p))
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=[f"paths.results={tmp_path}", f"rigid.paths.scores='{' '.join(paths)}'",
                                           f"paths.out={tmp_path / 'out'}"])
    rigid_summary.run(cfg)
    rows = (tmp_path / "out" / "summary.csv").read_text().splitlines()
    col = rows[0].split(",").index("ambiguous")
    assert [r.split(",")[col] for r in rows[1:]] == ["unchecked", "False", "True"]


def test_fit_yaml_names_the_calibrations_world_frame(rng):
    """The estimate is in the calibration's world frame, called 'camera axes' although that holds
    only while R = I, t = 0: fit.yaml labels the frame and gives gravity in camera axes."""
    from vidsim.rigid.dynamics import rotvec_to_rot
    from vidsim.rigid.outputs import is_camera_frame
    from vidsim.video.camera import PinholeCamera

    res, body = _fit(rng)
    K = [[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]
    cam = PinholeCamera(K)
    d = fit_to_dict(res, body, cam)
    assert is_camera_frame(cam) and "so it is the camera frame" in d["world_frame"]["note"]
    assert d["gravity_direction_camera"] == d["gravity_direction"]
    R = rotvec_to_rot(np.array([0.3, 0.0, 0.1]))
    tilted = PinholeCamera(K, R, [0.0, 0.0, 0.5])
    d = fit_to_dict(res, body, tilted)
    assert not is_camera_frame(tilted) and "NOT the camera frame" in d["world_frame"]["note"]
    assert np.allclose(d["gravity_direction_camera"], R @ np.asarray(d["gravity_direction"]))
    assert np.array_equal(d["world_frame"]["R"], R.tolist())
    assert fit_from_dict(yaml.safe_load(yaml.safe_dump(d))).mean_iou == res.mean_iou  # readers ignore the labels
    assert "world_frame" not in fit_to_dict(res, body)
