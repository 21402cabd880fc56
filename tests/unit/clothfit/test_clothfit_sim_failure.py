"""The fast scheme reports a blow-up as a failed result, never an exception (seen 2026-11-22)."""

from __future__ import annotations

import numpy as np

from vidsim.cloth import ClothParams, simulate
from vidsim.clothfit.film import swatch_driver, swatch_model_mesh
from vidsim.reality.cloth import corner_paths, swatch_motion


def test_fast_scheme_blow_up_is_a_failure_not_zero_division():
    t = np.arange(24) / 30.0
    cp = corner_paths(swatch_motion("exp1"), t)
    mesh = swatch_model_mesh(cp[0], 16, 0.3)
    drv, t0 = swatch_driver(mesh, t, cp, 0.2)
    # shear = 2 N/m with driven corners made _symplectic_loop raise ZeroDivisionError; at a fixed step
    # (no roll-back) it still blows up, and that is a failed result
    r = simulate(mesh, ClothParams(shear=2.0), drv, t, integrator="fast", t0=t0, dt=1.5e-3)
    assert not r.ok and r.failure is not None
    assert r.frames_done < len(t)
    assert np.all(np.isfinite(r.positions[: r.frames_done]))
    # the automatic step rolls back and halves itself instead, and completes the run
    auto = simulate(mesh, ClothParams(shear=2.0), drv, t, integrator="fast", t0=t0)
    assert auto.ok and auto.stats["dt_halvings"] >= 1, auto.failure
    # a stable parameter set still runs to the end
    ok = simulate(mesh, ClothParams(shear=40.0), drv, t, integrator="fast", t0=t0)
    assert ok.ok and ok.frames_done == len(t)
