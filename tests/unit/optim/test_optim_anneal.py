"""Simulated annealing, grid, evaluation cache: recovery on known functions; NaN-safety; replay."""

from __future__ import annotations

import numpy as np
import pytest

from vidsim.errors import ConfigError
from vidsim.optim import FAILED_SCORE
from vidsim.optim.anneal import AnnealConfig, anneal
from vidsim.optim.cache import EvalCache
from vidsim.optim.grid import grid_points, grid_search
from vidsim.optim.space import Axis, Space


def rosenbrock(u):
    x = 4 * np.asarray(u) - 2  # [-2, 2]^n, minimum at (1, ..., 1) -> u = 0.75
    return float(np.sum(100 * (x[1:] - x[:-1] ** 2) ** 2 + (1 - x[:-1]) ** 2))


def rastrigin(u):
    x = 10.24 * np.asarray(u) - 5.12 - 0.9  # shifted minimum
    x = x + 0.9
    return float(10 * x.size + np.sum(x * x - 10 * np.cos(2 * np.pi * x)))


def test_anneal_finds_rosenbrock_minimum():
    r = anneal(rosenbrock, np.array([0.2, 0.3, 0.25]), AnnealConfig(budget=3000, seed=1))
    assert r.n_evals == 3000
    assert r.best_f < 1e-2
    assert np.allclose(r.best_u, 0.75, atol=0.03)
    assert np.all(np.diff(r.best_trace) <= 0)
    assert len(r.resets) >= 1  # the schedule reached at least one simplex reset


def test_simplex_resets_at_the_best_point_each_time_the_temperature_falls_threefold():
    """The schedule of the issue: geometric cooling, and a new simplex at the best point so far each
    time the temperature has fallen by a factor of three since the last reset (or the start)."""
    pts = []

    def f(u):
        pts.append(np.array(u, float))
        return rosenbrock(u)

    cfg = AnnealConfig(budget=3000, seed=1)
    r = anneal(f, np.array([0.2, 0.3, 0.25]), cfg)
    T = r.temperatures
    assert len(r.resets) >= 3
    s0 = int(np.argmax(T > 0))  # the start simplex is evaluated before T0 is set (from its spread)
    assert s0 == 4 and np.all(T[s0:] > 0)
    T = T[s0:]
    # geometric cooling: every change of temperature is one factor `cooling`
    steps = T[1:][T[1:] != T[:-1]] / T[:-1][T[1:] != T[:-1]]
    assert len(steps) > 30 and np.allclose(steps, cfg.cooling)
    T = r.temperatures
    ref = T[s0]
    for k in r.resets:
        # the temperature has just fallen below 1/3 of the last reset's (not earlier, not later)
        assert T[k] <= ref / cfg.reset_factor * (1 + 1e-12) < T[k] / cfg.cooling
        ref = T[k]
        # the new simplex's first vertex is the best point evaluated so far
        np.testing.assert_array_equal(pts[k], pts[int(np.argmin(r.trace[:k]))])


def test_anneal_escapes_local_minima_better_than_zero_temperature():
    """Rastrigin from a poor start: with temperature, annealing ends lower than plain simplex (T ~ 0)."""
    u0 = np.full(4, 0.15)
    hot = [anneal(rastrigin, u0, AnnealConfig(budget=800, seed=s, T0=20.0)).best_f for s in range(4)]
    cold = [anneal(rastrigin, u0, AnnealConfig(budget=800, seed=s, T0=1e-9)).best_f for s in range(4)]
    assert np.median(hot) < np.median(cold)


def test_failed_evaluations_are_bad_scores_not_crashes():
    def sometimes_nan(u):  # "diverges" beyond u0 = 0.6, the optimum (0.58, 0.4) sits near that edge
        if u[0] > 0.6:
            return float("nan")
        return float(np.sum((u - [0.58, 0.4]) ** 2))

    with EvalCache(sometimes_nan) as f:
        r = anneal(f, np.array([0.2, 0.2]), AnnealConfig(budget=300, seed=0))
    assert np.isfinite(r.best_f) and r.best_f < 1e-4
    assert FAILED_SCORE in r.trace  # the NaN region was visited and scored as failed
    assert not np.any(np.isnan(r.trace))


