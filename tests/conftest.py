"""Shared pytest fixtures."""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from vidsim.io.paths import shared_data_dir  # noqa: E402


@pytest.fixture
def rng() -> np.random.Generator:
    """A fixed-seed generator: tests are reproducible."""
    return np.random.default_rng(12345)


@pytest.fixture
def shared_data():
    """The real-data folder, or skip the test (with the reason) when it is absent."""
    d = shared_data_dir()
    if not d.is_dir():
        pytest.skip(f"real data folder {d} is absent")
    return d


def strict_loads(text: str):
    """json.loads that refuses NaN/Infinity tokens, as a browser's JSON.parse does."""
    import json

    def refuse(tok):
        raise ValueError(f"non-strict token {tok}")
    return json.loads(text, parse_constant=refuse)


def assert_footage_holds_no_truth(folder) -> None:
    """No file of a synthetic footage folder carries truth entities or recordings (the reality stages
    keep the truth, their Rerun recordings and the true masks beside the folder; a real recording has
    none). ``meta.yaml`` may *say* that its initial guess was made from the truth; it may not hold it."""
    from pathlib import Path

    files = [f for f in Path(folder).rglob("*") if f.is_file()]
    assert files, f"{folder} is empty"
    for f in files:
        assert f.suffix != ".rrd", f"{f}: a recording inside the footage folder"
        assert b"truth/" not in f.read_bytes().lower(), f"{f} holds truth entities"


class truth_hidden:
    """Context manager: every file or folder beside a footage folder named ``<folder>.*`` (its truth,
    ``<folder>.truth*``, and its reality recording, ``<folder>.reality.rrd``, which holds the truth
    too) is moved away while estimator stages run, so a stage that read one fails instead of
    passing; all of them are put back afterwards."""

    def __init__(self, folder) -> None:
        from pathlib import Path

        self.folder = Path(folder)
        self.moved: list = []

    def __enter__(self) -> "truth_hidden":
        prefix = f"{self.folder.name}."  # a plain prefix: the glob <name>.* without glob metacharacters
        for f in sorted(self.folder.parent.iterdir()):
            if f.name.startswith(prefix):
                dest = f.with_name(f".hidden.{f.name}")
                f.rename(dest)
                self.moved.append((dest, f))
        assert self.moved, f"no truth beside {self.folder} to hide"
        return self

    def __exit__(self, *exc) -> None:
        for dest, f in self.moved:
            dest.rename(f)
