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
