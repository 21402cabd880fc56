"""CMA-ES (the ``cma`` package) on the unit cube at a fixed evaluation budget."""

from __future__ import annotations

from typing import Callable

import numpy as np


def cmaes(f: Callable[[np.ndarray], float], u0: np.ndarray, budget: int, sigma0: float = 0.2, seed: int = 0
          ) -> tuple[np.ndarray, float, np.ndarray]:
    """Minimise ``f`` from ``u0`` with CMA-ES within [0, 1]^n.

    Returns:
        best point (n,), best value, trace of values in evaluation order (budget,).
    """
    import cma

    trace: list[float] = []
    best = [np.asarray(u0, float), np.inf]
    opts = {"bounds": [0, 1], "seed": int(seed) + 1, "maxfevals": int(budget), "verbose": -9}
    es = cma.CMAEvolutionStrategy(np.clip(u0, 0, 1).tolist(), sigma0, opts)
    while not es.stop() and len(trace) < budget:
        X = es.ask()
        X = X[: budget - len(trace)]
        ys = []
        for x in X:
            y = float(f(np.clip(np.asarray(x), 0, 1)))
            trace.append(y)
            ys.append(y)
            if y < best[1]:
                best = [np.clip(np.asarray(x), 0, 1), y]
        if len(ys) < es.popsize:
            break
        es.tell(X, ys)
    return best[0], float(best[1]), np.array(trace)
