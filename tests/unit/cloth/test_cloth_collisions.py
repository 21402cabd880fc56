"""Collisions: a swatch dropped on a sphere never penetrates it; a crumpled swatch never
self-intersects (checked geometrically); a skirt stays outside moving leg capsules."""

import numpy as np
import pytest

from vidsim.cloth import (
    ClothInputError,
    ClothParams,
    Colliders,
    DrivenVertices,
    count_self_intersections,
    mid_range_params,
    simulate,
    skirt,
    swatch,
)


def test_swatch_dropped_on_sphere_never_penetrates():
    R = 0.08
    mesh = swatch(20, 20, 0.3, 0.3, origin=(-0.15, -0.15, R + 0.02), axis_u=(1, 0, 0), axis_v=(0, 1, 0))
    cols = Colliders.static(spheres=[((0.0, 0.0, 0.0), R)])
    p = mid_range_params()
    times = np.linspace(0.0, 1.0, 201)
    res = simulate(mesh, p, None, times, integrator="fast", colliders=cols)
    assert res.ok, res.failure
    r = np.linalg.norm(res.positions, axis=-1)
    assert r.min() > R, r.min() - R
    # it did land and drape: the centre rests on the sphere, the edges hang below its top
    centre = mesh.n_vertices // 2 + 10
    assert abs(r[-1, centre] - R) < 2 * p.collision_thickness
    assert res.positions[-1, :, 2].min() < 0.0


@pytest.fixture(scope="module")
def crumple():
    """A hanging swatch released 1 cm above a floor (a 50 m sphere) with a wavy sideways
    velocity: it buckles and piles up on itself in several layers."""
    mesh = swatch(16, 16, 0.3, 0.3, origin=(-0.15, 0.0, 0.31))
    R = 50.0
    cols = Colliders.static(spheres=[((0.0, 0.0, -R), R)])
    rng = np.random.default_rng(7)
    x0 = mesh.rest_positions + 1e-3 * rng.standard_normal(mesh.rest_positions.shape)
    v0 = np.zeros_like(x0)
    v0[:, 1] = 0.3 * (x0[:, 2] - 0.16) / 0.15 * np.cos(3 * x0[:, 0] / 0.15)
    times = np.linspace(0.0, 1.2, 61)
    return mesh, mid_range_params(), cols, times, x0, v0


@pytest.mark.parametrize("integrator", ["fast", "rk45"])
def test_crumpled_swatch_never_self_intersects(crumple, integrator):
    mesh, p, cols, times, x0, v0 = crumple
    edges = mesh.unique_edges()
    res = simulate(mesh, p, None, times, integrator=integrator, self_collision=True, x0=x0, v0=v0, colliders=cols)
    assert res.ok, res.failure
    counts = [count_self_intersections(res.positions[k], mesh.triangles, edges) for k in range(len(times))]
    assert max(counts) == 0, counts
    # it really piled up: layers in contact at the end, all within a few mm of the floor
    from vidsim.cloth.collision import build_self_pairs

    contacts = build_self_pairs(res.positions[-1], mesh.triangles, 1.5 * p.self_collision_thickness, 0.02)
    assert contacts.shape[0] > 100, contacts.shape
    assert res.positions[-1, :, 2].mean() < 0.03  # landed: the centre of mass fell from 0.16 m


def test_crumple_without_self_collision_does_intersect(crumple):
    """Control: the same motion without self repulsion passes through itself, so the test
    above is able to fail."""
    mesh, p, cols, times, x0, v0 = crumple
    res = simulate(mesh, p, None, times, integrator="fast", self_collision=False, x0=x0, v0=v0, colliders=cols)
    edges = mesh.unique_edges()
    counts = [count_self_intersections(res.positions[k], mesh.triangles, edges) for k in range(len(times))]
    assert max(counts) > 0


def test_self_collision_thickness_checked_against_mesh():
    mesh = swatch(40, 40, 0.1, 0.1)
    with pytest.raises(ClothInputError, match="self_collision_thickness"):
        simulate(mesh, ClothParams(self_collision_thickness=0.003), None, [0.0, 0.01], self_collision=True)


def test_skirt_stays_outside_skipping_legs():
    """Waistband bobbing (skipping) while two leg capsules swing forward and back."""
    mesh = skirt(32, 10, 0.14, 0.26, 0.40, waist_center=(0.0, 0.0, 1.0))
    wb = mesh.tags["waistband"]
    p0 = mesh.rest_positions[wb]
    T = 1.0
    ts = np.linspace(0.0, T, 201)
    bob = 0.04 * np.abs(np.sin(np.pi * 2.0 * ts))  # two hops per second
    drv = DrivenVertices(wb, ts, p0[None] + np.stack([np.zeros_like(ts), np.zeros_like(ts), bob], 1)[:, None, :])
    swing = 0.35 * np.sin(2 * np.pi * 1.0 * ts)
    hips = np.array([[0.0, 0.07, 0.95], [0.0, -0.07, 0.95]])
    ca = np.repeat(hips[None], len(ts), axis=0)
    ca[:, :, 2] += bob[:, None]
    leg = 0.8
    cb = ca.copy()
    for j, sgn in enumerate((1.0, -1.0)):
        cb[:, j, 0] += leg * np.sin(sgn * swing)
        cb[:, j, 2] -= leg * np.cos(sgn * swing)
    radii = np.array([0.06, 0.06])
    cols = Colliders(ts, np.zeros((len(ts), 1, 3)) + [0.0, 0.0, 1.0], np.array([0.11]), ca, cb, radii)
    res = simulate(mesh, mid_range_params(), drv, np.linspace(0.0, T, 101), integrator="fast", colliders=cols)
    assert res.ok, res.failure
    k_t = np.searchsorted(ts, res.times)
    worst = np.inf
    for k, tk in enumerate(k_t):
        x = res.positions[k]
        for j in range(2):
            a, b = ca[tk, j], cb[tk, j]
            s = np.clip((x - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
            d = np.linalg.norm(x - (a + s[:, None] * (b - a)), axis=1) - radii[j]
            worst = min(worst, d.min())
    assert worst > 0.0, worst
    # the legs did push the skirt: some hem vertex moved more than 5 cm horizontally
    hem = mesh.tags["hem"]
    dxy = np.linalg.norm(res.positions[:, hem, :2] - mesh.rest_positions[hem, :2], axis=-1)
    assert dxy.max() > 0.05
