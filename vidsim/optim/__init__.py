"""Optimisers sharing one interface: ``objective(theta) -> float`` on a box of bounds.

- :mod:`vidsim.optim.space`: parameter spaces (linear or log axes) mapping to the unit cube.
- :mod:`vidsim.optim.cache`: an append-only evaluation log on disk; a killed run resumes by
  replaying its deterministic trajectory through the cache.
- :mod:`vidsim.optim.anneal`: continuous simulated annealing (Metropolis + downhill simplex,
  Press et al.), geometric cooling, simplex reset at the best point every factor-3 cooling.
- :mod:`vidsim.optim.grid`: the coarse exhaustive grid that seeds the annealing.
- :mod:`vidsim.optim.cmaes`: CMA-ES (the ``cma`` package) at the same evaluation budget.

A simulation that fails (diverges) returns :data:`FAILED_SCORE`, a large finite number:
optimisers never see NaN or an exception.
"""

FAILED_SCORE = 1e30
