"""Physics invariants of the cloth simulator against known answers."""

import math

import numpy as np
import pytest

from vidsim.cloth import ClothParams, DrivenVertices, energies, simulate, swatch

G = 9.81


def _undamped(**kw):
    base = dict(bend_damping=0.0, stretch_damping=0.0, shear_damping=0.0, drag_linear=0.0, drag_quad=0.0,
                drag_degrade=0.0, stretch=200.0, shear=30.0, bend=1e-5, density=0.2)
    base.update(kw)
    return ClothParams(**base)


@pytest.mark.parametrize("integrator", ["rk45", "fast"])
def test_energy_drift_free_swinging(integrator):
    """Damping and drag off: a swatch released horizontally swings from two pinned corners
    for 2 s; total energy stays within 1 % of the swing's energy scale M g L."""
    mesh = swatch(10, 10, 0.3, 0.3, axis_u=(1, 0, 0), axis_v=(0, 1, 0))  # horizontal
    p = _undamped()
    pins = mesh.tags["top_corners"]
    drv = DrivenVertices.fixed(pins, mesh.rest_positions[pins])
    times = np.linspace(0, 2.0, 61)
    res = simulate(mesh, p, drv, times, integrator=integrator, rtol=1e-5, atol_x=1e-6, atol_v=1e-5)
    assert res.ok, res.failure
    E = np.array([energies(mesh, p, res.positions[k], res.velocities[k])["total"] for k in range(len(times))])
    scale = mesh.masses(p.density).sum() * G * 0.3
    ke_max = max(energies(mesh, p, res.positions[k], res.velocities[k])["kinetic"] for k in range(len(times)))
    assert ke_max > 0.3 * scale, "the swatch did not swing"
    drift = np.max(np.abs(E - E[0])) / scale
    assert drift < 0.01, drift


def test_pinned_strip_static_elongation():
    """A strip hanging from its pinned top row stretches by rho g L^2 / (2 k_s)."""
    L, W, ks, rho = 0.3, 0.06, 10.0, 0.2
    mesh = swatch(4, 16, W, L)
    p = ClothParams(stretch=ks, shear=5.0, bend=1e-7, bend_damping=0.0, stretch_damping=0.02, shear_damping=0.01,
                    drag_linear=10.0, drag_quad=0.0, drag_degrade=0.0, density=rho)
    top = mesh.tags["top_row"]
    drv = DrivenVertices.fixed(top, mesh.rest_positions[top])
    res = simulate(mesh, p, drv, np.array([0.0, 2.5, 3.0]), integrator="fast")
    assert res.ok, res.failure
    bottom = np.arange(mesh.n_vertices - 4, mesh.n_vertices)
    elong = -res.positions[-1, bottom, 2].mean() - L
    expected = rho * G * L**2 / (2 * ks)
    assert abs(elong - expected) < 0.05 * expected, (elong, expected)
    # settled: the last two frames agree to 1 % of the elongation
    assert np.max(np.abs(res.positions[-1] - res.positions[-2])) < 0.01 * expected


def test_falling_sheet_reaches_terminal_speed():
    """Face-first fall: rho g = kN v^2 / (1 + kf v^2)  =>  v = sqrt(rho g / (kN - kf rho g))."""
    rho, kn, kf = 0.2, 1.0, 0.1
    mesh = swatch(6, 6, 0.2, 0.2, axis_u=(1, 0, 0), axis_v=(0, 1, 0))
    p = ClothParams(density=rho, drag_quad=kn, drag_degrade=kf, drag_linear=0.5)
    res = simulate(mesh, p, None, np.array([0.0, 1.5, 2.5]), integrator="rk45")
    assert res.ok, res.failure
    v_sim = -res.velocities[-1, :, 2].mean()
    v_th = math.sqrt(rho * G / (kn - kf * rho * G))
    assert abs(v_sim - v_th) < 0.02 * v_th, (v_sim, v_th)


@pytest.mark.parametrize("integrator", ["rk45", "fast"])
def test_momentum_conserved_without_external_forces(integrator, rng):
    mesh = swatch(8, 8, 0.1, 0.1)
    p = ClothParams(gravity=(0.0, 0.0, 0.0), drag_linear=0.0, drag_quad=0.0, stretch_damping=0.01,
                    shear_damping=0.01, bend_damping=1e-7)
    x0 = mesh.rest_positions + 0.003 * rng.standard_normal(mesh.rest_positions.shape)
    v0 = 0.3 * rng.standard_normal(x0.shape)
    res = simulate(mesh, p, None, np.linspace(0, 0.2, 11), integrator=integrator, x0=x0, v0=v0,
                   self_collision=True)
    assert res.ok, res.failure
    m = mesh.masses(p.density)
    P = np.einsum("i,tij->tj", m, res.velocities)
    scale = np.sum(m * np.linalg.norm(v0, axis=1))
    assert np.max(np.abs(P - P[0])) < 1e-10 * scale
    Lz = np.einsum("i,tij->tj", m, np.cross(res.positions, res.velocities))
    # angular momentum: exact for RK45 up to its error tolerance
    assert np.max(np.abs(Lz - Lz[0])) < 2e-3 * scale * 0.1
