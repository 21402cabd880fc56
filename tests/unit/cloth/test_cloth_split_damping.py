"""The fast scheme's split damping (the Baraff-Witkin condition dampings applied after each step as
per-condition decays): each decay is what it claims, the pass only dissipates, the scheme
converges to the same motion as the explicit one, and "auto" picks it where the damping limits
the step."""

import numpy as np
import pytest

from vidsim.cloth import ClothInputError, ClothParams, simulate, stable_step, swatch
from vidsim.cloth.forces import color_order, damping_sweep, membrane_damping
from vidsim.cloth.simulate import SPLIT_GAIN, _model
from vidsim.clothfit.film import swatch_driver, swatch_model_mesh
from vidsim.reality.cloth import corner_paths, swatch_motion


def _arrays(mesh, p):
    m = _model(mesh, p, np.zeros(3))
    return dict(tris=m[0], coef=m[1], area=m[2], edges=m[3], bcoef=m[4], etris=m[13], tnorm=m[14], bquad=m[15],
                inv_mass=m[16], mass=m[6])


def _normals(x, tris):
    return np.cross(x[tris[:, 1]] - x[tris[:, 0]], x[tris[:, 2]] - x[tris[:, 0]])


def test_one_condition_decays_by_the_pade_factor():
    """A single triangle with shear damping only: the pass takes its shear rate dC/dt = J v to
    R(x) dC/dt, R(x) = 1/(1 + x + x^2/2), x = k_d a h J M^-1 J^T, changing v along M^-1 J^T only."""
    mesh = swatch(2, 2, 0.1, 0.1)
    p = ClothParams(density=0.2)
    a = _arrays(mesh, p)
    tris, coef, area = a["tris"][:1], a["coef"][:1], a["area"][:1]
    rng = np.random.default_rng(3)
    x = mesh.rest_positions + 0.01 * rng.standard_normal((4, 3))
    v = rng.standard_normal((4, 3))
    im = a["inv_mass"].copy()
    i, j, k = tris[0]
    wu = coef[0, 0] * x[i] + coef[0, 1] * x[j] + coef[0, 2] * x[k]
    wv = coef[0, 3] * x[i] + coef[0, 4] * x[j] + coef[0, 5] * x[k]
    J = np.zeros((4, 3))
    for n, vert in enumerate((i, j, k)):
        J[vert] = coef[0, n] * wv + coef[0, 3 + n] * wu
    for kd, h in ((0.01, 1e-4), (0.1, 1e-3), (1.0, 1e-2)):  # x from small to stiff
        v1 = v.copy()
        membrane_damping(x, v1, tris, coef, area, 0.0, kd, im, h, False, np.arange(1))
        w = float(np.sum(J * J * im[:, None]))
        xx = kd * area[0] * h * w
        R = 1.0 / (1.0 + xx + 0.5 * xx * xx)
        assert float(np.sum(J * v1)) == pytest.approx(R * float(np.sum(J * v)), rel=1e-9, abs=1e-12)
        dv = (v1 - v) / im[:, None]  # = lambda J
        lam = np.sum(dv * J) / np.sum(J * J)
        np.testing.assert_allclose(dv, lam * J, atol=1e-9 * np.abs(dv).max())
    # small x: the exact exponential decay to second order
    xx = 1e-3
    assert 1.0 / (1.0 + xx + 0.5 * xx * xx) == pytest.approx(np.exp(-xx), abs=xx ** 3)


def test_the_sweep_only_dissipates_and_keeps_momentum():
    """On a crumpled swatch with random velocities and large steps (up to 1000x the explicit damping
    limit), a full sweep lowers the kinetic energy, keeps the linear momentum (internal forces)
    and leaves driven vertices alone."""
    mesh = swatch(8, 8, 0.2, 0.2)
    p = ClothParams(density=0.1)
    a = _arrays(mesh, p)
    rng = np.random.default_rng(5)
    x = mesh.rest_positions + 0.01 * rng.standard_normal(mesh.rest_positions.shape)
    tn = _normals(x, a["tris"])
    m = a["mass"]
    for h in (1e-5, 1e-3, 1e-1):
        v = rng.standard_normal(x.shape)
        v1 = v.copy()
        damping_sweep(x, v1, a["tris"], a["coef"], a["area"], 0.1, 0.1, a["edges"], a["etris"], tn, a["bcoef"],
                      a["bquad"], False, 1e-6, a["inv_mass"], h)
        ke0 = 0.5 * np.sum(m[:, None] * v * v)
        ke1 = 0.5 * np.sum(m[:, None] * v1 * v1)
        assert ke1 < ke0
        np.testing.assert_allclose((m[:, None] * v1).sum(0), (m[:, None] * v).sum(0), atol=1e-12 * np.abs(m[:, None] * v).sum())
    im = a["inv_mass"].copy()
    pins = mesh.tags["top_corners"]
    im[pins] = 0.0
    v = rng.standard_normal(x.shape)
    v1 = v.copy()
    damping_sweep(x, v1, a["tris"], a["coef"], a["area"], 0.1, 0.1, a["edges"], a["etris"], tn, a["bcoef"], a["bquad"],
                  False, 1e-6, im, 1e-3)
    np.testing.assert_array_equal(v1[pins], v[pins])
    assert np.abs(v1 - v).max() > 0


