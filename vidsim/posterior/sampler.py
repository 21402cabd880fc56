"""emcee ensemble sampling with a resumable chain file, autocorrelation-based convergence and summaries.

The sampler runs in chunks of ``chunk`` steps. After every chunk the whole chain, its log
posterior values and the ensemble's random state are written atomically to one ``.npz`` (our own
backend: the project has no h5py). A stopped run started again with the same file continues from
the last saved chunk with the saved random state, so the resumed chain is bit-identical to an
uninterrupted one.

Convergence is read from emcee's integrated autocorrelation time ``tau`` (per parameter, on the
whole chain): a chain is ``converged`` only when its length is at least ``min_tau_multiple``
(default 50) times the largest ``tau``. A shorter chain is still summarised but is reported as
``converged: false``, never silently accepted. Burn-in: the first ``2 tau_max`` steps (at least
10 % of the chain, at most half of it; half when ``tau`` is not finite) are discarded before
summarising.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import emcee
import numpy as np

from vidsim.errors import VidsimError
from vidsim.io.atomic import write_npz


class PosteriorError(VidsimError):
    """Bad input to a posterior computation (names the field and what was expected)."""


@dataclass
class SamplerConfig:
    """emcee settings.

    Attributes:
        n_walkers: ensemble size (>= 2 * dimension).
        chunk: steps between checkpoints / convergence checks.
        min_steps: never stop before this many steps.
        max_steps: stop here even when not converged (then ``converged`` is false).
        min_tau_multiple: converged when steps >= this times the largest autocorrelation time.
        init_scale: walkers start at the mode plus this fraction of the approximate posterior
            standard deviation (emcee's advice: a small ball around the optimum).
        de_fraction: fraction of differential-evolution moves (rest: DE snooker); 0 = stretch moves.
        seed: seed of the initial ball and of the ensemble's random state.
    """

    n_walkers: int = 32
    chunk: int = 200
    min_steps: int = 400
    max_steps: int = 4000
    min_tau_multiple: float = 50.0
    init_scale: float = 0.1
    de_fraction: float = 0.8
    seed: int = 0

    def validate(self, ndim: int) -> None:
        """Raise :class:`PosteriorError` naming the field when a setting cannot work."""
        if self.n_walkers < 2 * ndim:
            raise PosteriorError(f"sampler.n_walkers = {self.n_walkers}: need >= 2 x dimension = {2 * ndim}")
        for name in ("chunk", "min_steps", "max_steps"):
            if getattr(self, name) < 1:
                raise PosteriorError(f"sampler.{name} = {getattr(self, name)}: must be >= 1")
        if self.max_steps < self.min_steps:
            raise PosteriorError(f"sampler.max_steps = {self.max_steps} is below min_steps = {self.min_steps}")
        if not (self.min_tau_multiple > 0 and self.init_scale > 0 and 0 <= self.de_fraction <= 1):
            raise PosteriorError("sampler: min_tau_multiple and init_scale must be > 0, de_fraction in [0, 1]; "
                                 f"got {self.min_tau_multiple}, {self.init_scale}, {self.de_fraction}")


@dataclass
class Chain:
    """A sampled chain and its diagnostics.

    Attributes:
        chain: (S, W, D) all steps of all walkers (sampled coordinates).
        log_prob: (S, W) their log posterior values.
        tau: (D,) integrated autocorrelation time per coordinate, steps.
        n_steps: S; burn: steps discarded before summarising.
        converged: ``n_steps >= min_tau_multiple * max(tau)``.
        acceptance: mean acceptance fraction over the whole chain: the fraction of moves after which a
            walker stands somewhere else (an accepted emcee move moves every coordinate; a rejected
            one none); read from the chain itself, so a resumed chain reports what an
            uninterrupted one does. Each walker's first move (from the start point) is not counted.
        ess: effective sample size, ``(S - burn) * W / max(tau)``.
        seconds: sampling wall time of this run (excludes replayed chunks).
        n_evals: log-posterior evaluations made in this run.
    """

    chain: np.ndarray
    log_prob: np.ndarray
    tau: np.ndarray
    n_steps: int
    burn: int
    converged: bool
    acceptance: float
    ess: float
    seconds: float
    n_evals: int
    history: list[dict] = field(default_factory=list)

    def samples(self) -> np.ndarray:
        """(N, D) post-burn-in samples, all walkers flattened."""
        return self.chain[self.burn:].reshape(-1, self.chain.shape[2])


def autocorr_time(chain: np.ndarray) -> np.ndarray:
    """(D,) integrated autocorrelation time of an (S, W, D) chain (emcee's estimator, no tolerance)."""
    return np.asarray(emcee.autocorr.integrated_time(chain, c=5, tol=0, quiet=True), float)


class SnookerMove(emcee.moves.DESnookerMove):
    """The differential-evolution snooker update of Ter Braak & Vrugt (2008), written as the paper has it.

    emcee 3.1's ``DESnookerMove`` steps along ``u = (x - z) / sqrt(|x - z|)`` instead of the unit
    vector, which makes the step scale with ``|x - z|`` (a scaling move about ``z`` with no matching
    correction), and weights the Metropolis ratio by ``(d - 1) / 2`` instead of ``d - 1``. It does not
    leave the target invariant: mixed 20 % with DE moves it sampled a 14-D standard normal with a
    standard deviation of 0.91-0.92 (session 33, found in review; this move: 1.00,
    ``tests/unit/posterior/test_posterior_sampler.py``). Here: ``e = (x - z) / |x - z|``,
    ``x* = x + gamma e (e . (z1 - z2))`` and the log ratio ``(d - 1) log(|x* - z| / |x - z|)``.
    """

    def get_proposal(self, s, c, random):
        Ns = len(s)
        Nc = list(map(len, c))
        ndim = s.shape[1]
        q = np.empty_like(s)
        metropolis = np.empty(Ns, dtype=np.float64)
        for i in range(Ns):
            w = np.array([c[j][random.randint(Nc[j])] for j in range(3)])
            random.shuffle(w)
            z, z1, z2 = w
            delta = s[i] - z
            norm = np.linalg.norm(delta)
            e = delta / norm
            q[i] = s[i] + e * self.gammas * (np.dot(e, z1) - np.dot(e, z2))
            metropolis[i] = np.log(np.linalg.norm(q[i] - z)) - np.log(norm)
        return q, (ndim - 1.0) * metropolis


def _moves(de_fraction: float) -> list | None:
    if de_fraction <= 0:
        return None
    if de_fraction >= 1:
        return [(emcee.moves.DEMove(), 1.0)]
    return [(emcee.moves.DEMove(), de_fraction), (SnookerMove(), 1.0 - de_fraction)]


def _state_arrays(rs: tuple) -> dict[str, np.ndarray]:
    name, keys, pos, has_gauss, cached = rs
    return {"rs_keys": np.asarray(keys, np.uint32), "rs_pos": np.array(pos),
            "rs_gauss": np.array([has_gauss, cached], float)}


def _state_tuple(z: dict) -> tuple:
    return ("MT19937", z["rs_keys"], int(z["rs_pos"]), int(z["rs_gauss"][0]), float(z["rs_gauss"][1]))


def _same_posterior(log_prob: Callable, walkers: np.ndarray, saved: np.ndarray, vectorize: bool) -> bool:
    """Whether ``log_prob`` gives the saved log densities at the saved last walker positions (to
    1e-6 relative, -inf where -inf was saved). The tolerance allows for the rounding of a
    vectorised density evaluated in other batch shapes than emcee's half-ensembles (a GP
    surrogate's matrix products: 1.5e-7 at |log p| 2.6 measured); a change of the inputs moves the
    densities by far more."""
    walkers = np.asarray(walkers, float)
    now = (np.asarray(log_prob(walkers), float) if vectorize
           else np.array([float(log_prob(x)) for x in walkers]))
    for lp, lp0 in zip(now, saved):
        if np.isfinite(lp0) != np.isfinite(lp):
            return False
        if np.isfinite(lp0) and abs(lp - lp0) > 1e-6 * max(1.0, abs(lp0)):
            return False
    return True


def _replay(chain: np.ndarray, cfg: SamplerConfig) -> list[dict]:
    """Per-chunk progress records of a saved (steps, walkers, dim) chain, like those :func:`sample`
    reports while sampling: ``tau_max`` from the steps before the chunk (as live), ``acceptance`` the
    fraction of walker moves within the chunk that changed the walker (for the first chunk one move
    fewer than live: the starting ball is not saved), ``seconds`` NaN (not saved). A chain saved with
    another chunk length ends with a record for its last, partial chunk."""
    out = []
    c = cfg.chunk
    S = chain.shape[0]
    ends = list(range(c, S + 1, c)) + ([S] if S % c else [])
    for i, end in enumerate(ends):
        start = ends[i - 1] if i else 0
        tmax = float(np.max(autocorr_time(chain[:start]))) if start >= 2 * c else float("inf")
        seg = chain[max(start - 1, 0):end]
        acc = float(np.mean(np.any(np.diff(seg, axis=0) != 0, axis=2))) if len(seg) > 1 else float("nan")
        out.append({"step": end, "max_steps": cfg.max_steps, "tau_max": tmax, "seconds": float("nan"),
                    "acceptance": acc, "resumed": True})
    return out


def sample(log_prob: Callable[[np.ndarray], float], center: np.ndarray, cov: np.ndarray,
           cfg: SamplerConfig | None = None, path: str | os.PathLike | None = None,
           progress: Callable[[dict], None] | None = None, vectorize: bool = False) -> Chain:
    """Run (or resume) an emcee ensemble until converged or ``max_steps``.

    Args:
        log_prob: log posterior of a (D,) point; ``-inf`` outside the prior or for a failed
            simulation (never NaN).
        center: (D,) the optimiser's result (the walkers' starting ball is around it).
        cov: (D, D) approximate posterior covariance (shapes the starting ball).
        cfg: sampler settings.
        path: chain file (``.npz``); an existing file from the same settings is resumed once
            ``log_prob`` reproduces the saved log densities of its last walkers (otherwise it was
            sampled from another posterior: it is moved aside to ``stale-<k>.<name>``).
        progress: called after every chunk with ``{"step", "max_steps", "tau_max", "seconds"}``.
        vectorize: ``log_prob`` takes an (n, D) array and returns (n,) values (emcee's
            ``vectorize``; a cheap surrogate evaluates the whole half-ensemble at once).

    Returns:
        :class:`Chain`.
    """
    cfg = cfg or SamplerConfig()
    center = np.asarray(center, float)
    D = center.size
    cfg.validate(D)
    cov = np.asarray(cov, float)
    if cov.shape != (D, D) or not np.all(np.isfinite(cov)):
        raise PosteriorError(f"cov must be a finite ({D}, {D}) matrix, got shape {cov.shape}")
    W = cfg.n_walkers
    chains: list[np.ndarray] = []
    lps: list[np.ndarray] = []
    rs = None
    def move_aside(why: str) -> None:
        k = 1
        while (stale := Path(path).with_name(f"stale-{k}.{Path(path).name}")).exists():
            k += 1
        Path(path).rename(stale)
        print(f"{path}: {why}; moved to {stale.name}, sampling afresh", file=sys.stderr, flush=True)

    if path is not None and Path(path).is_file():
        z = dict(np.load(path, allow_pickle=False))
        if z["chain"].shape[1:] != (W, D):
            # written with other settings (walkers or parameters changed since): kept aside, not continued
            move_aside(f"holds {z['chain'].shape[1:]} (walkers, dim) where this run has ({W}, {D})")
        else:
            chains, lps = [z["chain"]], [z["log_prob"]]
            rs = _state_tuple(z)
    rng = np.random.default_rng(cfg.seed)
    lp_one = (lambda x: float(log_prob(np.asarray(x)[None, :])[0])) if vectorize else log_prob
    if chains and not _same_posterior(log_prob, chains[0][-1], lps[0][-1], vectorize):
        # the chain was sampled from another posterior (its footage or settings changed since it
        # was killed): keep it aside and start afresh rather than continue a foreign chain
        move_aside("its walkers' saved log densities do not match this posterior (inputs changed since it was "
                   "written)")
        chains, lps, rs = [], [], None
    L = np.linalg.cholesky(cov + 1e-300 * np.eye(D)) if np.all(np.linalg.eigvalsh(cov) > 0) else np.diag(
        np.sqrt(np.maximum(np.diag(cov), 1e-30)))
    if chains:
        p0 = chains[-1][-1]
    else:
        p0 = center + cfg.init_scale * rng.normal(size=(W, D)) @ L.T
        # walkers must start inside the support
        for i in range(W):
            k = 0
            while not np.isfinite(lp_one(p0[i])) and k < 100:
                p0[i] = center + cfg.init_scale * 0.5 ** (k // 10 + 1) * rng.normal(size=D) @ L.T
                k += 1
    sampler = emcee.EnsembleSampler(W, D, log_prob, moves=_moves(cfg.de_fraction), vectorize=vectorize)
    if rs is None:
        sampler.random_state = np.random.RandomState(cfg.seed).get_state()
    else:
        sampler.random_state = rs
    t_start = time.perf_counter()
    n_done = sum(len(c) for c in chains)
    n_evals = 0
    # a resumed chain's chunks are reported again (marked "resumed"), so a progress log or
    # recording made by the resuming run covers the whole chain, not only the chunks after the kill
    history = _replay(chains[0], cfg) if chains else []
    if progress is not None:
        for info in history:
            progress(info)
    state = emcee.State(p0)
    acc_num = 0.0
    while True:
        tau = autocorr_time(np.concatenate(chains)) if n_done >= 2 * cfg.chunk else np.full(D, np.inf)
        tmax = float(np.max(tau))
        if n_done >= cfg.max_steps or (n_done >= cfg.min_steps and n_done >= cfg.min_tau_multiple * tmax):
            break
        sampler.reset()
        state = sampler.run_mcmc(state, cfg.chunk, progress=False)
        n_evals += cfg.chunk * W
        acc_num = float(np.mean(sampler.acceptance_fraction))
        chains.append(sampler.get_chain())
        lps.append(sampler.get_log_prob())
        n_done += cfg.chunk
        if path is not None:
            write_npz(path, chain=np.concatenate(chains), log_prob=np.concatenate(lps),
                      **_state_arrays(sampler.random_state))
        info = {"step": n_done, "max_steps": cfg.max_steps, "tau_max": tmax,
                "seconds": time.perf_counter() - t_start, "acceptance": acc_num}
        history.append(info)
        if progress is not None:
            progress(info)
    chain = np.concatenate(chains)
    lp = np.concatenate(lps)
    tau = autocorr_time(chain)
    tmax = float(np.max(tau))
    S = chain.shape[0]
    burn = int(min(S // 2, max(np.ceil(2 * tmax) if np.isfinite(tmax) else S // 2, S // 10)))
    converged = bool(np.isfinite(tmax) and S >= cfg.min_tau_multiple * tmax)
    acc = float(np.mean(np.any(np.diff(chain, axis=0) != 0, axis=2))) if S >= 2 else float("nan")
    ess = float((S - burn) * W / tmax) if np.isfinite(tmax) and tmax > 0 else 0.0
    return Chain(chain, lp, tau, S, burn, converged, acc, ess, time.perf_counter() - t_start, n_evals, history)


# ----------------------------------------------------------------------------- summaries
def summarize(samples: np.ndarray, names: list[str], point: np.ndarray | None = None,
              levels: tuple[float, float, float] = (5.0, 50.0, 95.0)) -> list[dict]:
    """Per-parameter ``{name, point, q05, median, q95, mean, sd}`` of (N, D) samples."""
    samples = np.asarray(samples, float)
    if samples.ndim != 2 or samples.shape[1] != len(names):
        raise PosteriorError(f"samples must be (N, {len(names)}), got {samples.shape}")
    q = np.percentile(samples, levels, axis=0)
    out = []
    for j, n in enumerate(names):
        out.append({"name": n, "point": float(point[j]) if point is not None else float("nan"),
                    "q05": float(q[0, j]), "median": float(q[1, j]), "q95": float(q[2, j]),
                    "mean": float(samples[:, j].mean()), "sd": float(samples[:, j].std())})
    return out


def correlation(samples: np.ndarray) -> np.ndarray:
    """(D, D) correlation matrix of (N, D) samples."""
    C = np.cov(np.asarray(samples, float), rowvar=False)
    s = np.sqrt(np.maximum(np.diag(C), 1e-300))
    return C / np.outer(s, s)


def covered(samples: np.ndarray, truth: np.ndarray, level: float = 90.0) -> np.ndarray:
    """(D,) bool: does the central ``level`` % interval of each marginal contain the truth?"""
    a = (100.0 - level) / 2.0
    lo, hi = np.percentile(np.asarray(samples, float), [a, 100.0 - a], axis=0)
    t = np.asarray(truth, float)
    return (lo <= t) & (t <= hi)
