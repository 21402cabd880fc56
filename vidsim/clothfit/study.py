"""Fitting cloth parameters: coarse grid, then simulated annealing or CMA-ES (seed 4.4).

Every evaluation goes through :class:`vidsim.optim.cache.EvalCache` (an fsync'd JSONL log when
a path is given), so a killed fit resumes by deterministic replay. The grid takes
``levels`` values (cell centres of the unit cube) of each "static" parameter with the others
at mid-range; its best point starts the annealing (or CMA-ES) for ``budget`` evaluations.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from vidsim.clothfit.objective import ClothObjective, ObjectiveError
from vidsim.optim.anneal import AnnealConfig, anneal
from vidsim.optim.cache import EvalCache
from vidsim.optim.cmaes import cmaes
from vidsim.optim.grid import grid_points, grid_search

__all__ = ["FitResult", "fit"]


@dataclass
class FitResult:
    """Outcome of :func:`fit`.

    Attributes:
        theta: (n,) best parameters (space order, SI).
        score: best objective value.
        grid_values: (m,) objective on the grid points.
        trace: (evals,) every objective value after the grid, in order.
        best_trace: (grid + evals,) best-so-far over all evaluations (error vs evaluations).
        n_evals: evaluations made (grid + optimiser), cache hits included.
        points: (n_evals, dim) the unit-cube points of those evaluations, in order.
    """

    theta: np.ndarray
    score: float
    grid_values: np.ndarray
    trace: np.ndarray
    best_trace: np.ndarray
    n_evals: int
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))


def fit(objective: ClothObjective, *, grid_params: list[str], levels: int = 4, budget: int = 600,
        method: str = "anneal", anneal_cfg: AnnealConfig | None = None, sigma0: float = 0.2, seed: int = 0,
        cache_path: str | os.PathLike | None = None, cache_context: str | None = None) -> FitResult:
    """Grid + annealing (or CMA-ES) on ``objective``.

    Args:
        objective: the (single- or multi-trial) objective.
        grid_params: names of the coarse-grid parameters (must be in the objective's space).
        levels: grid values per parameter.
        budget: evaluations after the grid.
        method: ``anneal`` or ``cmaes``.
        anneal_cfg: schedule (its ``budget`` is replaced by ``budget``).
        sigma0: CMA-ES initial step in the unit cube.
        seed: random seed.
        cache_path: JSONL evaluation log (resume); None keeps it in memory.
        cache_context: the objective's fingerprint (:meth:`ClothObjective.fingerprint`): a log
            written for another one is moved aside, not replayed (:class:`vidsim.optim.cache.EvalCache`).
    """
    names = objective.space.names
    bad = [p for p in grid_params if p not in names]
    if bad:
        raise ObjectiveError(f"cloth.fit.grid_params {bad} are not estimated parameters {names}")
    if method not in ("anneal", "cmaes"):
        raise ObjectiveError(f"cloth.fit.method must be 'anneal' or 'cmaes', got {method!r}")
    if grid_params and levels < 1:
        raise ObjectiveError(f"cloth.fit.grid_levels must be >= 1 (values per grid parameter), got {levels}; "
                             f"for no grid set cloth.fit.grid_params=[]")
    if budget < 1:
        raise ObjectiveError(f"cloth.fit.budget must be >= 1 (evaluations after the grid), got {budget}")
    with EvalCache(objective, cache_path, cache_context) as f:
        dims = [names.index(p) for p in grid_params]
        pts = grid_points(dims, levels, n=len(names)) if dims else np.full((1, len(names)), 0.5)
        gvals, u0 = grid_search(f, pts)
        n_grid = len(f.history)
        if method == "anneal":
            cfg = anneal_cfg or AnnealConfig()
            cfg = AnnealConfig(budget=budget, T0=cfg.T0, cooling=cfg.cooling, evals_per_T=cfg.evals_per_T,
                               reset_factor=cfg.reset_factor, step=cfg.step, min_step=cfg.min_step, seed=seed,
                               name=cfg.name)
            res = anneal(f, u0, cfg)
            u_best, f_best = res.best_u, res.best_f
        else:
            u_best, f_best, _ = cmaes(f, u0, budget, sigma0=sigma0, seed=seed)
        vals = np.array([v for _, v in f.history])
        if gvals.min() < f_best:
            u_best, f_best = u0, float(gvals.min())
        pts_all = np.array([u for u, _ in f.history], float).reshape(len(vals), len(names))
    return FitResult(objective.space.from_unit(u_best), float(f_best), gvals, vals[n_grid:],
                     np.minimum.accumulate(vals), len(vals), pts_all)
