"""Source-sink editing: gradients vs finite differences, Figure 15, three sinks at >= 98 %."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.fluid.edit import EditSpec
from vidsim.fluid.flow import estimate_flow
from vidsim.fluid.optimize import (
    Objective, PatchIndex, edit_field, harmonic_init, neighborhood, smoothness,
)
from vidsim.reality.fluid import make_scene

H = W = 64
FIG15 = {
    "grid": {"height": H, "width": W},
    "sources": [{"name": "top", "box": [20, 4, 44, 5], "distribution": [["red", 0.5], ["green", 0.5]]}],
    "sinks": [{"name": "red", "box": [4, 56, 22, 60]}, {"name": "green", "box": [42, 56, 60, 60]}],
    "weights": {"flow": 1.0, "smooth": 0.2, "neighborhood": 0.0},
}
THREE = {
    "grid": {"height": H, "width": W},
    "sources": [{"name": "top", "box": [12, 3, 52, 5],
                 "distribution": [["red", 0.3], ["blue", 0.4], ["green", 0.3]]}],
    "sinks": [{"name": "red", "box": [2, 56, 16, 60]}, {"name": "blue", "box": [25, 56, 39, 60]},
              {"name": "green", "box": [48, 56, 62, 60]}],
    "obstacles": [{"center": [32, 30], "radii": [8, 4]}],
    "weights": {"flow": 1.0, "smooth": 0.2, "neighborhood": 0.2},
    "optimizer": {"iterations": 60},
}


def _with(d, **kw):
    out = {k: v for k, v in d.items()}
    out.update(kw)
    return out


def test_flow_gradient_matches_central_differences(rng):
    # particles leave through the bottom edge: the exit point is smooth in the field there
    spec = EditSpec.from_dict(FIG15)
    prob = spec.rasterize()
    v = np.zeros((H, W, 2))
    v[..., 1] = 1.0
    v += 0.2 * rng.standard_normal(v.shape)
    v[..., 1] = np.abs(v[..., 1]) + 0.3
    obj = Objective(prob, None, 1.0, 0.0, 0.0)
    _, codes, errs, grad = obj.trace(v, True)
    assert (errs > 0).any()
    touched = np.argwhere(np.abs(grad).sum(-1) > 1e-6)
    h = 1e-6
    checked = 0
    for i, j in touched[rng.choice(len(touched), 12, replace=False)]:
        for c in range(2):
            vp, vm = v.copy(), v.copy()
            vp[i, j, c] += h
            vm[i, j, c] -= h
            _, cp, ep, _ = obj.trace(vp)
            _, cm, em, _ = obj.trace(vm)
            if not (np.array_equal(cp, codes) and np.array_equal(cm, codes)):
                continue  # a particle switched exit: the energy is not differentiable there
            fd = (ep.sum() - em.sum()) / (2 * h)
            assert fd == pytest.approx(grad[i, j, c], rel=1e-4, abs=1e-6)
            checked += 1
    assert checked >= 10


def test_smooth_and_neighborhood_gradients(rng):
    v = rng.standard_normal((12, 14, 2))
    video = np.cumsum(rng.standard_normal((3, 12, 14, 2)), axis=1) * 0.3
    idx = PatchIndex(video)
    _, gs = smoothness(v)
    off = np.zeros_like(v)
    for i, j, c in [(0, 0, 0), (5, 7, 1), (11, 13, 0), (0, 9, 1)]:
        e = np.zeros_like(v)
        e[i, j, c] = 1e-6
        fd = (smoothness(v + e)[0] - smoothness(v - e)[0]) / 2e-6
        assert fd == pytest.approx(gs[i, j, c], rel=1e-5)
        # neighbourhood with the matches held fixed: compare on exact queries
        _, gn = neighborhood(v, idx, off)
        ep, _ = neighborhood(v + e, idx, off)
        em, _ = neighborhood(v - e, idx, off)
        assert (ep - em) / 2e-6 == pytest.approx(gn[i, j, c], rel=1e-3, abs=1e-6)


def test_figure15_local_minimum_and_harmonic_fix():
    vf = np.zeros((H, W, 2))
    vf[..., 1] = 1.0
    # plain continuous descent from a field biased to the lower left: particles get stuck
    plain = edit_field(vf, EditSpec.from_dict(_with(FIG15, optimizer={"init": "uniform", "uniform": [-0.5, 1.0],
                                                                       "iterations": 200})))
    harm = edit_field(vf, EditSpec.from_dict(_with(FIG15, optimizer={"init": "harmonic", "iterations": 200})))
    print("Figure 15: plain", plain.figures["fraction_in_desired_sink"], "harmonic",
          harm.figures["fraction_in_desired_sink"])
    assert plain.figures["fraction_in_desired_sink"] < 0.9  # the seed's local minimum (measured 0.21)
    assert harm.figures["fraction_in_desired_sink"] >= 0.98
    assert harm.figures["fraction_in_desired_sink_init"] >= 0.98


def test_three_sinks_with_obstacle_and_video_neighbourhoods():
    foot = make_scene("stream_boat", size=128, n_frames=6, seed=1)
    fl = estimate_flow(foot.frames)  # the estimator's view: frames only
    vf = fl.reshape(5, 64, 2, 64, 2, 2).mean((2, 4)) / 2.0
    vf = np.stack([vf[..., 1], vf[..., 0]], -1).transpose(0, 2, 1, 3)  # turn the stream to flow down
    res = edit_field(vf.mean(0), EditSpec.from_dict(THREE), vf)
    print("three sinks:", res.figures)
    assert res.ok
    assert res.figures["fraction_in_desired_sink"] >= 0.98
    assert res.figures["En"] < 0.05  # the field keeps the video's local statistics
    # the obstacle is respected and no particle is lost at the frame edge
    assert np.all(res.field[EditSpec.from_dict(THREE).solid_mask()] == 0)
    assert not np.any(res.codes == -2)


def test_crossing_layout_harmonic_paths_then_optimisation():
    # red particles start right of the blue source yet must reach the left sink: their paths
    # must route around the blue channel (planar, but not the natural partition)
    d = _with(THREE, sources=[{"name": "a", "box": [10, 30, 20, 31], "distribution": "blue"},
                              {"name": "b", "box": [44, 30, 54, 31], "distribution": [["red", 0.5], ["green", 0.5]]}],
              weights={"flow": 1.0, "smooth": 0.2, "neighborhood": 0.0}, optimizer={"iterations": 300})
    spec = EditSpec.from_dict(d)
    prob = spec.rasterize()
    _, info = harmonic_init(prob, 1.0)
    assert info["paths_ok"] == 1.0  # every discrete steepest-descent path reaches its sink
    vf = np.zeros((H, W, 2))
    vf[..., 1] = 0.5
    res = edit_field(vf, spec)
    print("crossing layout:", res.figures["fraction_in_desired_sink_init"], "->", res.figures["fraction_in_desired_sink"])
    assert res.figures["fraction_in_desired_sink"] >= 0.98  # measured 1.0 (init and after)


def test_a_particle_starting_inside_another_sink_leaves_it_first():
    """A source node that lies in another sink (allowed by the edit spec) must not end there after
    one step: with a uniform +x field it crosses that sink and reaches the one it wants."""
    from vidsim.fluid.optimize import trace_particles

    h, w = 10, 16
    sink_id = -np.ones((h, w), np.int64)
    sink_id[:, 12:16] = 0  # the wanted sink, on the right
    sink_id[:, 0:4] = 1  # another sink, on the left, around the source node
    boxes = np.array([[12, 0, 15, h - 1], [0, 0, 3, h - 1]], float)  # x0, y0, x1, y1 in nodes
    solid = np.zeros((h, w), bool)
    v = np.zeros((h, w, 2))
    v[..., 0] = 1.0
    parts = np.array([[2.0, 5.0], [5.0, 5.0]])
    exits, codes, errs, _ = trace_particles(v, parts, np.array([0, 0], np.int64), boxes, sink_id, solid, 0.5, 200,
                                            False)
    assert list(codes) == [0, 0] and np.allclose(errs, 0.0)
    assert exits[0, 0] >= 11.5
    # against the field it crosses the sink it started in and leaves the frame on the left
    v[..., 0] = -1.0
    _, codes, errs, _ = trace_particles(v, parts[:1], np.array([0], np.int64), boxes, sink_id, solid, 0.5, 200, False)
    assert codes[0] == -2 and errs[0] > 0  # it leaves the frame on the left, far from sink 0


def test_travel_frames_is_distance_over_speed():
    """The time a particle takes to reach its sink along the field (frames): in a uniform
    field of 0.5 nodes/frame, from y = 2.25 the tracer needs 51 half-node steps (25.5 nodes) to
    enter the sink (y >= 27.5): 51 frames; at 0.25 nodes/frame twice as long; a particle
    starting in its sink takes 0, one in a field that never reaches a sink inf."""
    from vidsim.fluid.optimize import travel_frames

    h, w = 32, 8
    sink_id = -np.ones((h, w), np.int64)
    sink_id[28:, :] = 0
    solid = np.zeros((h, w), bool)
    parts = np.array([[3.0, 2.25], [3.0, 29.0]])
    des = np.array([0, 0], np.int64)
    v = np.zeros((h, w, 2))
    for speed in (0.5, 0.25):
        v[..., 1] = speed
        t = travel_frames(v, parts, des, sink_id, solid, 0.5, 1000)
        assert t[0] == pytest.approx(25.5 / speed, rel=1e-5) and t[1] == 0.0
    v[..., 1] = 0.0
    # no motion at all: the tracer never ends
    assert np.isinf(travel_frames(v, parts[:1], des[:1], sink_id, solid, 0.5, 100)[0])


def test_edit_reports_arrival_times():
    spec = EditSpec.from_dict(_with(FIG15, optimizer={"iterations": 5}))
    vf = np.zeros((H, W, 2))
    vf[..., 1] = 0.5
    res = edit_field(vf, spec)
    ok = res.codes == res.desired
    assert ok.any() and np.isfinite(res.arrival_frames[ok]).all()
    assert res.figures["arrival_frames_median"] == pytest.approx(np.median(res.arrival_frames[ok]))
    # at least the straight-line distance to the sink row over the fastest speed in the field
    vmax = np.linalg.norm(res.field, axis=-1).max()
    assert res.figures["arrival_frames_median"] >= (56 - 0.5 - 4) / vmax
