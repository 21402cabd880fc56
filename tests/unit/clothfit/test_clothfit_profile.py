"""Error profiles: a flat direction is reported as not determined, a sharp one as determined."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.clothfit.profile import indifference_interval, profile_parameters, stopped_short
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


class _Valley:
    """E = 1 + 40 (u0 - u1)^2 + 0.02 (u0 + u1 - 1)^2: a long narrow valley along u0 = u1.
    Each axis is sharp with the other held (a slice), but along the valley the error rises by
    at most 0.02 (2 %): re-optimising the other parameter, neither is determined."""

    def __init__(self):
        self.space = Space.from_config({"bend": {"lo": 1e-7, "hi": 1e-3, "log": True},
                                        "stretch": {"lo": 10.0, "hi": 5000.0, "log": True}})
        self.n = 0

    def f(self, u):
        return 1.0 + 40.0 * (u[0] - u[1]) ** 2 + 0.02 * (u[0] + u[1] - 1.0) ** 2

    def evaluate(self, theta):
        self.n += 1
        e = self.f(np.clip(self.space.to_unit(theta), 0, 1))

        class R:
            score = e

        return R()


def test_a_traded_off_pair_is_determined_by_slices_but_not_by_profiles():
    """The honest check of identifiability: a parameter another can make up for has a flat profile
    (the others re-optimised), though its slice (the others held) is sharp. The profile is never
    above the slice, the re-optimisation's evaluations go through ``f_unit`` (a cache, so a killed
    profile stage resumes), and the estimate's own error is the profile's value there."""
    from vidsim.optim.cache import EvalCache

    obj = _Valley()
    theta = obj.space.from_unit(np.array([0.5, 0.5]))
    sl = {p.name: p for p in profile_parameters(obj, theta, points=9, tol=0.05, max_width=0.5)}
    assert sl["bend"].determined and sl["stretch"].determined
    with EvalCache(lambda u: obj.f(u)) as cache:
        pr = {p.name: p for p in profile_parameters(obj, theta, points=9, tol=0.05, max_width=0.5,
                                                    reoptimise_evals=40, seed=0, f_unit=cache)}
        n_calls, n_cached = len(cache.history), len(cache)
    assert not pr["bend"].determined and not pr["stretch"].determined
    for name in ("bend", "stretch"):
        assert np.all(pr[name].errors <= sl[name].errors + 1e-12)
        assert pr[name].e_hat == sl[name].e_hat == 1.0
        # at the range's ends (the other parameter free) the error is near the valley floor's 1.02
        ends = pr[name].errors[[0, -1]]
        assert np.all(ends < 1.03), ends
        assert np.all(sl[name].errors[[0, -1]] > 5.0)
    # every grid point's slice value and its re-optimisation (40 evaluations) ran through the cache
    # (9 grid points per axis, plus the estimate where it is not one of them; the estimate itself
    # is evaluated directly)
    n_pts = sum(len(p.u) - 1 for p in pr.values())
    assert n_pts in (16, 17, 18)
    assert n_calls == n_pts * (1 + 40), n_calls
    assert n_pts < n_cached <= n_calls
    with pytest.raises(ValueError, match="reoptimise_evals"):
        profile_parameters(obj, theta, reoptimise_evals=-1)


class _Rough(_Bowl):
    """The bowl plus a deterministic 'chaos': a hash of the point, up to 0.3 (the cloth loss moves by
    5-40 of ~175 under 0.2 % changes of a stiffness; docs/posterior.md)."""

    def evaluate(self, theta):
        self.n += 1
        u = np.clip(self.space.to_unit(theta), 0, 1)
        h = np.sin(float(u @ np.array([12.9898, 78.233])) * 43758.5453)
        e = 1.0 + 40.0 * (u[0] - 0.3) ** 2 + 0.02 * u[1] + 0.3 * (h - np.floor(h))

        class R:
            score = e

        return R()


def test_roughness_widens_as_good_on_a_chaotic_loss_and_not_on_a_smooth_one():
    from vidsim.clothfit.profile import roughness

    smooth, rough = _Bowl(), _Rough()
    theta = smooth.space.from_unit(np.array([0.3, 0.5]))
    info_s, info_r = {}, {}
    ps = profile_parameters(smooth, theta, points=9, tol=0.05, roughness_points=12, info=info_s)
    pr = profile_parameters(rough, theta, points=9, tol=0.05, roughness_points=12, info=info_r)
    # smooth: the spread under 1e-3 steps is the slope's (0.02 x 1e-3 and a curvature term): tol stays
    assert info_s["roughness_sd"] < 1e-4 and info_s["tol_effective"] == 0.05
    assert [p.interval_u for p in ps] == [p.interval_u for p in profile_parameters(smooth, theta, points=9, tol=0.05)]
    # rough: a uniform hash of amplitude 0.3 has sd 0.3 / sqrt(12) = 0.087
    assert 0.04 < info_r["roughness_sd"] < 0.14
    e_hat = pr[0].e_hat
    assert info_r["tol_effective"] == pytest.approx(2.0 * info_r["roughness_sd"] / e_hat)
    # "as good" only widens: every interval contains the one measured with tol alone
    for a, b in zip(pr, profile_parameters(rough, theta, points=9, tol=0.05)):
        assert a.interval_u[0] <= b.interval_u[0] and a.interval_u[1] >= b.interval_u[1]
    assert roughness(lambda u: 1.0, np.array([0.5]), 1.0, 0) == 0.0


def test_a_profile_below_the_estimate_is_reported_as_stopped_short():
    # the estimate sits off the bowl's minimum along 'stiff' (u0 = 0.6: E = 4.6 against 1.0 at 0.3)
    # and at it along 'flat' up to its 0.02 slope, which the tolerance covers
    obj = _Bowl()
    theta = obj.space.from_unit(np.array([0.6, 0.0]))
    profs = profile_parameters(obj, theta, points=11, tol=0.05, max_width=0.5)
    short = stopped_short(profs, tol=0.05)
    assert list(short) == ["stiff"]
    assert short["stiff"]["error"] == pytest.approx(1.0 + 40.0 * (0.3 - 0.3) ** 2, abs=1e-9)
    assert short["stiff"]["value"] == pytest.approx(float(obj.space.from_unit(np.array([0.3, 0.0]))[0]))
    assert short["stiff"]["error_at_estimate"] == pytest.approx(1.0 + 40.0 * 0.09)
    # at the minimum nothing is reported
    at_min = profile_parameters(_Bowl(), obj.space.from_unit(np.array([0.3, 0.0])), points=11, tol=0.05)
    assert stopped_short(at_min, tol=0.05) == {}
