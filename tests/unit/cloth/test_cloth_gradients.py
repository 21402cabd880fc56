"""Every force against finite differences of its energy (or dissipation potential)."""

import numpy as np
import pytest

from vidsim.cloth import Colliders, swatch
from vidsim.cloth.collision import build_self_pairs, collider_forces, self_collision_forces
from vidsim.cloth.forces import (
    atan2_fast,
    bend_forces,
    bend_forces_quadratic,
    drag_dissipation_potential,
    drag_forces,
    gravity_forces,
    stretch_shear_forces,
)


def _fd_grad(fun, x, h=1e-7):
    g = np.zeros_like(x)
    for i in range(x.shape[0]):
        for d in range(3):
            xp = x.copy()
            xm = x.copy()
            xp[i, d] += h
            xm[i, d] -= h
            g[i, d] = (fun(xp) - fun(xm)) / (2 * h)
    return g


@pytest.fixture
def bent(rng):
    m = swatch(5, 5, 0.1, 0.1)
    x = m.rest_positions + 0.004 * rng.standard_normal(m.rest_positions.shape)
    x[:, 2] *= 1.1  # stretch along v as well
    v = rng.standard_normal(x.shape)
    return m, x, v


def _check(force, grad, scale):
    err = np.max(np.abs(force + grad))
    assert np.max(np.abs(grad)) > 1e-3 * scale, "test configuration exerts no force"
    assert err < 1e-5 * np.max(np.abs(grad)), err


@pytest.mark.parametrize("which", ["stretch", "shear", "anisotropic stretch"])
def test_stretch_shear_force_is_minus_energy_gradient(bent, which):
    m, x, _ = bent
    z = np.zeros_like(x)
    ks, ksv, ksh = {"stretch": (300.0, 300.0, 0.0), "shear": (0.0, 0.0, 40.0),
                    "anisotropic stretch": (300.0, 45.0, 0.0)}[which]

    def energy(xx):
        f = np.zeros_like(xx)
        a, b = stretch_shear_forces(xx, z, m.triangles, m.tri_coef, m.tri_area, ks, ksv, ksh, 0.0, 0.0, f)
        return a + b

    f = np.zeros_like(x)
    stretch_shear_forces(x, z, m.triangles, m.tri_coef, m.tri_area, ks, ksv, ksh, 0.0, 0.0, f)
    _check(f, _fd_grad(energy, x), 1.0)


def test_bend_force_is_minus_energy_gradient(bent):
    m, x, _ = bent
    z = np.zeros_like(x)

    def energy(xx):
        return bend_forces(xx, z, m.bend_edges, m.bend_coef, m.bend_rest, 2e-5, 0.0, np.zeros_like(xx))

    f = np.zeros_like(x)
    bend_forces(x, z, m.bend_edges, m.bend_coef, m.bend_rest, 2e-5, 0.0, f)
    _check(f, _fd_grad(energy, x), 1e-3)


def test_quadratic_bend_force_is_minus_energy_gradient(bent):
    m, x, _ = bent
    z = np.zeros_like(x)

    def energy(xx):
        return bend_forces_quadratic(xx, z, m.bend_edges, m.bend_quad, 2e-5, 0.0, np.zeros_like(xx))

    f = np.zeros_like(x)
    bend_forces_quadratic(x, z, m.bend_edges, m.bend_quad, 2e-5, 0.0, f)
    _check(f, _fd_grad(energy, x), 1e-3)


def test_quadratic_bend_matches_dihedral_energy_at_small_angles(rng):
    """Same D: on a flat-rest swatch, the quadratic model's energy equals the dihedral
    model's to O(theta^4) (ratio -> 1 as the bending amplitude -> 0), and a cylinder bent
    along the warp has energy D/2 kappa^2 per area on the interior (regular grid)."""
    m = swatch(12, 12, 0.2, 0.2, axis_u=(1, 0, 0), axis_v=(0, 1, 0))
    X = m.rest_positions
    z = np.zeros_like(X)
    shape = rng.standard_normal((m.n_vertices,))
    ratios = []
    for amp in (1e-3, 1e-4):
        x = X.copy()
        x[:, 2] = amp * shape
        ed = bend_forces(x, z, m.bend_edges, m.bend_coef, m.bend_rest, 1.0, 0.0, np.zeros_like(x))
        eq = bend_forces_quadratic(x, z, m.bend_edges, m.bend_quad, 1.0, 0.0, np.zeros_like(x))
        ratios.append(eq / ed)
    assert abs(ratios[1] - 1) < 1e-3 and abs(ratios[1] - 1) < abs(ratios[0] - 1) + 1e-12, ratios
    kap = 3.0
    s = X[:, 0]
    x = np.stack([np.sin(kap * s) / kap, X[:, 1], (1 - np.cos(kap * s)) / kap], axis=1)
    eq = bend_forces_quadratic(x, z, m.bend_edges, m.bend_quad, 1.0, 0.0, np.zeros_like(x))
    # interior bend edges along v: (n-2) columns x (n-1) rows of h x h cells, D/2 kappa^2 each
    h = 0.2 / 11
    expect = 0.5 * kap**2 * h**2 * 10 * 11
    assert abs(eq - expect) < 1e-3 * expect, (eq, expect)