def test_colour_order_groups_vertex_disjoint_elements():
    mesh = swatch(6, 5, 0.2, 0.2)
    a = _arrays(mesh, ClothParams())
    for elems in (a["tris"], a["edges"]):
        order = color_order(elems, mesh.n_vertices)
        assert sorted(order.tolist()) == list(range(len(elems)))
        # the greedy colouring replayed in plain Python: the order runs through the colours in turn,
        # and no vertex repeats within a colour
        used = [set() for _ in range(mesh.n_vertices)]
        colour = []
        for e in elems.tolist():
            taken = set().union(*(used[vert] for vert in e))
            c = min(set(range(len(elems) + 1)) - taken)
            colour.append(c)
            for vert in e:
                used[vert].add(c)
        cols = [colour[e] for e in order]
        assert cols == sorted(cols) and max(cols) >= 2
        for c in set(cols):
            verts = [vert for e in np.flatnonzero(np.array(colour) == c) for vert in elems[e]]
            assert len(verts) == len(set(verts))


def _driven(n: int = 10):
    times = np.arange(7) / 30.0
    cp = corner_paths(swatch_motion("exp1"), times)
    mesh = swatch_model_mesh(cp[0], n, 0.3)
    drv, t0 = swatch_driver(mesh, times, cp, 0.05)
    return mesh, drv, t0, times


#: a light, strongly damped fabric (the corner where the satin fits spent their time)
DAMPED = dict(stretch=1500.0, shear=400.0, bend=5e-5, stretch_damping=0.05, shear_damping=0.1, bend_damping=1e-6,
              density=0.1)


def test_split_converges_to_the_same_motion_as_explicit():
    """Over 0.25 s of a driven damped swatch, against an explicit reference at a sixteenth of the
    step: the split scheme's error falls as the step does and, at the explicit scheme's own steps, is
    no larger than 2x the explicit one's, and a small fraction of what the dampings change (measured:
    split 1.03e-5 / 3.5e-6 m at h / h/2, explicit 7.8e-6 / 3.5e-6 m; the dampings move the swatch by
    2.0e-3 m)."""
    mesh, drv, t0, times = _driven()
    p = ClothParams(**DAMPED)
    h = simulate(mesh, p, drv, times, integrator="fast", t0=t0).dt
    ref = simulate(mesh, p, drv, times, integrator="fast", t0=t0, dt=h / 16)
    err = {}
    for mode in ("explicit", "split"):
        for dt in (h, h / 2):
            res = simulate(mesh, p, drv, times, integrator="fast", t0=t0, dt=dt, damping=mode)
            assert res.ok, res.failure
            err[mode, dt] = float(np.max(np.abs(res.positions[1:] - ref.positions[1:])))
    assert err["split", h / 2] < 0.7 * err["split", h], err
    for dt in (h, h / 2):
        assert err["split", dt] < 2.0 * err["explicit", dt], err
    undamped = simulate(mesh, p.replace(stretch_damping=0.0, shear_damping=0.0, bend_damping=0.0), drv, times,
                        integrator="fast", t0=t0, dt=h)
    effect = float(np.max(np.abs(undamped.positions[1:] - ref.positions[1:])))
    assert err["split", h] < 0.02 * effect, (err, effect)
    # with the bending kicked once per 4 steps the split dampings still act every inner step: no
    # larger error (applying the bending damping once per outer step instead was 6x less accurate)
    mr = simulate(mesh, p, drv, times, integrator="fast", t0=t0, dt=h, damping="split", multirate=4)
    assert mr.ok and mr.stats["multirate"] == 4
    err_mr = float(np.max(np.abs(mr.positions[1:] - ref.positions[1:])))
    assert err_mr < 1.5 * err["split", h], (err_mr, err)


def test_auto_splits_where_the_damping_limits_the_step():
    """"auto" splits on the damped fabric (its step grows by more than SPLIT_GAIN and the run takes
    fewer steps) and stays explicit on a lightly damped one; nonsense is refused."""
    mesh, drv, t0, times = _driven(12)
    p = ClothParams(**DAMPED)
    h, info = stable_step(mesh, p, driven=drv.indices, damping="auto")
    assert info["damping"] == "split" and info["h_split"] > SPLIT_GAIN * info["h_explicit"]
    ex = simulate(mesh, p, drv, times, integrator="fast", t0=t0)
    au = simulate(mesh, p, drv, times, integrator="fast", t0=t0, damping="auto")
    assert ex.ok and au.ok
    assert au.stats["damping"] == "split" and ex.stats["damping"] == "explicit"
    assert au.steps < ex.steps / SPLIT_GAIN
    light = ClothParams(stretch=300.0, shear=50.0, bend=1e-5, density=0.2)
    assert simulate(mesh, light, drv, times, integrator="fast", t0=t0, damping="auto").stats["damping"] == "explicit"
    for bad in ("implicit", None):
        with pytest.raises(ClothInputError, match="damping"):
            simulate(mesh, p, drv, times, integrator="fast", t0=t0, damping=bad)
    with pytest.raises(ClothInputError, match="split"):
        simulate(mesh, p, drv, times, integrator="rk45", t0=t0, damping="split")
