"""Atomic file writes: a killed job never leaves a truncated output behind.

Every writer goes through :func:`atomic_path`, which yields a temporary path in the
same folder and renames it over the target only when the block finished without error.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any, Iterator

import numpy as np
import yaml


_UMASK = os.umask(0)
os.umask(_UMASK)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    Args:
        path: final destination. Parent folders are created.
        suffix: suffix of the temporary file (defaults to the target's, so that
            libraries choosing a format by extension still work).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    suffix = path.suffix if suffix is None else suffix
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".part{suffix}", dir=path.parent)
    os.close(fd)
    os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes 0600; outputs are ordinary files
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        with open(tmp_path, "rb+") as fh:  # on disk before the rename: a crash cannot leave it empty
            os.fsync(fh.fileno())
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def replace_dir(tmp: str | os.PathLike, out: str | os.PathLike, stale: tuple = ()) -> None:
    """Put a stage's finished staging folder ``tmp`` in the place of ``out``.

    The old ``out`` is renamed aside first and deleted only after the new one is in place, so a
    kill never leaves a half-deleted folder under the output's name. ``stale``: files that belong
    with the old ``out`` (e.g. its truth beside it), removed before the swap so that they are never
    found beside the new folder; the caller writes their new versions after this returns.
    """
    import shutil

    tmp, out = Path(tmp), Path(out)
    for p in stale:
        Path(p).unlink(missing_ok=True)
    # an old folder a killed swap left behind (named by the pid before 5 Dec 2026, so never found again)
    for left in out.parent.glob(f".{out.name}.old*"):
        shutil.rmtree(left, ignore_errors=True)
    old = None
    if out.exists():
        old = out.with_name(f".{out.name}.old")
        os.replace(out, old)
    os.replace(tmp, out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


#: how :func:`to_json` writes a non-finite float: ``"null"`` (strict JSON's usual reading, the default;
#: the value is lost) or ``"string"`` (``"nan"``, ``"inf"``, ``"-inf"``, for files a reader computes
#: with again and that need the distinction: :func:`restore_nonfinite` turns them back into floats)
NONFINITE_MODES = ("null", "string")
_NONFINITE_STRINGS = {"nan": float("nan"), "inf": float("inf"), "-inf": float("-inf")}


def _to_plain(obj: Any, nonfinite: str | None = None, where: str = "") -> Any:
    """Plain Python values (numpy arrays and scalars, paths, tuples converted); with ``nonfinite``
    (one of :data:`NONFINITE_MODES`) every NaN / +-inf float is replaced as that mode says. In
    ``"string"`` mode a string value that is itself ``"nan"``, ``"inf"`` or ``"-inf"`` (a label, say)
    is refused (ValueError naming its key path, ``where`` that of ``obj``): :func:`restore_nonfinite`
    would read it back as a float."""
    if isinstance(obj, dict):
        return {str(k): _to_plain(v, nonfinite, f"{where}.{k}" if where else str(k)) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_to_plain(v, nonfinite, f"{where}[{i}]") for i, v in enumerate(obj)]
    if isinstance(obj, np.ndarray):
        return _to_plain(obj.tolist(), nonfinite, where)
    if isinstance(obj, np.generic):
        return _to_plain(obj.item(), nonfinite, where)
    if isinstance(obj, Path):
        obj = str(obj)
    if nonfinite is not None and isinstance(obj, float) and not math.isfinite(obj):
        return None if nonfinite == "null" else ("nan" if obj != obj else ("inf" if obj > 0 else "-inf"))
    if nonfinite == "string" and isinstance(obj, str) and obj in _NONFINITE_STRINGS:
        raise ValueError(f"{where or '(top level)'} = {obj!r}: a string that would be read back as a float "
                         f"(restore_nonfinite); with nonfinite='string' such a value cannot be written")
    return obj


def to_json(data: Any, nonfinite: str = "null", **kw: Any) -> str:
    """``data`` (numpy arrays allowed) as strict JSON text (``allow_nan=False``: no ``NaN`` or
    ``Infinity`` tokens, which Python reads but browsers and ``jq`` refuse). Non-finite floats are
    written as ``nonfinite`` says (:data:`NONFINITE_MODES`; ``"string"`` refuses a string value
    ``"nan"``/``"inf"``/``"-inf"``, which would come back as a float); ``kw`` go to :func:`json.dumps`."""
    if nonfinite not in NONFINITE_MODES:
        raise ValueError(f"nonfinite must be one of {NONFINITE_MODES}, got {nonfinite!r}")
    return json.dumps(_to_plain(data, nonfinite), allow_nan=False, **kw)


def restore_nonfinite(obj: Any) -> Any:
    """The inverse of ``to_json(..., nonfinite="string")``: the strings ``"nan"``, ``"inf"`` and
    ``"-inf"`` anywhere in a parsed document become floats again (everything else unchanged)."""
    if isinstance(obj, dict):
        return {k: restore_nonfinite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [restore_nonfinite(v) for v in obj]
    if isinstance(obj, str) and obj in _NONFINITE_STRINGS:
        return _NONFINITE_STRINGS[obj]
    return obj


def write_yaml(path: str | os.PathLike, data: Any) -> None:
    """Write ``data`` (numpy arrays allowed) as YAML, atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(yaml.safe_dump(_to_plain(data), sort_keys=False))


def write_json(path: str | os.PathLike, data: Any, nonfinite: str = "null") -> None:
    """Write ``data`` (numpy arrays allowed) as strict JSON, atomically (:func:`to_json`: a NaN or
    infinite float becomes ``null``, or with ``nonfinite="string"`` the string ``"nan"``/``"inf"``/
    ``"-inf"``, read back by :func:`restore_nonfinite`)."""
    text = to_json(data, nonfinite, indent=2)  # before the file is opened: a refused value leaves no file
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write a text file atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_npz(path: str | os.PathLike, **arrays: np.ndarray) -> None:
    """Write a compressed ``.npz`` atomically."""
    with atomic_path(path, suffix=".npz") as tmp:
        np.savez_compressed(tmp, **arrays)
