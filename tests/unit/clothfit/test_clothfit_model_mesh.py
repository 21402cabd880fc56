"""The estimator's swatch hangs from its gripped corners wherever they are at frame 0."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.clothfit.film import ClothFilmError, swatch_model_mesh


@pytest.mark.parametrize("dz", [0.0, 0.0005, 0.03, -0.05])
def test_corners_at_different_heights_give_a_hanging_square(dz):
    """The downward axis was (0,0,-1) - au_z au instead of + au_z au: orthogonal to the corner line only
    when both corners are level, so mocap-noisy or real corner paths made the mesh builder refuse
    ('axis_u and axis_v must be orthonormal', review 5 Dec 2026)."""
    c = np.array([[-0.15, 0.02, 1.2], [0.15, 0.0, 1.2 + dz]])
    m = swatch_model_mesh(c, 6, 0.3)
    x = m.rest_positions
    np.testing.assert_allclose(x[m.tags["top_corners"]], c, atol=1e-12)
    au = (c[1] - c[0]) / np.linalg.norm(c[1] - c[0])
    down = x[-6] - x[0]  # first vertex of the last row minus the first corner: along the hanging side
    assert abs(np.dot(down, au)) < 1e-12  # a square: the side is perpendicular to the top edge
    assert np.linalg.norm(down) == pytest.approx(0.3)
    assert down[2] < 0  # and it hangs down


def test_corners_one_above_the_other_are_refused():
    with pytest.raises(ClothFilmError, match="one above the other"):
        swatch_model_mesh(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.3]]), 6, 0.3)
