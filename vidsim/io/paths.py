"""Where things live: the repository root, the shared real-data folder, results."""

from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]


def shared_data_dir() -> Path:
    """Folder of real recordings (``../shared/data`` beside the repository).

    Overridable with the environment variable ``VIDSIM_SHARED_DATA``. The folder may be
    absent on a user's machine; callers (tests) skip with a reason in that case.
    """
    env = os.environ.get("VIDSIM_SHARED_DATA")
    if env:
        return Path(env)
    return (REPO_ROOT.parent / "shared" / "data").resolve()


def results_dir() -> Path:
    """The results folder (git-ignored); ``VIDSIM_RESULTS`` overrides."""
    return Path(os.environ.get("VIDSIM_RESULTS", REPO_ROOT / "results"))
