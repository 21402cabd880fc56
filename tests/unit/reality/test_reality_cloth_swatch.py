"""MuJoCo cloth reality: the swatch hangs, follows its grips, fabrics and effects differ."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.reality.cloth import (
    ClothRealityError,
    air_forces,
    corner_paths,
    fabric_profile,
    resolve_effects,
    simulate_swatch,
    swatch_motion,
)

SMALL = {"resolution": 11, "n_frames": 30, "settle": 0.7}


def _edge_strain(run, frame: int) -> np.ndarray:
    f = run.faces
    e = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [0, 2]]]), axis=1), axis=0)
    x, x0 = run.vertices[frame], run.truth["rest_vertices"]
    return np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1) / np.linalg.norm(x0[e[:, 0]] - x0[e[:, 1]], axis=1) - 1


@pytest.fixture(scope="module")
def fabric_runs():
    return {
        name: simulate_swatch(fabric_profile(name), swatch_motion("exp1"), {}, np.random.default_rng(1), **SMALL)
        for name in ("linen", "fleece", "satin", "knit")
    }


def test_hangs_without_exploding_and_stays_attached(fabric_runs):
    run = fabric_runs["linen"]
    assert run.ok and run.failure is None
    assert run.vertices.shape == (30, 121, 3) and run.faces.shape == (200, 3)
    assert np.isfinite(run.vertices).all()
    np.testing.assert_allclose(run.times, np.arange(30) / 30.0)
    ids = run.truth["corner_vertex_ids"]
    # the gripped vertices are exactly on the (true = measured, no slip) corner path ...
    np.testing.assert_allclose(run.vertices[:, ids], run.corner_paths_measured, atol=1e-9)
    # ... and the cloth next to them is not torn away: linen strains stay tiny everywhere
    assert max(_edge_strain(run, k).max() for k in (0, 15, 29)) < 0.01
    # at rest (frame 0, after settling) it hangs as a flat 0.3 m square below the grips
    x0 = run.vertices[0]
    assert np.ptp(x0[:, 2]) == pytest.approx(0.3, abs=0.003)
    assert np.ptp(x0[:, 1]) < 0.005
    assert x0[:, 2].max() <= 1.0 + 1e-6
    # while waving, nothing flies off: every vertex stays within the swatch size of the grips
    mid = run.corner_paths_measured.mean(axis=1)
    assert np.linalg.norm(run.vertices - mid[:, None, :], axis=2).max() < 0.3 * np.sqrt(1.25) + 0.02


def test_fabrics_differ_consistently_with_stiffness(fabric_runs):
    sag = {k: np.ptp(r.vertices[0, :, 2]) for k, r in fabric_runs.items()}
    # stretch under its own weight: knit (25 N/m) >> fleece (300 N/m) > linen, satin
    assert sag["knit"] > sag["fleece"] + 0.005
    assert sag["fleece"] > max(sag["linen"], sag["satin"]) + 0.0005
    # droop of the top edge between the grips: stiffest (linen) least, stretchy knit most
    droop = {}
    for k, r in fabric_runs.items():
        top = np.argmin(np.linalg.norm(r.truth["rest_vertices"] - [0.0, 0.0, 1.0], axis=1))
        droop[k] = 1.0 - r.vertices[0, top, 2]
    assert droop["linen"] < droop["satin"] < droop["fleece"] < droop["knit"]
    # and the motions differ measurably (cm scale) between every pair of fabrics
    names = list(fabric_runs)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            diff = np.abs(fabric_runs[a].vertices - fabric_runs[b].vertices).max()
            assert diff > 0.01, f"{a} and {b} move alike (max difference {diff:.4f} m)"


def test_air_forces_match_closed_form():
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # area 0.5, normal +z
    f = np.array([[0, 1, 2]])
    rho, cd, cl, cf = 1.2, 1.1, 0.7, 0.05
    q = 0.5 * rho * 0.5
    # moving along the normal: pure pressure drag, no lift, no friction
    v = np.tile([0.0, 0.0, 2.0], (3, 1))
    tot = air_forces(x, v, f, np.zeros(3), rho, cd, cl, cf).sum(axis=0)
    np.testing.assert_allclose(tot, [0, 0, -cd * q * 4.0], atol=1e-12)
    # moving in the plane: friction only
    v = np.tile([3.0, 0.0, 0.0], (3, 1))
    tot = air_forces(x, v, f, np.zeros(3), rho, cd, cl, cf).sum(axis=0)
    np.testing.assert_allclose(tot, [-cf * q * 9.0, 0, 0], atol=1e-12)
    # still plate in a 45-degree wind: drag along the normal plus lift perpendicular to the wind
    wind = np.array([0.0, -np.sqrt(2), np.sqrt(2)])  # |w| = 2 m/s at 45 degrees to the plate
    v = np.zeros((3, 3))
    tot = air_forces(x, v, f, -wind, rho, cd, 0.0, 0.0).sum(axis=0)
    un = wind[2]  # relative velocity u = v - (-wind) = wind; u.n = sqrt(2)
    np.testing.assert_allclose(tot, [0, 0, -cd * q * un * un], atol=1e-12)
    lift_only = air_forces(x, v, f, -wind, rho, 0.0, cl, 0.0).sum(axis=0)
    assert abs(lift_only @ wind) < 1e-12  # perpendicular to the relative air velocity
    assert np.linalg.norm(lift_only) == pytest.approx(cl * q * 4.0 * 0.5, rel=1e-12)


def test_air_drag_damps_the_swing():
    fab = fabric_profile("satin")
    off = simulate_swatch(fab, swatch_motion("exp1"), {}, np.random.default_rng(0), **SMALL)
    on = simulate_swatch(fab, swatch_motion("exp1"), {"air_drag": {"on": True}}, np.random.default_rng(0), **SMALL)
    assert on.ok and off.ok

    def swing(run):
        bottom = np.argmin(np.linalg.norm(run.truth["rest_vertices"] - [0.0, 0.0, 0.7], axis=1))
        return np.ptp(run.vertices[:, bottom, 1] - run.corner_paths_measured[:, :, 1].mean(axis=1))

    assert swing(on) < 0.95 * swing(off)


@pytest.mark.parametrize(
    "effects",
    [
        {"wind": {"on": True, "velocity": [0.0, 1.5, 0.0]}},
        {"wind": {"on": True, "velocity": [0.0, 1.5, 0.0], "gust": 0.8}},
        {"anisotropy": {"on": True, "warp": 40.0, "weft": 0.0}},
        {"strain_stiffening": {"on": True, "c3": 300.0}},
        {"grip_slip": {"on": True, "drop": 0.01, "lag": 0.03}},
        {"gravity_tilt": {"on": True, "degrees": 5.0}},
        {"bending_plasticity": {"on": True, "yield_strain": 2e-4}},
        {"mocap_noise": {"on": True, "sigma": 0.002}},
    ],
)
def test_effects_switch_on_and_change_the_motion(effects):
    small = {"resolution": 9, "n_frames": 20, "settle": 0.5}
    fab = fabric_profile("knit")
    (name,) = effects
    # the wind acts through the air: its base is the swatch in still air, not in vacuum
    base_eff = {"air_drag": {"on": True}} if name == "wind" else {}
    base = simulate_swatch(fab, swatch_motion("exp2"), base_eff, np.random.default_rng(3), **small)
    run = simulate_swatch(fab, swatch_motion("exp2"), {**base_eff, **effects}, np.random.default_rng(3), **small)
    assert run.ok, run.failure
    assert run.truth["effects"][name]["on"] is True
    slip = np.abs(run.truth["corner_paths_true"] - run.corner_paths_measured)
    if name == "mocap_noise":  # only the measurement changes: the cloth is untouched
        np.testing.assert_array_equal(run.vertices, base.vertices)
        assert 0.0017 < np.sqrt(np.mean(slip**2)) < 0.0023  # RMS error = sigma (120 samples)
        return
    assert np.abs(run.vertices - base.vertices).max() > 0.01
    if name == "grip_slip":
        assert slip.max() > 0.005  # the measured path (meta) is not the path the cloth followed
    else:
        assert slip.max() == 0.0


def test_seed_reproducible_and_seed_matters():
    eff = {"air_drag": {"on": True}, "wind": {"on": True, "velocity": [0.0, 1.5, 0.0], "gust": 0.8}}
    small = {"resolution": 9, "n_frames": 15, "settle": 0.3}
    a = simulate_swatch(fabric_profile("satin"), swatch_motion("robot"), eff, np.random.default_rng(7), **small)
    b = simulate_swatch(fabric_profile("satin"), swatch_motion("robot"), eff, np.random.default_rng(7), **small)
    c = simulate_swatch(fabric_profile("satin"), swatch_motion("robot"), eff, np.random.default_rng(8), **small)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    assert np.abs(a.vertices - c.vertices).max() > 1e-3  # gust phases come from the generator


def test_trials_differ_slightly_and_robot_differs_more():
    t = np.arange(50) / 30.0
    e1, e2, rb = (corner_paths(swatch_motion(k), t) for k in ("exp1", "exp2", "robot"))
    d12, d1r = np.abs(e1 - e2).max(), np.abs(e1 - rb).max()
    assert 0.01 < d12 < d1r
    np.testing.assert_allclose(np.linalg.norm(e1[:, 1] - e1[:, 0], axis=1), 0.3)  # rigid grip bar
    np.testing.assert_allclose(e1[0], [[-0.15, 0.0, 1.0], [0.15, 0.0, 1.0]], atol=1e-12)  # starts at rest


def test_grip_squeeze_brings_the_grips_together_and_is_off_by_default():
    t = np.arange(60) / 30.0
    mot = swatch_motion("exp1")
    assert "squeeze" not in mot  # the named motions keep the grips 0.3 m apart
    sq = {**mot, "squeeze": 0.35}
    gap = np.linalg.norm(np.diff(corner_paths(sq, t), axis=1)[:, 0], axis=1)
    np.testing.assert_allclose(gap[0], 0.3, atol=1e-12)  # at rest: the swatch's width
    # the grips come together by up to 35 % once the ramp is over (cos term: minimum at f t = 1/2)
    assert 0.3 * 0.65 - 1e-3 < gap.min() < 0.3 * 0.7 and gap.max() <= 0.3 + 1e-12
    mid = 0.5 * corner_paths(sq, t).sum(axis=1)
    np.testing.assert_allclose(mid, 0.5 * corner_paths(mot, t).sum(axis=1), atol=1e-12)  # the bar's centre is unchanged
    with pytest.raises(ClothRealityError, match="squeeze"):
        corner_paths({**mot, "squeeze": 0.9}, t)


def test_bad_inputs_raise_clear_errors():
    with pytest.raises(ClothRealityError, match="unknown effect"):
        resolve_effects({"wnd": {"on": True}})
    with pytest.raises(ClothRealityError, match="veloc"):
        resolve_effects({"wind": {"veloc": 1}})
    # values are checked by name before any simulation
    for bad, match in (({"air_drag": {"on": True, "density": -5.0}}, r"\['air_drag'\]\['density'\] must be a number >= 0"),
                       ({"air_drag": {"on": True}, "wind": {"on": True, "velocity": [1.0, 2.0]}}, r"\['wind'\]\['velocity'\] must be 3"),
                       ({"air_drag": {"on": "false"}}, r"\['air_drag'\]\['on'\] must be true or false"),
                       ({"grip_slip": {"on": True, "drop": -0.05}}, r"\['grip_slip'\]\['drop'\]"),
                       ({"strain_stiffening": {"on": True, "c3": -1.0, "stiffness": -300.0}}, r"\['strain_stiffening'\]\['c3'\]"),
                       ({"mocap_noise": {"on": True, "sigma": -1e-3}}, r"\['mocap_noise'\]\['sigma'\]"),
                       ({"wind": {"on": True}}, "wind.*air_drag.*off")):
        with pytest.raises(ClothRealityError, match=match):
            resolve_effects(bad)
    fab = fabric_profile("linen")
    fab["bend"] = -1.0
    with pytest.raises(ClothRealityError, match="bend"):
        simulate_swatch(fab, swatch_motion("exp1"), {}, np.random.default_rng(0))
    with pytest.raises(ClothRealityError, match="fabric name"):
        fabric_profile("silk")
    mot = swatch_motion("exp1")
    mot["width"] = 0.5
    with pytest.raises(ClothRealityError, match="width"):
        simulate_swatch(fabric_profile("linen"), mot, {}, np.random.default_rng(0), n_frames=2, settle=0.0)


def test_divergence_returns_a_failure_not_an_exception():
    """A hurricane (300 m/s wind) blows the explicit air forces up: a flagged run, no NaN, no raise."""
    run = simulate_swatch(fabric_profile("satin"), swatch_motion("exp1"),
                          {"air_drag": {"on": True}, "wind": {"on": True, "velocity": [0.0, 300.0, 0.0]}}, np.random.default_rng(0),
                          resolution=9, n_frames=20, settle=0.3)
    assert not run.ok and run.failure
    assert len(run.vertices) < 20 and np.isfinite(run.vertices).all()
    assert len(run.times) == len(run.vertices) == len(run.corner_paths_measured)


def test_extra_edge_springs_strips_add_up_to_the_swatch_width():
    """Each grid line of edges carries a strip of the width h, the two border lines h/2: n lines
    then carry exactly the swatch's width, so the membrane N/m written to the truth is the one the
    springs apply (all lines at h made it n/(n-1) too stiff: 7 % at 15 vertices)."""
    from vidsim.reality.cloth import _border_halves

    size, n = 0.3, 15
    h = size / (n - 1)
    coord = np.repeat(np.linspace(-size / 2, size / 2, n), n - 1)  # n lines of n-1 edges each
    w = _border_halves(coord)
    assert np.isclose(np.sum(w * h) / (n - 1), size)
    assert np.count_nonzero(w == 0.5) == 2 * (n - 1)
