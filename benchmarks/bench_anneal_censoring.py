"""Benchmark: how much of an annealing fit's simulation time could early stopping save?

Racing idea: the cloth metric sums non-negative per-frame terms, so a simulation could stop as
soon as its partial error guarantees that the annealing rejects the point. This replays a
finished fit's evaluation log (``evals.jsonl`` of ``cloth_fit``, full setting: 4^3 grid + 600
annealing evaluations) through :func:`vidsim.optim.anneal.anneal` with the same schedule, reads
each simplex move's rejection threshold (``observe``), and reports the evaluations whose value
lay beyond it (their exact value did not matter) and their share of the fit's time. That share
is an upper bound on the saving: a stopped simulation still runs until its partial error
crosses the threshold.

    .venv/bin/python benchmarks/bench_anneal_censoring.py <fit folder>/evals.jsonl

The replay must reproduce the fit's best value (checked), else the log is not the default
schedule's and nothing is reported.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from vidsim.config.cloth import ClothFitConfig
from vidsim.optim.anneal import AnnealConfig, anneal
from vidsim.optim.cache import point_key
from vidsim.optim.grid import grid_points


def main() -> None:
    fc = ClothFitConfig()
    ap = argparse.ArgumentParser()
    ap.add_argument("log", help="a cloth fit's evals.jsonl")
    ap.add_argument("--budget", type=int, default=fc.budget)
    ap.add_argument("--levels", type=int, default=fc.grid_levels)
    ap.add_argument("--seed", type=int, default=fc.seed)
    a = ap.parse_args()
    rows = {}
    with open(a.log) as fh:
        for line in fh:
            r = json.loads(line)
            if "key" not in r:
                continue
            t = r.get("info", {}).get("timing", {})
            rows[r["key"]] = (float(r["f"]), float(t.get("simulate", 0.0)), float(sum(t.values())))
    if not rows:
        sys.exit(f"{a.log}: no evaluation records")
    n = len(next(iter(rows)).split(","))
    from vidsim.clothfit.objective import ESTIMATED_NAMES

    dims = [list(ESTIMATED_NAMES).index(p) for p in fc.grid_params] if n == len(ESTIMATED_NAMES) else []
    used: list[tuple[float, float, float]] = []

    def lookup(u: np.ndarray) -> float:
        k = point_key(np.clip(u, 0.0, 1.0))
        if k not in rows:
            sys.exit(f"{a.log}: the replay asked for a point the log does not hold: not the default schedule "
                     f"(budget {a.budget}, grid {a.levels} levels, seed {a.seed})")
        used.append(rows[k])
        return rows[k][0]

    pts = grid_points(dims, a.levels, n=n) if dims else np.full((1, n), 0.5)
    gvals = np.array([lookup(p) for p in pts])
    n_grid = len(used)
    moves: list[tuple[int, float, float]] = []
    cfg = AnnealConfig(budget=a.budget, cooling=fc.cooling, evals_per_T=fc.evals_per_T, step=fc.step,
                       min_step=fc.min_step, seed=a.seed)
    res = anneal(lookup, pts[int(np.argmin(gvals))], cfg, observe=lambda y, thr: moves.append((len(used) - 1, y, thr)))
    best = min(res.best_f, float(gvals.min()))
    logged_best = min(v[0] for v in rows.values())
    if not np.isclose(best, logged_best, rtol=0, atol=1e-9):
        sys.exit(f"replay's best {best} differs from the log's best {logged_best}: not the default schedule")
    t_sim = sum(u[1] for u in used)
    t_all = sum(u[2] for u in used)
    cens = [(i, y, thr) for i, y, thr in moves if y >= thr]
    t_cens = sum(used[i][1] for i, _, _ in cens)
    ratio = np.array([y / thr for _, y, thr in cens]) if cens else np.zeros(0)
    print(f"{a.log}: {n_grid} grid + {res.n_evals} annealing evaluations replayed (best {best:.4f}, as logged)")
    print(f"  evaluation time {t_all:.0f} s, of which simulation {t_sim:.0f} s")
    print(f"  simplex moves {len(moves)}, rejected {len(cens)}; their simulation {t_cens:.0f} s = "
          f"{t_cens / t_all:.1%} of the evaluation time (the most early stopping could save)")
    if cens:
        q = np.quantile(ratio, [0.1, 0.5, 0.9])
        print(f"  rejected moves' value / threshold: 10 % {q[0]:.3f}, median {q[1]:.3f}, 90 % {q[2]:.3f} "
              f"(the partial sum reaches the threshold only once 1/ratio of the total error has accrued)")
        est = sum(used[i][1] * (1.0 - thr / y) for i, y, thr in cens if y > 0)
        print(f"  if each evaluation's error accrued in step with its simulated time, stopping at the threshold "
              f"would save {est:.0f} s = {est / t_all:.1%}")


if __name__ == "__main__":
    main()
