"""Resolution independence: same parameters, 10x10 / 20x20 / 40x40 swatches."""

import numpy as np
import pytest

from vidsim.cloth import DrivenVertices, mid_range_params, simulate, swatch

SIZE = 0.3


def wave(mesh):
    """Top corners waved: 5 cm side-to-side at 1.5 Hz, 8 cm back-and-forth at 1 Hz."""
    idx = mesh.tags["top_corners"]
    p0 = mesh.rest_positions[idx]

    def fn(t):
        off = np.array([0.05 * np.sin(2 * np.pi * 1.5 * t), 0.08 * np.sin(2 * np.pi * 1.0 * t),
                        0.03 * (1 - np.cos(2 * np.pi * 1.5 * t))])
        return p0 + off

    return DrivenVertices.from_function(idx, fn, 0.0, 50 / 30, 1000.0)


@pytest.fixture(scope="module")
def trajectories():
    """Bottom-corner trajectories (50 frames at 30 Hz) for 10x10, 20x20 and 40x40 swatches.

    Parameters: mid-range, except bending 1e-4 N m and bend damping 1e-6 N m s (top of
    their ranges, a stiff fabric). With mid-range bending (3e-6 N m) the bending length
    (D / (rho g))^(1/3) is about 1 cm, finer than a 10x10 mesh (3.3 cm edges) can fold,
    and the meshes disagree by up to 13 % of the swatch size (measured): resolution
    independence holds only where the mesh resolves the bending length.
    """
    p = mid_range_params(bend=1e-4, bend_damping=1e-6)
    times = np.arange(50) / 30.0
    traj = {}
    for n in (10, 20, 40):
        mesh = swatch(n, n, SIZE, SIZE)
        res = simulate(mesh, p, wave(mesh), times, integrator="fast")
        assert res.ok, res.failure
        traj[n] = res.positions[:, mesh.tags["corners"][2:]]  # the two free bottom corners
    moved = np.max(np.linalg.norm(traj[40] - traj[40][:1], axis=-1))
    assert moved > 0.1 * SIZE, "the bottom corners hardly moved"
    return traj


@pytest.mark.slow
def test_20x20_and_40x40_corner_trajectories_agree(trajectories):
    dev = np.max(np.linalg.norm(trajectories[20] - trajectories[40], axis=-1))
    assert dev < 0.05 * SIZE, dev


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="known shortfall: 10x10 deviates from 40x40 by up to 2.7 cm "
                   "(9 % of the swatch) in the first 0.3 s and 1.6 cm (5.2 %) afterwards (measured)")
def test_10x10_agrees_over_all_50_frames(trajectories):
    dev = np.max(np.linalg.norm(trajectories[10] - trajectories[40], axis=-1))
    assert dev < 0.05 * SIZE, dev