def test_replay_through_cache_gives_identical_run(tmp_path):
    calls = {"n": 0}

    def counted(u):
        calls["n"] += 1
        return rosenbrock(u)

    log = tmp_path / "evals.jsonl"
    with EvalCache(counted, log) as f:
        anneal(f, np.array([0.2, 0.3]), AnnealConfig(budget=120, seed=3))
    first = calls["n"]
    # a "killed" run: keep only the first 70 lines (plus a torn line), then rerun with a larger budget
    lines = log.read_text().splitlines()[:70]
    log.write_text("\n".join(lines) + '\n{"key": "torn')
    calls["n"] = 0
    with EvalCache(counted, log) as f:
        resumed = anneal(f, np.array([0.2, 0.3]), AnnealConfig(budget=120, seed=3))
    with EvalCache(rosenbrock) as f:
        fresh = anneal(f, np.array([0.2, 0.3]), AnnealConfig(budget=120, seed=3))
    assert calls["n"] == first - 70  # only the evaluations after the kill point were recomputed
    assert resumed.best_f == fresh.best_f and np.array_equal(resumed.best_u, fresh.best_u)
    assert np.array_equal(resumed.trace, fresh.trace)
    # a kill between a whole record and its newline: the record stays in the log (and is not redone)
    lines = log.read_text().splitlines()[:40]
    log.write_text("\n".join(lines))
    calls["n"] = 0
    with EvalCache(counted, log) as f:
        again = anneal(f, np.array([0.2, 0.3]), AnnealConfig(budget=120, seed=3))
    assert calls["n"] == first - 40 and np.array_equal(again.trace, fresh.trace)
    assert log.read_text().splitlines()[:40] == lines


def test_grid_search_and_space():
    sp = Space((Axis("k", 1e-6, 1e-2, log=True), Axis("d", 0.0, 10.0)))
    th = np.array([1e-4, 2.5])
    assert np.allclose(sp.from_unit(sp.to_unit(th)), th)
    assert np.allclose(sp.to_unit(th), [0.5, 0.25])
    pts = grid_points([0, 1], levels=4, n=2)
    vals, best = grid_search(lambda u: float(np.sum((u - [0.62, 0.4]) ** 2)), pts)
    assert pts.shape == (16, 2) and np.allclose(best, [0.625, 0.375])
    with pytest.raises(ConfigError, match="'k'"):
        Axis("k", 0.0, 1.0, log=True)
    with pytest.raises(ConfigError, match="budget"):
        AnnealConfig(budget=0)


def test_bad_schedules_and_log_values_name_what_is_wrong():
    """A schedule that cannot run, and a value a log axis cannot map, are refused by name (the
    config prefix the caller gives), never run on as a silent -inf or an endless loop."""
    with pytest.raises(ConfigError, match=r"cloth\.fit\.cooling"):
        AnnealConfig(cooling=1.0, name="cloth.fit")
    with pytest.raises(ConfigError, match=r"cloth\.fit\.evals_per_T"):
        AnnealConfig(evals_per_T=0, name="cloth.fit")
    with pytest.raises(ConfigError, match=r"min_step"):
        AnnealConfig(step=0.1, min_step=0.2)
    with pytest.raises(ConfigError, match="temperature"):
        AnnealConfig(T0=float("nan"))
    sp = Space((Axis("d", 0.0, 10.0), Axis("k", 1e-6, 1e-2, log=True)))
    with pytest.raises(ConfigError, match=r"'k' = -1\.0.*logarithmic"):
        sp.to_unit(np.array([[1.0, 1e-4], [2.0, -1.0]]))
    with pytest.raises(ConfigError, match="'k'"):
        sp.to_unit(np.array([1.0, np.nan]))
    # a linear axis takes zero and negatives (outside the box maps outside [0, 1])
    assert np.allclose(sp.to_unit(np.array([-5.0, 1e-2])), [-0.5, 1.0])


def test_nan_without_a_cache_is_a_bad_score_for_anneal_and_grid():
    """The optimisers map a non-finite value to FAILED_SCORE themselves: without an EvalCache a NaN
    in the starting simplex froze the search (never replaced, never shrunk away) and grid_search
    returned the NaN point as its best."""
    def nan_left(u):
        return float("nan") if u[0] < 0.3 else float(np.sum((u - [0.6, 0.4]) ** 2))

    r = anneal(nan_left, np.array([0.31, 0.5]), AnnealConfig(budget=300, seed=0, step=0.15))
    assert FAILED_SCORE in r.trace and not np.any(np.isnan(r.trace))
    assert r.best_f < 1e-3  # from 0.094 at the start
    vals, best = grid_search(nan_left, grid_points([0, 1], 4))
    assert not np.any(np.isnan(vals)) and best[0] > 0.3
    # CMA-ES too: cma itself would replace a NaN by the generation's median, silently
    from vidsim.optim.cmaes import cmaes

    _, fb, tr = cmaes(nan_left, np.array([0.31, 0.5]), 200, sigma0=0.2, seed=0)
    assert FAILED_SCORE in tr and not np.any(np.isnan(tr)) and fb < 1e-3


