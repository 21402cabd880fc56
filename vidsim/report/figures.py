"""Plot helpers shared by stages (matplotlib, Agg backend, atomic PNG writes)."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from vidsim.io.atomic import atomic_path  # noqa: E402


def save_figure(fig: "plt.Figure", path: str | os.PathLike, dpi: int = 110) -> None:
    """Save a figure atomically and close it."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, bbox_inches="tight", format="png")
    plt.close(fig)


def contact_sheet(frames: np.ndarray, path: str | os.PathLike, n: int = 8, titles: list[str] | None = None) -> None:
    """A row grid of ``n`` evenly spaced frames (T,H,W[,3]) saved as PNG."""
    idx = np.linspace(0, len(frames) - 1, min(n, len(frames))).round().astype(int)
    cols = min(4, len(idx))
    rows = int(np.ceil(len(idx) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.5 * rows), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for k, i in enumerate(idx):
        ax = axes.ravel()[k]
        ax.imshow(frames[i], cmap="gray" if frames[i].ndim == 2 else None)
        ax.set_title(titles[k] if titles else f"frame {i}", fontsize=8)
    save_figure(fig, path)
