"""Continuous simulated annealing: Metropolis + downhill simplex (Press et al., ``amebsa``).

The seed's optimiser for cloth (section 4.4): the simplex moves (reflect, expand, contract,
shrink) are judged on function values with thermal fluctuations -- a positive fluctuation
``-T log(u)`` on the stored vertices and a negative one on each trial point -- so uphill moves
are accepted with a probability that falls with the temperature. Temperature follows a
geometric schedule (``T <- cooling * T`` every ``evals_per_T`` simplex moves; a move costs 1, 2
or n + 2 evaluations, so a temperature lasts about 1.2-1.8 ``evals_per_T`` evaluations: 23-37 at
20 in 9-D, where Press et al. count evaluations), and whenever it has
fallen by ``reset_factor`` (3, as the seed) since the last reset the simplex is rebuilt around
the best point found so far, each time at half the previous size (down to ``min_step``). The best point ever evaluated is returned.

Works on the unit cube (see :class:`vidsim.optim.space.Space`); deterministic for a seed, so a
killed run resumes through :class:`vidsim.optim.cache.EvalCache` (see there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from vidsim.optim import FAILED_SCORE


@dataclass
class AnnealConfig:
    """Budget and schedule.

    Attributes:
        budget: objective evaluations in total.
        T0: initial temperature in objective units; None: half the spread (std) of the initial
            simplex's values.
        cooling: geometric factor per temperature step (0 < cooling < 1).
        evals_per_T: simplex moves at each temperature (each 1, 2 or n + 2 evaluations; the name
            is historical: Press et al.'s amebsa counts evaluations).
        reset_factor: rebuild the simplex around the best point when T fell by this factor.
        step: initial simplex edge in the unit cube.
        min_step: the smallest edge used when a reset shrinks the simplex.
        seed: random seed (fluctuations).
        name: the config prefix that error messages name (e.g. ``cloth.fit``).
    """

    budget: int = 600
    T0: float | None = None
    cooling: float = 0.9
    evals_per_T: int = 20
    reset_factor: float = 3.0
    step: float = 0.15
    min_step: float = 0.02
    seed: int = 0
    name: str = "anneal"

    def __post_init__(self) -> None:
        from vidsim.errors import ConfigError

        p = self.name
        if self.budget < 1:
            raise ConfigError(f"{p}.budget must be >= 1, got {self.budget}")
        if self.T0 is not None and not (math.isfinite(self.T0) and self.T0 >= 0):
            raise ConfigError(f"{p}: the initial temperature must be finite and >= 0 (or None), got {self.T0}")
        if not 0 < self.cooling < 1:
            raise ConfigError(f"{p}.cooling must be in (0, 1), got {self.cooling}")
        if self.evals_per_T < 1:
            raise ConfigError(f"{p}.evals_per_T must be >= 1, got {self.evals_per_T}")
        if self.reset_factor <= 1:
            raise ConfigError(f"{p}.reset_factor must be > 1, got {self.reset_factor}")
        if not 0 < self.step <= 0.5:
            # a larger step puts a start vertex beyond the cube from a centre near 0.5: the score would
            # be the clipped point's while the simplex keeps the unclipped one
            raise ConfigError(f"{p}.step must be in (0, 0.5], got {self.step}")
        if isinstance(self.seed, bool) or int(self.seed) != self.seed or self.seed < 0:
            raise ConfigError(f"{p}.seed must be a whole number >= 0, got {self.seed!r}")
        if not 0 < self.min_step <= self.step:
            raise ConfigError(f"{p}.min_step must be in (0, step = {self.step}], got {self.min_step}")


@dataclass
class AnnealResult:
    """Outcome. ``trace``: (evals,) objective of each evaluation in order; ``best_trace``:
    best-so-far after each; ``temperatures``: T at each evaluation; ``resets``: evaluation
    indices of simplex resets."""

    best_u: np.ndarray
    best_f: float
    n_evals: int
    trace: np.ndarray
    best_trace: np.ndarray
    temperatures: np.ndarray
    resets: list[int] = field(default_factory=list)


class _Budget(Exception):
    pass


def anneal(f: Callable[[np.ndarray], float], u0: np.ndarray, cfg: AnnealConfig,
           progress: Callable[[int, float, float], None] | None = None,
           observe: Callable[[float, float], None] | None = None) -> AnnealResult:
    """Minimise ``f`` over the unit cube from ``u0``.

    Args:
        f: objective on (n,) points in [0, 1]^n (finite values; failures as a large number).
        u0: (n,) start (e.g. the best point of the coarse grid).
        cfg: budget and schedule.
        progress: called as ``progress(n_evals, best_f, T)`` after each evaluation.
        observe: called as ``observe(y, y_reject)`` after each simplex move's evaluation (reflect,
            expand, contract; not the shrinks and resets, whose values are all kept): the move is
            rejected exactly when ``y >= y_reject`` (the simplex's fluctuated worst value minus the
            trial's fluctuation), so ``y_reject`` is the value beyond which the evaluation's exact
            value did not matter. For measurements (benchmarks/bench_anneal_censoring.py); it does
            not change the run.
    """
    rng = np.random.default_rng(cfg.seed)
    u0 = np.clip(np.asarray(u0, float), 0, 1)
    n = u0.size
    trace: list[float] = []
    best_trace: list[float] = []
    temps: list[float] = []
    state = {"T": 0.0, "best_u": u0.copy(), "best_f": np.inf}

    def ev(u: np.ndarray) -> float:
        if len(trace) >= cfg.budget:
            raise _Budget
        u = np.clip(u, 0.0, 1.0)
        y = float(f(u))
        if not math.isfinite(y):  # a NaN vertex would never be replaced nor shrunk away
            y = FAILED_SCORE
        trace.append(y)
        if y < state["best_f"]:
            state["best_f"], state["best_u"] = y, u.copy()
        best_trace.append(state["best_f"])
        temps.append(state["T"])
        if progress is not None:
            progress(len(trace), state["best_f"], state["T"])
        return y

    def simplex_around(c: np.ndarray, step: float) -> np.ndarray:
        P = np.repeat(c[None], n + 1, axis=0)
        for i in range(n):
            # step towards the interior so that no vertex is clipped onto the same point
            P[i + 1, i] += step if c[i] + step <= 1 else -step
        return P

    resets: list[int] = []
    try:
        P = simplex_around(u0, cfg.step)
        Y = np.array([ev(p) for p in P])
        T = cfg.T0 if cfg.T0 is not None else 0.5 * float(np.std(Y[Y < 1e29])) if np.any(Y < 1e29) else 1.0
        T = max(T, 1e-12)
        T_reset = T
        state["T"] = T
        while True:
            for _ in range(cfg.evals_per_T):
                # thermal fluctuation on the stored vertices (positive): uphill looks better
                yflu = Y - T * np.log(rng.random(n + 1))
                order = np.argsort(yflu)
                ilo, ihi, inhi = order[0], order[-1], order[-2]
                ylo, yhi, ynhi = yflu[ilo], yflu[ihi], yflu[inhi]
                psum = P.sum(axis=0)

                def amotsa(fac: float) -> float:
                    nonlocal yhi, psum
                    fac1 = (1.0 - fac) / n
                    fac2 = fac1 - fac
                    ptry = psum * fac1 - P[ihi] * fac2
                    ytry = ev(ptry)
                    lfl = T * np.log(rng.random())  # negative fluctuation on the trial
                    yfl = ytry + lfl
                    if observe is not None:
                        observe(ytry, yhi - lfl)
                    if yfl < yhi:
                        P[ihi] = np.clip(ptry, 0, 1)
                        Y[ihi] = ytry
                        yhi = yfl
                        psum = P.sum(axis=0)
                    return yfl

                ytry = amotsa(-1.0)
                if ytry <= ylo:
                    amotsa(2.0)
                elif ytry >= ynhi:
                    ysave = yhi
                    ytry = amotsa(0.5)
                    if ytry >= ysave:
                        for i in range(n + 1):
                            if i != ilo:
                                P[i] = 0.5 * (P[i] + P[ilo])
                                Y[i] = ev(P[i])
            T *= cfg.cooling
            state["T"] = T
            if T_reset / T >= cfg.reset_factor:
                T_reset = T
                resets.append(len(trace))
                # each reset halves the simplex (down to min_step): later stages refine locally
                step = max(cfg.min_step, cfg.step * 0.5 ** len(resets))
                P = simplex_around(state["best_u"], step)
                Y = np.array([ev(p) for p in P])
    except _Budget:
        pass
    return AnnealResult(
        best_u=state["best_u"], best_f=float(state["best_f"]), n_evals=len(trace),
        trace=np.array(trace), best_trace=np.array(best_trace), temperatures=np.array(temps), resets=resets,
    )
