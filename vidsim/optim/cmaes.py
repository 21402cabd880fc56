"""CMA-ES (the ``cma`` package) on the unit cube at a fixed evaluation budget."""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from vidsim.errors import ConfigError
from vidsim.optim import FAILED_SCORE

#: seed offset between restarts (any odd number; restart 0 keeps the seed ``seed + 1``)
_RESTART_SEED_STRIDE = 7919


def cmaes(f: Callable[[np.ndarray], float], u0: np.ndarray, budget: int, sigma0: float = 0.2, seed: int = 0,
          stops: list | None = None) -> tuple[np.ndarray, float, np.ndarray]:
    """Minimise ``f`` from ``u0`` with CMA-ES within [0, 1]^n, spending exactly ``budget`` evaluations.

    When the strategy stops on its own before the budget is spent (``tolfun`` on a flat region, e.g.
    a generation whose every simulation failed, or ``tolx``), it restarts from the best point so far
    with ``sigma0`` and the remaining budget (a new seed per restart), so that "CMA-ES at the same
    budget as annealing" compares equal numbers of evaluations.

    Args:
        stops: if given, each run's stop conditions (``cma``'s ``es.stop()`` dicts) are appended.

    Returns:
        best point (n,), best value, trace of values in evaluation order (budget,).
    """
    import cma

    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        # cma treats seed 0 (our -1 + 1) as "seed from the clock": not reproducible
        raise ConfigError(f"the CMA-ES seed must be a whole number >= 0, got {seed!r}")
    trace: list[float] = []
    best = [np.clip(np.asarray(u0, float), 0, 1), np.inf]
    run = 0
    while len(trace) < budget:
        start = best[0]
        opts = {"bounds": [0, 1], "seed": int(seed) + 1 + _RESTART_SEED_STRIDE * run,
                "maxfevals": int(budget - len(trace)), "verbose": -9}
        es = cma.CMAEvolutionStrategy(start.tolist(), sigma0, opts)
        while not es.stop() and len(trace) < budget:
            X = es.ask()
            X = X[: budget - len(trace)]
            ys = []
            for x in X:
                y = float(f(np.clip(np.asarray(x), 0, 1)))
                if not math.isfinite(y):  # cma would silently replace it by the generation's median
                    y = FAILED_SCORE
                trace.append(y)
                ys.append(y)
                if y < best[1]:
                    best = [np.clip(np.asarray(x), 0, 1), y]
            if len(ys) < es.popsize:
                break
            es.tell(X, ys)
        if stops is not None:
            stops.append({str(k): (v if isinstance(v, (int, float, str)) else str(v)) for k, v in es.stop().items()})
        run += 1
    return best[0], float(best[1]), np.array(trace)
