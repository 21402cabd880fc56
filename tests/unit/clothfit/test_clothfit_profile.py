"""Error profiles: a flat direction is reported as not determined, a sharp one as determined."""

from __future__ import annotations

import numpy as np

from vidsim.clothfit.profile import indifference_interval, profile_parameters
from vidsim.optim.space import Space


class _Bowl:
    """E = 1 + 40 (u0 - 0.3)^2 + 0.02 u1 (u1 nearly flat) on the unit cube of a 2-D space."""

    def __init__(self):
        self.space = Space.from_config({"stiff": {"lo": 1.0, "hi": 1000.0, "log": True},
                                        "flat": {"lo": 0.0, "hi": 2.0, "log": False}})
        self.n = 0

    def evaluate(self, theta):
        self.n += 1
        u = self.space.to_unit(theta)

        class R:
            score = 1.0 + 40.0 * (u[0] - 0.3) ** 2 + 0.02 * u[1]

        return R()


def test_flat_parameter_is_not_determined_and_sharp_one_is():
    obj = _Bowl()
    theta = obj.space.from_unit(np.array([0.3, 0.5]))
    profs = {p.name: p for p in profile_parameters(obj, theta, points=9, tol=0.05, max_width=0.5)}
    assert profs["stiff"].determined and not profs["flat"].determined
    # the interval of the sharp axis is where 40 (u - 0.3)^2 <= 0.05: |u - 0.3| <= 0.035 (grid-interpolated)
    lo, hi = profs["stiff"].interval_u
    assert 0.2 < lo < 0.3 < hi < 0.4
    assert profs["flat"].width > 0.9
    # the estimate once, then each axis' grid without the estimate (0.5 is a grid point of 'flat', 0.3 is not)
    assert obj.n == 1 + 9 + 8
    # interval in physical units is in the log axis' unit (the estimate lies inside)
    v = float(theta[0])
    assert profs["stiff"].interval[0] < v < profs["stiff"].interval[1]


def test_indifference_interval_stops_at_the_first_crossing():
    u = np.linspace(0, 1, 11)
    e = np.array([5, 1.2, 1.0, 1.2, 5, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0])  # a second basin right of a barrier
    lo, hi = indifference_interval(u, e, 0.2, 1.0, 0.5)
    assert 0.0 < lo < 0.1 and 0.3 < hi < 0.4  # the far basin is not joined
