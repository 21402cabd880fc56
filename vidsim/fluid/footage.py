"""Where the fluid stages' footage lives: edit-YAML labels to footage folders, and the
nominal camera of fluid footage.

An edit's ``footage:`` field (``docs/fluid_editing.md``) names the footage it edits:

* ``synthetic:<scene>`` -> ``<results>/footage/fluid_<scene>`` (made by ``reality_fluid``),
* ``piv:<name>`` -> ``<results>/footage/piv_<name>`` (imported by ``fluid_piv_footage``),
* anything else is a footage folder path (absolute, or relative to the working directory).

No file access here: the stage checks that the folder exists (``vidsim.io.footage``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from vidsim.errors import ConfigError
from vidsim.video.camera import PinholeCamera, intrinsics

SYNTHETIC_SCENES = ("waterfall", "stream_boat", "flame")
PIV_RECORDINGS = ("karman", "jet")


class FootageLabelError(ConfigError):
    """An edit's ``footage:`` label names no known scene or recording."""


def footage_folder_name(label: str) -> str:
    """The folder name under ``<results>/footage/`` of a ``synthetic:``/``piv:`` label.

    Raises:
        FootageLabelError: an unknown scene or recording, or an empty label.
    """
    if not isinstance(label, str) or not label.strip():
        raise FootageLabelError(f"footage={label!r}: expected 'synthetic:<scene>', 'piv:<name>' or a folder path")
    kind, _, name = label.partition(":")
    if kind == "synthetic":
        if name not in SYNTHETIC_SCENES:
            raise FootageLabelError(f"footage={label!r}: unknown synthetic scene {name!r}; expected one of {SYNTHETIC_SCENES}")
        return f"fluid_{name}"
    if kind == "piv":
        if name not in PIV_RECORDINGS:
            raise FootageLabelError(f"footage={label!r}: unknown PIV recording {name!r}; expected one of {PIV_RECORDINGS}")
        return f"piv_{name}"
    raise FootageLabelError(f"footage={label!r} is not a 'synthetic:<scene>' or 'piv:<name>' label")


def resolve_footage(label: str, results: str | Path) -> Path:
    """The footage folder an edit's ``footage:`` label refers to.

    Args:
        label: ``synthetic:<scene>``, ``piv:<name>`` or a folder path (contains ``/`` or no ``:``).
        results: the results folder (``paths.results``).
    """
    if isinstance(label, str) and re.match(r"^(synthetic|piv):", label):
        return Path(results) / "footage" / footage_folder_name(label)
    if not isinstance(label, str) or not label.strip():
        raise FootageLabelError(f"footage={label!r}: expected 'synthetic:<scene>', 'piv:<name>' or a folder path")
    return Path(label)


def nominal_camera(width: int, height: int) -> PinholeCamera:
    """The camera written into fluid footage folders: image-plane only (the fluid stages work
    in pixels and never use a pose); identity pose, focal length = image width, centred."""
    return PinholeCamera(intrinsics(float(width), float(width), (width - 1) / 2, (height - 1) / 2),
                         np.eye(3), np.zeros(3), int(width), int(height))
