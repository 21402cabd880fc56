"""A small annealing job run as its own process by ``test_kill_resume.py``.

``python tests/integration/anneal_job.py <cache.jsonl> <result.json> <delay_s>``: anneals a 4-D
Rosenbrock through the fsync'd evaluation cache (each new evaluation sleeps ``delay_s``, standing
in for a simulation), then writes the result atomically. Killing it at any moment and starting it
again must give the same result as an uninterrupted run.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from vidsim.io.atomic import write_json
from vidsim.optim.anneal import AnnealConfig, anneal
from vidsim.optim.cache import EvalCache

BUDGET = 400


def objective(u: np.ndarray) -> float:
    x = 4 * np.asarray(u) - 2
    return float(np.sum(100 * (x[1:] - x[:-1] ** 2) ** 2 + (1 - x[:-1]) ** 2))


def main(cache_path: str, result_path: str, delay: float) -> None:
    def slow(u: np.ndarray) -> float:
        time.sleep(delay)
        return objective(u)

    with EvalCache(slow, cache_path) as f:
        r = anneal(f, np.full(4, 0.2), AnnealConfig(budget=BUDGET, seed=7))
        write_json(result_path, {"best_u": [float(x).hex() for x in r.best_u], "best_f": float(r.best_f).hex(),
                                 "n_evals": r.n_evals, "n_new": f.n_new, "n_hits": f.n_hits})


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], float(sys.argv[3]))
