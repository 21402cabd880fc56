"""The candidates a fit hands to the cross-trial selection: best first, distinct, failures excluded,
and only the run's own evaluations (a log shared with an earlier run in the folder does not leak)."""

from __future__ import annotations

import numpy as np

from vidsim.cli.cloth_fit import candidates
from vidsim.optim import FAILED_SCORE
from vidsim.optim.space import Space


def test_candidates_are_best_distinct_and_never_failures():
    space = Space.from_config({"stretch": {"lo": 20.0, "hi": 4000.0, "log": True}, "bend": {"lo": 1e-7, "hi": 1e-4, "log": True}})
    recs = [([0.5, 0.5], 3.0), ([0.51, 0.5], 2.5), ([0.9, 0.1], 4.0), ([0.2, 0.2], FAILED_SCORE), ([0.1, 0.9], 5.0)]
    c = candidates(np.array([u for u, _ in recs]), np.array([f for _, f in recs]), space, 3)
    assert [x["score"] for x in c] == [2.5, 4.0, 5.0]  # 3.0 is within 0.05 of the best point
    assert np.isclose(c[0]["theta"]["stretch"], space.from_unit(np.array([0.51, 0.5]))[0])


def test_a_second_seed_in_the_same_folder_gets_its_own_candidates(tmp_path):
    """Two annealing runs with different seeds on one objective and one log: the second run's
    candidates are those of the same seed run in an empty folder (seen 3 Dec 2026: they were the
    union of both runs' logged points)."""
    from vidsim.clothfit.study import fit
    from vidsim.optim.anneal import AnnealConfig

    space = Space.from_config({"stretch": {"lo": 20.0, "hi": 4000.0, "log": True}, "bend": {"lo": 1e-7, "hi": 1e-4, "log": True}})

    class Quad:  # a cheap objective with the interface fit() reads
        def __init__(self) -> None:
            self.space = space

        def __call__(self, u):
            u = np.asarray(u, float)
            return float(np.sum((u - np.array([0.3, 0.7])) ** 2)), {}

    cfg = AnnealConfig(evals_per_T=4, step=0.1)
    shared = tmp_path / "shared" / "evals.jsonl"
    fit(Quad(), grid_params=["stretch", "bend"], levels=3, budget=20, anneal_cfg=cfg, seed=1, cache_path=shared)
    r2 = fit(Quad(), grid_params=["stretch", "bend"], levels=3, budget=20, anneal_cfg=cfg, seed=2, cache_path=shared)
    alone = fit(Quad(), grid_params=["stretch", "bend"], levels=3, budget=20, anneal_cfg=cfg, seed=2,
                cache_path=tmp_path / "alone" / "evals.jsonl")
    np.testing.assert_array_equal(r2.points, alone.points)
    c2 = candidates(r2.points, np.r_[r2.grid_values, r2.trace], space, 3)
    ca = candidates(alone.points, np.r_[alone.grid_values, alone.trace], space, 3)
    assert c2 == ca


def test_fit_settings_that_cannot_run_are_refused_by_their_config_names():
    """grid_levels 0 made an empty grid and a crash in argmin; an annealing schedule's errors name
    cloth.fit.* (the keys a user sets), not the optimiser's internal names."""
    import pytest

    from vidsim.clothfit.objective import ObjectiveError
    from vidsim.clothfit.study import fit
    from vidsim.errors import ConfigError
    from vidsim.optim.anneal import AnnealConfig

    space = Space.from_config({"stretch": {"lo": 20.0, "hi": 4000.0, "log": True}})

    class Flat:
        def __init__(self) -> None:
            self.space = space

        def __call__(self, u):
            return 1.0, {}

    with pytest.raises(ObjectiveError, match=r"cloth\.fit\.grid_levels.*got 0"):
        fit(Flat(), grid_params=["stretch"], levels=0, budget=5)
    with pytest.raises(ObjectiveError, match=r"cloth\.fit\.budget"):
        fit(Flat(), grid_params=["stretch"], levels=2, budget=0)
    with pytest.raises(ConfigError, match=r"cloth\.fit\.step"):
        AnnealConfig(step=2.0, name="cloth.fit")
    # a valid schedule runs the grid and then exactly the budget
    r = fit(Flat(), grid_params=["stretch"], levels=2, budget=3, anneal_cfg=AnnealConfig(evals_per_T=2, name="cloth.fit"))
    assert r.n_evals == 2 + 3
