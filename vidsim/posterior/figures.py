"""Figures of a posterior: corner plot and correlation matrix (matplotlib figures, saved by the caller)."""

from __future__ import annotations

import numpy as np


def corner_figure(samples: np.ndarray, names: list[str], units: list[str] | None = None,
                  point: np.ndarray | None = None, truth: np.ndarray | None = None, bins: int = 30,
                  max_points: int = 4000, flags: str = ""):
    """Corner plot: 1-D marginals on the diagonal (5/50/95 % marked), 2-D scatter below.

    Args:
        samples: (N, D) posterior samples; names/units: D labels.
        point: (D,) optimiser's estimate (red); truth: (D,) known truth of a synthetic case (blue).
        bins: histogram bins; max_points: scatter points shown (thinned evenly).
        flags: quality warnings printed under the title in red (e.g. "chain NOT converged"), so the
            figure never shows an unconverged or unchecked posterior as if it were sound.

    Returns:
        A matplotlib Figure.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    S = np.asarray(samples, float)
    N, D = S.shape
    step = max(1, N // max_points)
    T = S[::step]
    size = 1.1 * D + 1
    fig = plt.figure(figsize=(size, size))
    m0, cell = 0.8 / size, (1 - 1.0 / size) / D  # only the lower triangle gets axes (fast)
    q = np.percentile(S, [5, 50, 95], axis=0)
    for i in range(D):
        for j in range(i + 1):
            ax = fig.add_axes((m0 + j * cell, 1 - 0.35 / size - (i + 1) * cell, 0.95 * cell, 0.95 * cell))
            if i == j:
                ax.hist(S[:, i], bins=bins, color="0.4", histtype="step")
                for v, ls in zip(q[:, i], ("--", "-", "--")):
                    ax.axvline(v, color="k", ls=ls, lw=0.7)
                if point is not None:
                    ax.axvline(point[i], color="r", lw=0.8)
                if truth is not None:
                    ax.axvline(truth[i], color="b", lw=0.8)
                ax.set_yticks([])
            else:
                ax.plot(T[:, j], T[:, i], ",", color="0.2", alpha=0.5, rasterized=True)
                if point is not None:
                    ax.plot(point[j], point[i], "r+", ms=6)
                if truth is not None:
                    ax.plot(truth[j], truth[i], "bx", ms=5)
            if i == D - 1:
                ax.xaxis.set_major_locator(MaxNLocator(2))
                ax.tick_params(labelsize=5, rotation=45)
                ax.set_xlabel(names[j] + (f" [{units[j]}]" if units else ""), fontsize=6)
            else:
                ax.set_xticks([])
            if j == 0 and i > 0:
                ax.yaxis.set_major_locator(MaxNLocator(2))
                ax.tick_params(labelsize=5)
                ax.set_ylabel(names[i] + (f" [{units[i]}]" if units else ""), fontsize=6)
            elif i != j:
                ax.set_yticks([])
    fig.suptitle("posterior (black: 5/50/95 %" + (", red: estimate" if point is not None else "")
                 + (", blue: truth" if truth is not None else "") + ")", fontsize=8)
    if flags:
        fig.text(0.5, 1 - 0.22 / size, flags, ha="center", va="top", fontsize=7, color="C3")
    return fig


def correlation_figure(corr: np.ndarray, names: list[str], title: str = "posterior correlation"):
    """Heat map of a (D, D) correlation matrix with the values printed. Returns a Figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    C = np.asarray(corr, float)
    D = C.shape[0]
    fig, ax = plt.subplots(figsize=(0.45 * D + 2, 0.45 * D + 1.5))
    im = ax.imshow(C, vmin=-1, vmax=1, cmap="RdBu_r")
    ax.set_xticks(range(D), names, rotation=90, fontsize=7)
    ax.set_yticks(range(D), names, fontsize=7)
    for i in range(D):
        for j in range(D):
            ax.text(j, i, f"{C[i, j]:.1f}", ha="center", va="center", fontsize=5)
    fig.colorbar(im, ax=ax, shrink=0.8)
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    return fig
