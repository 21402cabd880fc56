"""The settle bath: a viscous preparation that brings a hanging swatch to rest before frame 0."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.cloth import ClothInputError, simulate
from vidsim.clothfit.film import swatch_driver, swatch_model_mesh
from vidsim.gap.cloth_suite import ClothSceneConfig, twin_truth_params
from vidsim.reality.cloth import ClothRealityError, corner_paths, fabric_profile, simulate_swatch, swatch_motion

FRAMES = np.arange(0, 7) / 30.0


def _run(settle_s: float, bath: float, **kw):
    p = twin_truth_params(ClothSceneConfig(), {})
    cp = corner_paths(swatch_motion("exp1"), FRAMES)
    mesh = swatch_model_mesh(cp[0], 8, 0.3)
    drv, t0 = swatch_driver(mesh, FRAMES, cp, settle_s)
    return simulate(mesh, p, drv, FRAMES, integrator="fast", t0=t0, settle_bath=bath, **kw)


def test_bath_brings_the_hanging_swatch_to_its_equilibrium():
    free = _run(0.5, 0.0)
    bathed = {s: _run(s, 20.0) for s in (0.5, 1.0)}
    speed = {k: np.linalg.norm(r.velocities[0], axis=1).mean() for k, r in
             (("free", free), ("0.5", bathed[0.5]), ("1.0", bathed[1.0]))}
    # without the bath the swatch still swings at frame 0 (flat start, stretch sag);
    # with it (critical damping of the ~7 rad/s modes) it is at rest
    assert speed["free"] > 0.01
    assert speed["0.5"] < 0.05 * speed["free"] and speed["1.0"] < 0.01 * speed["free"]
    # the frame-0 state no longer depends on how long the settle lasted: it is the equilibrium
    d_bath = np.abs(bathed[0.5].positions[0] - bathed[1.0].positions[0]).max()
    d_free = np.abs(free.positions[0] - _run(1.0, 0.0).positions[0]).max()
    assert d_bath < 0.1 * d_free


def test_bath_ends_at_bath_until():
    """After the bath the motion is the undamped model's: same as restarting from the bathed state."""
    full = _run(0.5, 20.0, dt=2e-4)
    p = twin_truth_params(ClothSceneConfig(), {})
    cp = corner_paths(swatch_motion("exp1"), FRAMES)
    mesh = swatch_model_mesh(cp[0], 8, 0.3)
    drv, _ = swatch_driver(mesh, FRAMES, cp, 0.5)
    rest = simulate(mesh, p, drv, FRAMES, integrator="fast", t0=0.0, x0=full.positions[0], v0=full.velocities[0],
                    dt=2e-4)
    np.testing.assert_allclose(rest.positions, full.positions, atol=1e-9)
    # and the bath did act before: the bathed run differs from the free one
    assert np.abs(full.positions[-1] - _run(0.5, 0.0, dt=2e-4).positions[-1]).max() > 1e-4


def test_bath_input_errors():
    with pytest.raises(ClothInputError, match="settle_bath"):
        _run(0.5, -1.0)
    with pytest.raises(ClothInputError, match="settle_bath .* too strong"):
        _run(0.5, 1e4, dt=1e-3)
    with pytest.raises(ClothInputError, match="bath_until must be a finite time"):
        _run(0.5, 20.0, bath_until=float("nan"))
    with pytest.raises(ClothRealityError, match="settle_bath"):
        simulate_swatch(fabric_profile("linen"), swatch_motion("exp1"), {}, np.random.default_rng(0),
                        resolution=5, n_frames=2, settle_bath=float("nan"))


def test_mujoco_reality_bath_reaches_the_same_rest_state():
    def x0(settle, bath):
        run = simulate_swatch(fabric_profile("linen"), swatch_motion("exp1"), {}, np.random.default_rng(1),
                              resolution=11, n_frames=2, settle=settle, settle_bath=bath)
        assert run.ok
        return run.vertices[0]

    d_free = np.abs(x0(0.7, 0.0) - x0(1.4, 0.0)).max()
    d_bath = np.abs(x0(0.7, 20.0) - x0(1.4, 20.0)).max()
    assert d_bath < 1e-8 and d_bath < 0.01 * d_free


def test_a_strong_bath_shortens_the_automatic_step_to_its_stability_limit():
    """The bath is one more damping rate: velocity Verlet needs omega^2 h^2 + 2 (c + bath) h <= 4.
    A bath at 0.45 / h passes the old guard (bath x dt <= 0.5) but is unstable at the step estimated
    without it (a stiff, undamped swatch needed a roll-back and halving; review, 5 Dec 2026)."""
    from vidsim.cloth import ClothParams, stable_step

    p = ClothParams(stretch=3000.0, shear=500.0, bend=4e-5, stretch_damping=0.0, shear_damping=0.0,
                    bend_damping=0.0)
    cp = corner_paths(swatch_motion("exp1"), FRAMES)
    mesh = swatch_model_mesh(cp[0], 12, 0.3)
    drv, t0 = swatch_driver(mesh, FRAMES, cp, 0.5)
    h, info = stable_step(mesh, p, mesh.rest_positions, driven=drv.indices)
    bath = 0.45 / h
    r = simulate(mesh, p, drv, FRAMES, integrator="fast", t0=t0, settle_bath=bath)
    assert r.ok, r.failure
    h_bath = r.stats["h_stable_with_bath"]
    assert h_bath < info["h_stable"]  # the bath lowers the limit
    assert r.stats["dt_halvings"] == 0 and r.dt <= 0.9 * h_bath * (1 + 1e-12)
    with pytest.raises(ClothInputError, match="too strong for the fixed step"):
        simulate(mesh, p, drv, FRAMES, integrator="fast", t0=t0, settle_bath=bath, dt=1.01 * h_bath)
