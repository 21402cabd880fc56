"""A small Gaussian-process emulator on the unit cube (the cloth posterior's surrogate).

Matern-5/2 kernel with one length scale per input (ARD), a white-noise nugget (the cloth metric
is only piecewise smooth at the pixel scale: a silhouette is a count of pixels), and a *fixed*
mean. The caller fixes the mean at the level the loss is clipped to (see
:mod:`vidsim.posterior.cloth`), so far from every evaluation the emulator reverts to "bad" and
never invents a low loss in a region nobody evaluated. Hyperparameters (log length scales, log
signal and nugget variances of the standardised targets) maximise the log marginal likelihood
(analytic gradient, L-BFGS-B, a few seeded restarts): the fit is a deterministic function of its
data and seed, so a resumed stage rebuilds the same emulator bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import minimize

SQRT5 = np.sqrt(5.0)
#: bounds of the hyperparameters: length scale (unit cube), signal and nugget variance of the
#: standardised targets
LS_BOUNDS = (0.005, 5.0)
SF2_BOUNDS = (1e-4, 1e4)
SN2_BOUNDS = (1e-10, 1.0)


def _r2(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    a = np.sum(A * A, axis=1)[:, None]
    b = np.sum(B * B, axis=1)[None, :]
    return np.maximum(a + b - 2.0 * A @ B.T, 0.0)


def _matern(r2: np.ndarray, sf2: float) -> np.ndarray:
    s = SQRT5 * np.sqrt(r2)
    return sf2 * (1.0 + s + s * s / 3.0) * np.exp(-s)


@dataclass
class GP:
    """A fitted emulator: ``predict(X)`` is the posterior mean of the targets at (n, D) points.

    Attributes:
        X: (n, D) training inputs; y: (n,) targets; mean: the fixed prior mean.
        ls: (D,) length scales; sf2, sn2: signal and nugget variances (target units squared).
        nll: negative log marginal likelihood at the optimum (standardised targets).
    """

    X: np.ndarray
    y: np.ndarray
    mean: float
    ls: np.ndarray
    sf2: float
    sn2: float
    nll: float = float("nan")

    def __post_init__(self) -> None:
        K = _matern(_r2(self.X / self.ls, self.X / self.ls), self.sf2) + self.sn2 * np.eye(len(self.X))
        self._cf = cho_factor(K, lower=True)
        self._alpha = cho_solve(self._cf, self.y - self.mean)

    def predict(self, Xs: np.ndarray, return_var: bool = False):
        """Mean (and variance, without the nugget) at (m, D) points."""
        Xs = np.atleast_2d(np.asarray(Xs, float))
        Ks = _matern(_r2(Xs / self.ls, self.X / self.ls), self.sf2)
        mu = self.mean + Ks @ self._alpha
        if not return_var:
            return mu
        v = cho_solve(self._cf, Ks.T)
        var = np.maximum(self.sf2 - np.sum(Ks * v.T, axis=1), 0.0)
        return mu, var

    def grad(self, x: np.ndarray) -> np.ndarray:
        """(D,) gradient of the mean at one point."""
        x = np.asarray(x, float)
        d = (x[None, :] - self.X) / self.ls  # (n, D)
        s = SQRT5 * np.sqrt(np.sum(d * d, axis=1))
        dk_dr2 = -self.sf2 * np.exp(-s) * (5.0 / 6.0) * (1.0 + s)  # dk/d(r^2)
        return (2.0 * (dk_dr2 * self._alpha)[:, None] * d / self.ls).sum(axis=0)

    def hessian(self, x: np.ndarray, h: float = 1e-4) -> np.ndarray:
        """(D, D) Hessian of the mean at one point (central differences of the analytic gradient)."""
        x = np.asarray(x, float)
        D = x.size
        H = np.zeros((D, D))
        for j in range(D):
            e = np.zeros(D)
            e[j] = h
            H[:, j] = (self.grad(x + e) - self.grad(x - e)) / (2 * h)
        return 0.5 * (H + H.T)


def _nll_and_grad(p: np.ndarray, X: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    n, D = X.shape
    ls = np.exp(p[:D])
    sf2, sn2 = np.exp(p[D]), np.exp(p[D + 1])
    Z = X / ls
    r2 = _r2(Z, Z)
    s = SQRT5 * np.sqrt(r2)
    es = np.exp(-s)
    Kf = sf2 * (1.0 + s + s * s / 3.0) * es
    K = Kf + sn2 * np.eye(n)
    try:
        cf = cho_factor(K, lower=True)
    except np.linalg.LinAlgError:
        return 1e25, np.zeros_like(p)
    alpha = cho_solve(cf, y)
    nll = 0.5 * y @ alpha + np.sum(np.log(np.diag(cf[0]))) + 0.5 * n * np.log(2 * np.pi)
    Kinv = cho_solve(cf, np.eye(n))
    W = np.outer(alpha, alpha) - Kinv  # d nll / dK = -W / 2
    g = np.zeros_like(p)
    base = sf2 * es * (5.0 / 3.0) * (1.0 + s)  # dk/dlog ls_d = base * (dx_d / ls_d)^2
    for d in range(D):
        dd = Z[:, d][:, None] - Z[:, d][None, :]
        g[d] = -0.5 * np.sum(W * base * dd * dd)
    g[D] = -0.5 * np.sum(W * Kf)
    g[D + 1] = -0.5 * sn2 * np.trace(W)
    return float(nll), g


def fit_gp(X: np.ndarray, y: np.ndarray, mean: float, seed: int = 0, restarts: int = 2,
           ls0: float = 0.2, min_nugget: float = 0.0) -> GP:
    """Fit an emulator with a fixed mean to (n, D) inputs and (n,) targets.

    Args:
        X, y: training data (unit-cube inputs).
        mean: the fixed prior mean (the clipping level of the targets).
        seed: seed of the restarts' random starting length scales.
        restarts: random restarts besides the start at ``ls0``.
        min_nugget: smallest nugget variance (target units squared), e.g. the measured roughness of
            a chaotic objective, so the emulator smooths it instead of interpolating it.

    Returns:
        The :class:`GP` of the restart with the best marginal likelihood.
    """
    X = np.asarray(X, float)
    y = np.asarray(y, float)
    n, D = X.shape
    scale = float(np.sqrt(np.mean((y - mean) ** 2))) or 1.0
    yn = (y - mean) / scale
    rng = np.random.default_rng(seed)
    starts = [np.r_[np.full(D, np.log(ls0)), 0.0, np.log(1e-4)]]
    for _ in range(restarts):
        starts.append(np.r_[np.log(rng.uniform(0.05, 1.0, D)), rng.uniform(-1, 1), np.log(10 ** rng.uniform(-6, -2))])
    sn_lo = max(SN2_BOUNDS[0], float(min_nugget) / scale ** 2)
    sn_hi = max(SN2_BOUNDS[1], 4.0 * sn_lo)
    bounds = [tuple(np.log(LS_BOUNDS))] * D + [tuple(np.log(SF2_BOUNDS)), (np.log(sn_lo), np.log(sn_hi))]
    starts = [np.r_[p0[:D + 1], np.clip(p0[D + 1], np.log(sn_lo), np.log(sn_hi))] for p0 in starts]
    best = None
    for p0 in starts:
        r = minimize(_nll_and_grad, p0, args=(X, yn), jac=True, method="L-BFGS-B", bounds=bounds,
                     options={"maxiter": 200})
        if best is None or r.fun < best.fun:
            best = r
    p = best.x
    return GP(X, y, float(mean), np.exp(p[:D]), float(np.exp(p[D]) * scale ** 2), float(np.exp(p[D + 1]) * scale ** 2),
              float(best.fun))
