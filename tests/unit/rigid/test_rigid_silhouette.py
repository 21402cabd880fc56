"""Soft convex-hull silhouettes: exact hard masks, the mismatch it sums, and its pose gradient."""

from __future__ import annotations

import numpy as np

from vidsim.render.raster import silhouette_batch
from vidsim.rigid.body import t_object
from vidsim.rigid.dynamics import quat_exp, quat_mul, quat_to_rot, simulate
from vidsim.rigid.silhouette import render_coverage, sequence_costs, weight_maps
from vidsim.video.camera import PinholeCamera, intrinsics

BODY, _ = t_object()
CAM = PinholeCamera(intrinsics(640, None, 319.5, 239.5), width=640, height=480)
P = np.r_[0.1, 1.0, 3.2, 0, 0, 0, 0.5, -5.5, 0.2, 3.0, -5.0, 8.0, 0.05, -0.04]
QB = quat_exp(np.array([0.4, 1.0, -0.3]))
TIMES = np.linspace(0, 0.6, 8)


def _poses():
    tr = simulate(P, QB, BODY.inertia, TIMES, 0.0, sensitivities=False)
    return tr.states[:, 0:3], tr.states[:, 3:7]


def test_hard_silhouette_equals_triangle_rasteriser():
    X, Q = _poses()
    soft = render_coverage(X, Q, BODY.box_vertices(), CAM)
    V, F = BODY.mesh()
    Vs = np.stack([V @ quat_to_rot(q).T + x for x, q in zip(X, Q)])
    ref = silhouette_batch(Vs, F, CAM)
    assert ref.sum() > 8 * 500
    assert ((soft > 0.5) ^ ref).sum() <= 8  # the union of hulls is the exact silhouette (ties on edges aside)


def test_cost_is_seed_mismatch_and_gradient_matches_differences():
    X, Q = _poses()
    V, F = BODY.mesh()
    Vs = np.stack([V @ quat_to_rot(q).T + x for x, q in zip(X, Q)])
    obs = silhouette_batch(Vs, F, CAM)
    # lam = 0: the cost is the seed's mismatch count |A_real - A_sim| with soft A_sim
    W, base = weight_maps(obs, 0.0, 20.0, 200.0)
    Xs = X + np.array([0.02, -0.01, 0.0])  # shifted: a few pixels off
    c, g = sequence_costs(Xs, Q, BODY.box_vertices(), CAM, W, base)
    soft = render_coverage(Xs, Q, BODY.box_vertices(), CAM)
    assert np.allclose(c, np.abs(obs - soft).sum((1, 2)))
    # gradient along a direction vs a difference with a larger step
    Wd, based = weight_maps(obs, 1.0, 20.0, 200.0)
    c0, g0 = sequence_costs(Xs, Q, BODY.box_vertices(), CAM, Wd, based)
    h = 0.004
    cp, _ = sequence_costs(Xs + [h, 0, 0], Q, BODY.box_vertices(), CAM, Wd, based, grad=False)
    cm, _ = sequence_costs(Xs - [h, 0, 0], Q, BODY.box_vertices(), CAM, Wd, based, grad=False)
    fd = (cp - cm) / (2 * h)
    assert np.all(np.sign(fd) == np.sign(g0[:, 0]))
    assert np.allclose(fd, g0[:, 0], rtol=0.15)
    # the shift was +x: moving back (-x) must lower the cost
    assert np.all(g0[:, 0] > 0)
    r = np.array([0.0, 0.0, 0.01])
    Qp = np.stack([quat_mul(q, quat_exp(r)) for q in Q])
    Qm = np.stack([quat_mul(q, quat_exp(-r)) for q in Q])
    cp, _ = sequence_costs(Xs, Qp, BODY.box_vertices(), CAM, Wd, based, grad=False)
    cm, _ = sequence_costs(Xs, Qm, BODY.box_vertices(), CAM, Wd, based, grad=False)
    fdr = (cp - cm) / 0.02
    assert np.allclose(fdr, g0[:, 5], rtol=0.25, atol=0.05 * np.abs(g0[:, 5]).max())
