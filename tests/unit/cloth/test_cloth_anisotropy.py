"""Warp/weft stretch stiffnesses (``ClothParams.stretch_anisotropy``) against the hanging-sheet
solution: a sheet held along its top edge stretches under its own weight by rho g H^2 / (2 k_v)."""

import numpy as np
import pytest

from vidsim.cloth import ClothParams, DrivenVertices, simulate, swatch

RHO, G, H = 0.2, 9.81, 0.3


def _hang(params: ClothParams) -> np.ndarray:
    mesh = swatch(10, 10, H, H)
    top = mesh.tags["top_row"]
    drv = DrivenVertices.fixed(top, mesh.rest_positions[top])
    # viscous settle bath for 2 s: the state at t = 2 s is the static equilibrium
    res = simulate(mesh, params, drv, np.array([2.0]), integrator="fast", t0=0.0, settle_bath=30.0, bath_until=2.0)
    assert res.ok, res.failure
    return res.positions[-1]


@pytest.mark.parametrize("a", [np.log(4.0), -np.log(4.0)])
def test_hanging_sheet_stretches_by_its_weft_stiffness(a):
    p = ClothParams(stretch=20.0, shear=20.0, bend=1e-6, density=RHO, drag_linear=0.0, drag_quad=0.0,
                    stretch_anisotropy=a)
    x = _hang(p)
    bottom = x[-10:]
    elong = -bottom[:, 2].mean() - H
    expected = RHO * G * H**2 / (2.0 * p.stretch_weft)
    assert abs(elong - expected) < 0.02 * expected, (elong, expected)
    # the warp (width) hardly changes: no Poisson coupling in the model, the stiffer or softer warp
    width = bottom[:, 0].max() - bottom[:, 0].min()
    assert abs(width - H) < 0.005 * H, width


def test_zero_anisotropy_is_the_isotropic_model():
    p = ClothParams(stretch=20.0, shear=20.0, bend=1e-6, density=RHO)
    assert p.stretch_warp == p.stretch_weft == 20.0
    x0 = _hang(p)
    # (comparing with stretch_anisotropy=0.0 would compare p with itself: it is the default)
    # zero is where the anisotropic model meets the isotropic one continuously, and it acts away from zero
    for eps in (1e-9, -1e-9):
        assert np.abs(_hang(p.replace(stretch_anisotropy=eps)) - x0).max() < 1e-8
    assert np.abs(_hang(p.replace(stretch_anisotropy=0.5)) - x0).max() > 1e-4
    with pytest.raises(ValueError, match="stretch_anisotropy"):
        ClothParams(stretch_anisotropy=float("nan"))