def test_cache_turns_a_numerical_fault_into_a_failed_score_it_names(tmp_path):
    """A numba kernel's division by zero raises ZeroDivisionError (an ArithmeticError, not a
    FloatingPointError) and a singular solve LinAlgError: both are failed points, logged with
    their reason, not crashes of the fit; any other error still stops it."""
    def faulty(u):
        if u[0] < 0.3:
            raise ZeroDivisionError("division by zero")
        if u[0] > 0.9:
            raise np.linalg.LinAlgError("Singular matrix")
        if 0.5 < u[0] < 0.51:
            raise ValueError("a bug, not a numerical fault")
        return float(np.sum((u - 0.6) ** 2))

    with EvalCache(faulty, tmp_path / "evals.jsonl") as f:
        assert f(np.array([0.1, 0.5])) == FAILED_SCORE and f(np.array([0.95, 0.5])) == FAILED_SCORE
        assert f(np.array([0.6, 0.6])) == 0.0
        with pytest.raises(ValueError, match="a bug"):
            f(np.array([0.505, 0.5]))
    log = (tmp_path / "evals.jsonl").read_text()
    assert "ZeroDivisionError: division by zero" in log and "LinAlgError: Singular matrix" in log


def test_bad_seed_step_and_space_types_are_refused_by_name():
    with pytest.raises(ConfigError, match=r"cloth\.fit\.seed"):
        AnnealConfig(seed=-1, name="cloth.fit")
    with pytest.raises(ConfigError, match=r"step must be in \(0, 0\.5\]"):
        AnnealConfig(step=0.6)
    # Hydra passes `log=no` as the string "no", and bool("no") is True
    for bad in ("no", "false", 0):
        with pytest.raises(ConfigError, match=r"'bend': log must be true or false"):
            Space.from_config({"bend": {"lo": 1e-7, "hi": 1e-4, "log": bad}})
    with pytest.raises(ConfigError, match="lo and hi must be numbers"):
        Space.from_config({"bend": {"lo": True, "hi": 2.0}})
    assert Space.from_config({"bend": {"lo": 1e-7, "hi": 1e-4, "log": True}}).axes[0].log


def test_cmaes_spends_exactly_its_budget_restarting_after_an_early_stop():
    """CMA-ES on a function with a flat region stopped after 24 of 600 evaluations (cma's tolfun);
    now it restarts from its best point until the budget is spent. Fixed seeds reproduce the run,
    and a smooth quadratic inside the cube is solved."""
    from vidsim.optim.cmaes import cmaes

    def flat_then_bowl(u):  # flat (all "failed") unless near the bowl at 0.8
        d = float(np.sum((u - 0.8) ** 2))
        return FAILED_SCORE if d > 0.05 else d

    stops: list = []
    u, fb, tr = cmaes(flat_then_bowl, np.full(3, 0.2), 600, sigma0=0.05, seed=3, stops=stops)
    assert len(tr) == 600 and len(stops) >= 2 and ("tolfun" in stops[0] or "tolflatfitness" in stops[0])
    u2, fb2, tr2 = cmaes(flat_then_bowl, np.full(3, 0.2), 600, sigma0=0.05, seed=3)
    assert np.array_equal(tr, tr2) and np.array_equal(u, u2)
    uq, fq, trq = cmaes(lambda v: float(np.sum((v - [0.3, 0.7, 0.5]) ** 2)), np.full(3, 0.5), 400, seed=0)
    assert len(trq) == 400 and fq < 1e-10 and np.all((uq >= 0) & (uq <= 1))
    with pytest.raises(ConfigError, match="seed"):
        cmaes(flat_then_bowl, np.full(3, 0.2), 10, seed=-1)


def test_observe_reports_the_exact_rejection_threshold_and_changes_nothing():
    """``observe(y, y_reject)``: a move is rejected exactly when y >= y_reject. Replacing every
    rejected move's value by a larger one (what an early-stopped simulation would report) must
    leave the run unchanged, and one value just under its threshold must change it."""
    cfg = AnnealConfig(budget=400, seed=3)
    u0 = np.array([0.2, 0.3, 0.25])
    plain = anneal(rosenbrock, u0, cfg)
    n_calls = [0]

    def counted(u):
        n_calls[0] += 1
        return rosenbrock(u)

    seen = []  # (evaluation index, y, threshold)
    observed = anneal(counted, u0, cfg, observe=lambda y, thr: seen.append((n_calls[0] - 1, y, thr)))
    assert np.array_equal(plain.trace, observed.trace)
    assert all(plain.trace[i] == y for i, y, _ in seen)
    censored = {i for i, y, thr in seen if y >= thr}
    assert 0 < len(censored) < len(seen)  # both outcomes occur

    def run_with(change):
        k = [0]

        def f(u):
            i = k[0]
            k[0] += 1
            return change(i, rosenbrock(u))

        return anneal(f, u0, cfg)

    r = run_with(lambda i, y: 10 * y + 1 if i in censored else y)
    assert np.array_equal(r.best_u, plain.best_u) and r.best_f == plain.best_f
    # one rejected move's value lowered to just under its threshold: that move is accepted
    i_j, _, thr_j = next(s for s in seen if s[1] > s[2] + 1e-6)
    r2 = run_with(lambda i, y: thr_j - 1e-9 if i == i_j else y)
    assert not np.allclose(r2.trace[i_j + 1:i_j + 40], plain.trace[i_j + 1:i_j + 40])
