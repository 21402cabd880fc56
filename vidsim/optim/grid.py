"""The coarse exhaustive grid that seeds annealing (seed 4.4: four values per parameter)."""

from __future__ import annotations

import itertools
import math
from typing import Callable

import numpy as np

from vidsim.optim import FAILED_SCORE


def grid_points(dims: list[int], levels: int = 4, n: int | None = None, base: np.ndarray | None = None) -> np.ndarray:
    """Unit-cube points: ``levels`` values (cell centres) along each axis in ``dims``, the other
    axes held at ``base`` (default 0.5). Returns (levels**len(dims), n)."""
    n = n if n is not None else max(dims) + 1
    base = np.full(n, 0.5) if base is None else np.asarray(base, float)
    vals = (np.arange(levels) + 0.5) / levels
    pts = []
    for combo in itertools.product(vals, repeat=len(dims)):
        p = base.copy()
        p[list(dims)] = combo
        pts.append(p)
    return np.array(pts)


def grid_search(f: Callable[[np.ndarray], float], points: np.ndarray,
                progress: Callable[[int, float], None] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Evaluate ``f`` on every point; return (values (m,), best point (n,))."""
    vals = np.empty(len(points))
    for i, p in enumerate(points):
        y = float(f(p))
        vals[i] = y if math.isfinite(y) else FAILED_SCORE  # argmin would pick a NaN
        if progress is not None:
            progress(i + 1, float(vals[: i + 1].min()))
    return vals, points[int(np.argmin(vals))]
