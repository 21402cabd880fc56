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


# Truth fields an estimator is scored on (read from ``<folder>.truth.yaml``), which no file inside the
# footage folder may repeat: the rigid throw's initial state, gravity, camera pose and effect
# strengths; the cloth's stiffnesses, dampings and drags (twin ``params``, MuJoCo ``fabric``) and the
# true camera and projector poses. Not listed, because the estimator is given them as measured input
# (written to ``meta.yaml`` by design): the areal density, the gripped corners' paths, the first
# throw frame ``t0`` and the camera intrinsics of the rigid scene.
SECRET_TRUTH_FIELDS = ("position", "quaternion", "velocity", "omega_world", "gravity", "tilt", "roll",
                       "camera_tilt_deg", "effects", "params", "fabric", "camera.R", "camera.t",
                       "projector.R", "projector.t")
KNOWN_INPUT_FIELDS = ("params.density", "fabric.areal_density")


def _numbers(node, path: str = ""):
    """(path, value) of every finite non-boolean number in a parsed YAML tree."""
    import math

    if isinstance(node, bool):
        return
    if isinstance(node, (int, float)):
        if math.isfinite(node):
            yield path, float(node)
    elif isinstance(node, dict):
        for k, v in node.items():
            yield from _numbers(v, f"{path}.{k}" if path else str(k))
    elif isinstance(node, (list, tuple)):
        for i, v in enumerate(node):
            yield from _numbers(v, f"{path}[{i}]")


def _leaf_name(path: str) -> str:
    """``a.b[2][0]`` -> ``b``: the key a number sits under."""
    return path.split(".")[-1].split("[")[0]


def _distinctive(v: float) -> bool:
    """A number with more than three significant digits, which no file holds by chance."""
    return abs(v - float(f"{v:.3g}")) > 1e-9 * abs(v)


def secret_truth_values(truth: dict) -> list[tuple[float, str]]:
    """The numbers of a truth file's estimation targets (:data:`SECRET_TRUTH_FIELDS`), each with the
    truth field it came from; 0, +-1 and magnitudes below 1e-9 are left out."""
    out: list[tuple[float, str]] = []
    for field in SECRET_TRUTH_FIELDS:
        node = truth
        for part in field.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        out += [(v, path) for path, v in _numbers(node, field)
                if path not in KNOWN_INPUT_FIELDS and abs(v) >= 1e-9 and abs(v) != 1.0]
    return out


def truth_leaks(tree, secrets: list[tuple[float, str]]) -> list[str]:
    """Where a parsed file repeats a secret truth number (to 1e-9 relative): anywhere for a
    distinctive number (:func:`_distinctive`), under the same key name for a round one (a round
    stiffness such as 300 may stand in a file by chance, but not as ``stretch: 300``)."""
    leaks = []
    for path, v in _numbers(tree):
        for s, field in secrets:
            if abs(v - s) <= 1e-9 * abs(s) and (_distinctive(s) or _leaf_name(path) == _leaf_name(field)):
                leaks.append(f"{path} = {v!r} equals the truth's {field}")
    return leaks


def assert_footage_holds_no_truth(folder) -> None:
    """No file of a synthetic footage folder carries the truth beside it: no truth entities or
    recordings (the reality stages keep the truth, their Rerun recordings and the true masks beside
    the folder; a real recording has none), and no YAML or CSV file inside it repeats an estimation
    target of ``<folder>.truth.yaml`` (:func:`truth_leaks`). ``meta.yaml`` may *say* that its
    initial guess was made from the truth; it may not hold it."""
    import csv
    from pathlib import Path

    import yaml

    folder = Path(folder)
    files = [f for f in folder.rglob("*") if f.is_file()]
    assert files, f"{folder} is empty"
    truth_file = folder.with_name(folder.name + ".truth.yaml")
    secrets = secret_truth_values(yaml.safe_load(truth_file.read_text())) if truth_file.is_file() else []
    for f in files:
        assert f.suffix != ".rrd", f"{f}: a recording inside the footage folder"
        assert b"truth/" not in f.read_bytes().lower(), f"{f} holds truth entities"
        if not secrets or f.suffix not in (".yaml", ".yml", ".csv"):
            continue
        if f.suffix == ".csv":
            with f.open() as fh:
                tree = [[float(x) for x in row if _is_number(x)] for row in csv.reader(fh)]
        else:
            tree = yaml.safe_load(f.read_text())
        leaks = truth_leaks(tree, secrets)
        assert not leaks, f"{f} holds the truth of {truth_file.name}: " + "; ".join(leaks[:5])


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


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