def test_quadratic_bend_rejects_curved_rest_shape():
    from vidsim.cloth import ClothInputError, ClothParams, compute_forces, skirt

    m = skirt(12, 4, flat_rest_bend=False)
    with pytest.raises(ClothInputError, match="flat bending rest"):
        compute_forces(m, ClothParams(), m.rest_positions, np.zeros_like(m.rest_positions), bending="quadratic")


def test_atan2_fast_matches_math_atan2():
    import math

    a = np.linspace(-np.pi, np.pi, 20001)[1:-1]
    for r in (1e-9, 1.0, 1e6):
        for y, x in zip(r * np.sin(a), r * np.cos(a)):
            assert abs(atan2_fast(y, x) - math.atan2(y, x)) < 1e-15
    for y, x in ((0.0, 0.0), (0.0, 1.0), (0.0, -1.0), (1.0, 0.0), (-1.0, 0.0), (1.0, 1.0), (-2.0, -2.0)):
        assert abs(atan2_fast(y, x) - math.atan2(y, x)) < 1e-15, (y, x)


def test_damping_forces_are_minus_rayleigh_gradient(bent):
    """d = -kd dC/dx Cdot is -dR/dv with R = kd/2 Cdot^2 = 1/2 v.D.v, so v.f = -2R."""
    m, x, v = bent

    def dforce(vv):
        f = np.zeros_like(x)
        stretch_shear_forces(x, vv, m.triangles, m.tri_coef, m.tri_area, 0.0, 0.0, 0.0, 0.02, 0.03, f)
        bend_forces(x, vv, m.bend_edges, m.bend_coef, m.bend_rest, 0.0, 1e-7, f)
        return f

    def rayleigh(vv):
        return -0.5 * np.sum(vv * dforce(vv))

    f = dforce(v)
    g = _fd_grad(rayleigh, v, h=1e-5)
    _check(f, g, 1e-3)
    # dissipative: power is negative for any velocity
    assert np.sum(v * f) < 0


def test_quadratic_bend_damping_is_minus_rayleigh_gradient(bent):
    m, x, v = bent

    def dforce(vv):
        f = np.zeros_like(x)
        bend_forces_quadratic(x, vv, m.bend_edges, m.bend_quad, 0.0, 1e-7, f)
        return f

    f = dforce(v)
    g = _fd_grad(lambda vv: -0.5 * np.sum(vv * dforce(vv)), v, h=1e-5)
    _check(f, g, 1e-6)
    assert np.sum(v * f) < 0


def test_drag_is_minus_dissipation_potential_gradient(bent, rng):
    m, x, v = bent
    wind = np.array([0.3, -0.2, 0.1])
    f = np.zeros_like(x)
    drag_forces(x, v, m.triangles, 0.7, 1.3, 0.4, wind, f)
    g = _fd_grad(lambda vv: drag_dissipation_potential(x, vv, m.triangles, 0.7, 1.3, 0.4, wind), v, h=1e-6)
    _check(f, g, 1e-3)


def test_gravity_and_collider_forces_are_minus_energy_gradient(rng):
    m = swatch(6, 6, 0.1, 0.1, origin=(-0.05, -0.05, 0.0), axis_u=(1, 0, 0), axis_v=(0, 1, 0))
    x = m.rest_positions + 0.001 * rng.standard_normal(m.rest_positions.shape)
    cols = Colliders.static(spheres=[((0.0, 0.0, -0.05), 0.048)],
                            capsules=[((-0.1, 0.02, -0.02), (0.1, 0.02, -0.02), 0.018)])
    args = (cols.times, cols.sphere_centers, cols.sphere_radii, cols.capsule_a, cols.capsule_b, cols.capsule_radii)
    mass = m.masses(0.2)
    g = np.array([0.0, 3.0, -9.81])

    def energy(xx):
        f = np.zeros_like(xx)
        return gravity_forces(xx, mass, g, f) + collider_forces(0.0, xx, m.vertex_area, *args, 2e5, 0.004, f)

    f = np.zeros_like(x)
    e_col = collider_forces(0.0, x, m.vertex_area, *args, 2e5, 0.004, f)
    assert e_col > 0, "no vertex in contact"
    gravity_forces(x, mass, g, f)
    _check(f, _fd_grad(energy, x, h=1e-8), 1e-3)


