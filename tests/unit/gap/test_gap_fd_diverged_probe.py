"""A finite-difference probe whose simulation diverges keeps its step (review, 5 Dec 2026).

``fd_steps`` had shrunk such a probe's step to target/inf = 0, so the Jacobian column was 0/0 and
the refit raised on NaN instead of scoring the model badly.
"""

from __future__ import annotations

import warnings

import numpy as np

from vidsim.gap.rigid_diagnose import Problem, refit
from vidsim.gap.rigid_model import RigidGapModel
from vidsim.rigid.body import t_object
from vidsim.video.camera import PinholeCamera, intrinsics


def test_a_diverging_probe_keeps_a_finite_step_and_the_refit_runs():
    body, _ = t_object()
    cam = PinholeCamera(intrinsics(400.0, None, 159.5, 119.5), np.eye(3), np.zeros(3), 320, 240)
    times = np.arange(10) / 30.0
    m = RigidGapModel(body, cam, times, 0.0, np.array([1.0, 0, 0, 0]), ("angular_drag",), scale=0.5)
    p = np.zeros(m.n_params)
    p[0:3] = [0.0, 0.0, 2.5]
    p[6:9] = [0.5, -1.0, 0.0]
    p[9 + int(np.argmax(np.diag(body.inertia)))] = 499.99  # just under the model's 500 rad/s guard
    img, ok = m.render(p)
    assert ok
    hs = m.fd_steps(p, 1e-4)
    assert np.all(np.isfinite(hs)) and np.all(hs > 0), hs
    pr = Problem(m, img.copy(), np.ones_like(img, bool), np.arange(len(times)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        J = pr.jacobian(p)
        th, info = refit(pr, p, 3)
    assert np.all(np.isfinite(J))
    assert np.all(np.isfinite(th))