def test_self_collision_force_is_minus_energy_gradient(rng):
    m = swatch(6, 6, 0.1, 0.1, axis_u=(1, 0, 0), axis_v=(0, 1, 0))
    n = m.n_vertices
    # fold: a second layer 2 mm above the first, slightly shifted
    x = m.rest_positions.copy()
    upper = np.arange(n) % 6 >= 3
    x[upper, 0] = 0.1 - x[upper, 0] + 0.004
    x[upper, 2] += 0.002
    x += 0.0003 * rng.standard_normal(x.shape)
    h, k = 0.003, 1e5
    pairs = build_self_pairs(x, m.triangles, 3 * h, 0.02)

    def energy(xx):
        return self_collision_forces(xx, m.triangles, m.vertex_area, pairs, k, h, np.zeros_like(xx),
                                     m.vertex_valence, m.tri_edge_share)

    f = np.zeros_like(x)
    assert energy(x) > 0
    self_collision_forces(x, m.triangles, m.vertex_area, pairs, k, h, f, m.vertex_valence, m.tri_edge_share)
    _check(f, _fd_grad(energy, x, h=1e-9), 1e-3)
    # equal and opposite: no net force
    assert np.allclose(f.sum(axis=0), 0.0, atol=1e-12 * np.abs(f).max() * n)


def test_fused_kernels_equal_the_separate_forces(bent):
    """The integrator's fused triangle/bend kernels give the same total force as the
    separately checked kernels above (plus gravity)."""
    from vidsim.cloth import ClothParams, compute_forces

    m, x, v = bent
    p = ClothParams(bend=2e-5, stretch=300.0, shear=40.0, bend_damping=1e-7, stretch_damping=0.02,
                    shear_damping=0.03, drag_linear=0.7, drag_quad=1.3, drag_degrade=0.4)
    wind = np.array([0.3, -0.2, 0.1])
    f = np.zeros_like(x)
    stretch_shear_forces(x, v, m.triangles, m.tri_coef, m.tri_area, 300.0, 300.0, 40.0, 0.02, 0.03, f)
    bend_forces(x, v, m.bend_edges, m.bend_coef, m.bend_rest, 2e-5, 1e-7, f)
    drag_forces(x, v, m.triangles, 0.7, 1.3, 0.4, wind, f)
    gravity_forces(x, m.masses(p.density), np.asarray(p.gravity), f)
    fused = compute_forces(m, p, x, v, wind=wind, bending="dihedral")
    assert np.allclose(fused, f, rtol=1e-9, atol=1e-12 * np.abs(f).max())
    # quadratic bending: the integrator's kernel selection gives the checked kernel's forces
    fq = f.copy()
    bend_forces(x, v, m.bend_edges, m.bend_coef, m.bend_rest, -2e-5, -1e-7, fq)  # remove the dihedral part
    bend_forces_quadratic(x, v, m.bend_edges, m.bend_quad, 2e-5, 1e-7, fq)
    fused_q = compute_forces(m, p, x, v, wind=wind, bending="quadratic")
    assert np.allclose(fused_q, fq, rtol=1e-9, atol=1e-12 * np.abs(f).max())
    # "auto" is the quadratic model on this flat-rest swatch; the default is dihedral
    assert np.array_equal(compute_forces(m, p, x, v, wind=wind, bending="auto"), fused_q)
    assert np.array_equal(compute_forces(m, p, x, v, wind=wind), fused)


def test_anisotropic_fused_kernel_equals_the_separate_forces(bent):
    """The fused kernel takes the warp and weft stretch stiffnesses of ``stretch_anisotropy``."""
    from vidsim.cloth import ClothParams, compute_forces

    m, x, v = bent
    p = ClothParams(bend=0.0, stretch=300.0, shear=40.0, bend_damping=0.0, stretch_damping=0.02,
                    shear_damping=0.03, drag_linear=0.0, drag_quad=0.0, stretch_anisotropy=1.2)
    assert np.isclose(p.stretch_warp / p.stretch_weft, np.exp(1.2)) and np.isclose(p.stretch_warp * p.stretch_weft, 300.0**2)
    f = np.zeros_like(x)
    stretch_shear_forces(x, v, m.triangles, m.tri_coef, m.tri_area, p.stretch_warp, p.stretch_weft, 40.0, 0.02, 0.03, f)
    gravity_forces(x, m.masses(p.density), np.asarray(p.gravity), f)
    fused = compute_forces(m, p, x, v)
    assert np.allclose(fused, f, rtol=1e-9, atol=1e-12 * np.abs(f).max())
    iso = compute_forces(m, p.replace(stretch_anisotropy=0.0), x, v)
    assert np.abs(fused - iso).max() > 1e-3 * np.abs(iso).max()  # the anisotropy changes the forces
