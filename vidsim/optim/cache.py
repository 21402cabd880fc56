"""An append-only log of objective evaluations: the optimisers' checkpoint.

Every evaluation is appended as one JSON line (``{"key", "u", "f", "info"}``) and flushed and
fsync-ed before the optimiser continues. Optimisers are deterministic given their seed, so a
killed run resumes by running again from the start: every evaluation it already made is found
here (keyed by the exact unit-cube point) and returns at once, and the run continues past the
kill point with exactly the state it would have had. A torn last line (killed mid-write) is
ignored on reading. Lines are strict JSON: a non-finite number in a record's ``info`` is written
as the string ``"nan"``, ``"inf"`` or ``"-inf"`` and read back as that float
(:func:`vidsim.io.atomic.restore_nonfinite`; logs written before 5 Dec 2026 with bare ``NaN``
tokens still read).

A log belongs to one objective: with a ``context`` (e.g. :func:`fingerprint` of the footage and
settings that decide a score) its first line is ``{"context": ...}``, and a log found with another
context (or none) was written for a different objective (the footage was re-rendered, a model
setting changed, the simulator's kernels changed): it is moved aside to ``<name>.stale-<k>.jsonl``
(never deleted) and the run starts afresh, so a rerun after an input change does not replay
scores of the old inputs.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import sys
from pathlib import Path
from typing import Any, Callable

import numpy as np

from vidsim.io.atomic import restore_nonfinite, to_json
from vidsim.optim import FAILED_SCORE


def fingerprint(*objs: Any) -> str:
    """SHA-256 (hex) of nested values: arrays by dtype, shape and bytes, floats exactly (hex),
    dataclasses and plain objects by their fields, mappings by sorted keys. Two objectives whose
    inputs differ in any bit get different fingerprints."""
    h = hashlib.sha256()

    def feed(x: Any, depth: int = 0) -> None:
        if depth > 12:
            raise ValueError("fingerprint: nesting deeper than 12 levels (a cycle?)")
        if isinstance(x, str):  # length-prefixed: no string can mimic the separators of another
            b = x.encode()
            h.update(f"str:{len(b)}:".encode() + b)
        elif x is None or isinstance(x, (bool, int)):
            h.update(f"{type(x).__name__}:{x};".encode())
        elif isinstance(x, float):
            h.update(f"f:{float(x).hex()};".encode())
        elif isinstance(x, np.generic):
            feed(x.item(), depth + 1)
        elif isinstance(x, np.ndarray):
            h.update(f"a:{x.dtype.str}:{x.shape};".encode())
            h.update(np.ascontiguousarray(x).tobytes())
        elif isinstance(x, dict):
            h.update(b"{")
            for k in sorted(x, key=str):
                feed(str(k), depth + 1)
                feed(x[k], depth + 1)
            h.update(b"}")
        elif isinstance(x, (list, tuple)):
            h.update(b"[")
            for v in x:
                feed(v, depth + 1)
            h.update(b"]")
        elif dataclasses.is_dataclass(x):
            feed(type(x).__name__, depth + 1)
            feed({f.name: getattr(x, f.name) for f in dataclasses.fields(x)}, depth + 1)
        elif hasattr(x, "__dict__"):
            feed(type(x).__name__, depth + 1)
            feed({k: v for k, v in vars(x).items() if not callable(v)}, depth + 1)
        else:
            raise TypeError(f"fingerprint: cannot hash a {type(x).__name__}")

    for o in objs:
        feed(o)
    return h.hexdigest()


def log_context(path: str | os.PathLike) -> str | None:
    """The context of an evaluation log (None: no header, or no file)."""
    p = Path(path)
    if not p.is_file():
        return None
    with open(p) as fh:
        first = fh.readline()
    try:
        rec = json.loads(first)
    except json.JSONDecodeError:
        return None
    return rec.get("context") if isinstance(rec, dict) else None


def point_key(u: np.ndarray) -> str:
    """Exact, platform-stable key of a point (hex of the float64 values)."""
    return ",".join(float(x).hex() for x in np.asarray(u, float).ravel())


class EvalCache:
    """Cached, logged, NaN-safe objective.

    Args:
        fn: ``fn(u) -> float`` or ``fn(u) -> (float, info_dict)`` on the unit cube.
        path: the JSONL log (None: in memory only).
        context: what the scores depend on (e.g. :func:`fingerprint`); a log with another context
            is moved aside (``stale_moved`` says where) and not replayed. None: any log is replayed.
    """

    def __init__(self, fn: Callable[[np.ndarray], Any], path: str | os.PathLike | None = None,
                 context: str | None = None) -> None:
        self.fn = fn
        self.path = Path(path) if path is not None else None
        self.context = context
        self.store: dict[str, tuple[float, dict]] = {}
        self.history: list[tuple[np.ndarray, float]] = []  # in call order, including cache hits
        self.n_new = 0
        self.n_hits = 0
        self.stale_moved: Path | None = None
        if self.path is not None and self.path.is_file() and context is not None \
                and log_context(self.path) != context and self.path.stat().st_size > 0:
            k = 1
            while (stale := self.path.with_name(f"{self.path.stem}.stale-{k}{self.path.suffix}")).exists():
                k += 1
            self.path.rename(stale)
            self.stale_moved = stale
            print(f"{self.path}: written for another objective (footage, settings or simulator changed); "
                  f"moved to {stale.name}, not replayed", file=sys.stderr, flush=True)
        if self.path is not None and self.path.is_file():
            for line in self.path.read_text().splitlines():
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue  # torn last line of a killed run
                if "key" in rec:  # (the context header has none)
                    self.store[rec["key"]] = (float(rec["f"]), restore_nonfinite(rec.get("info", {})))
        self._fh = None
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._drop_torn_tail(self.path)
            new = not self.path.is_file() or self.path.stat().st_size == 0
            self._fh = open(self.path, "a")
            if new and context is not None:
                self._fh.write(to_json({"context": context}) + "\n")
                self._fh.flush()
                os.fsync(self._fh.fileno())

    @staticmethod
    def _drop_torn_tail(path: Path) -> None:
        """Cut a torn last line (a kill mid-write) so the next record starts on its own line; a last
        line that is a whole record and lost only its newline is kept (the newline added): it was
        read into the store, and cutting it would drop it from the log for the next reader."""
        if not path.is_file():
            return
        data = path.read_bytes()
        if data and not data.endswith(b"\n"):
            cut = data.rfind(b"\n") + 1
            try:
                whole = isinstance(json.loads(data[cut:].decode()), dict)
            except (UnicodeDecodeError, json.JSONDecodeError):
                whole = False
            with open(path, "r+b") as fh:
                if whole:
                    fh.seek(0, os.SEEK_END)
                    fh.write(b"\n")
                else:
                    fh.truncate(cut)
                fh.flush()
                os.fsync(fh.fileno())

    def __len__(self) -> int:
        return len(self.store)

    def __call__(self, u: np.ndarray) -> float:
        u = np.asarray(u, float)
        key = point_key(u)
        if key in self.store:
            self.n_hits += 1
            f = self.store[key][0]
        else:
            try:
                out = self.fn(u)
            except (ArithmeticError, np.linalg.LinAlgError) as e:  # a numerical fault is a failed point
                out = (FAILED_SCORE, {"failure": f"{type(e).__name__}: {e}"})
            f, info = (out if isinstance(out, tuple) else (out, {}))
            f = float(f)
            if not math.isfinite(f):
                info = {**info, "failure": "non-finite objective"}
                f = FAILED_SCORE
            self.store[key] = (f, info)
            self.n_new += 1
            if self._fh is not None:
                self._fh.write(to_json({"key": key, "u": u, "f": f, "info": info}, "string") + "\n")
                self._fh.flush()
                os.fsync(self._fh.fileno())
        self.history.append((u.copy(), f))
        return f

    def evaluate(self, u: np.ndarray, fn: Callable[[np.ndarray], Any] | None = None) -> tuple[float, dict]:
        """``(f, info)`` of the point ``u``: replayed from the log, or computed once by ``fn``
        (which becomes the cache's function; None: the one it has) and logged. For callers whose
        result lives in ``info`` (a stage's end point, a calibration): a failure (a numerical fault,
        ArithmeticError or LinAlgError, or a non-finite score) gives ``FAILED_SCORE`` and an ``info``
        without their fields (only ``failure``, the reason)."""
        if fn is not None:
            self.fn = fn
        f = self(u)
        return f, self.store[point_key(u)][1]

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def __enter__(self) -> "EvalCache":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def logged_keys(path: str | os.PathLike) -> set[str]:
    """The distinct point keys an evaluation log holds (its header and torn lines skipped; failed
    evaluations included: they simulated too)."""
    keys = set()
    for line in Path(path).read_text().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(rec, dict) and "key" in rec:
            keys.add(rec["key"])
    return keys


def keep_only(path: str | os.PathLike, keys: set[str] | list[str]) -> Path | None:
    """Reduce an evaluation log to the records of ``keys`` (a finished run's own evaluations), its
    context header kept, written atomically; records of other runs of the same objective (another
    seed or budget, replayed only where they coincide) are moved to ``<name>.other-runs-<k>.jsonl``
    rather than deleted. Then the log, and whatever reads it later (the cloth posterior's
    surrogate), is what a run in an empty folder leaves. Returns the path of the moved records,
    or None when there were none."""
    from vidsim.io.atomic import write_text

    p = Path(path)
    if not p.is_file():
        return None
    keys = set(keys)
    header, keep, other = [], [], []
    for line in p.read_text().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue  # a torn line
        if not isinstance(rec, dict):
            continue
        if "key" not in rec:
            header.append(line)
        elif rec["key"] in keys:
            keep.append(line)
        else:
            other.append(line)
    if not other:
        return None
    k = 1
    while (aside := p.with_name(f"{p.stem}.other-runs-{k}{p.suffix}")).exists():
        k += 1
    write_text(aside, "\n".join(header + other) + "\n")  # written before the log is cut: nothing lost on a kill
    write_text(p, "\n".join(header + keep) + "\n")
    return aside



class StepMemo:
    """Checkpoint of a deterministic multi-step computation (a diagnosis): each finished step's
    result kept in its own file, keyed by a fingerprint of everything it depends on.

    ``memo(name, args, compute)`` returns the result a killed, earlier run stored for the same
    ``context``, ``name`` and ``args``, or runs ``compute()`` and stores its result atomically
    (``<folder>/<name>-<key>.pkl``) before returning it. A rerun with the same folder therefore
    replays every finished step and computes the rest: its result is the uninterrupted run's bit
    for bit. A file written for other inputs (another ``context``: footage, fit, settings, code)
    has another key and is never read; an unreadable one is recomputed.

    Args:
        folder: where the steps are kept (None: keep nothing, compute every step).
        context: what every step depends on, e.g. :func:`fingerprint` of the inputs and the
            source digest.
    """

    def __init__(self, folder: str | os.PathLike | None, context: str) -> None:
        self.folder = Path(folder) if folder is not None else None
        self.context = context
        self.n_replayed = 0
        self.n_computed = 0

    def __call__(self, name: str, args: Any, compute: Callable[[], Any]) -> Any:
        import pickle

        from vidsim.io.atomic import atomic_path

        if self.folder is None:
            self.n_computed += 1
            return compute()
        key = fingerprint(self.context, name, args)
        path = self.folder / f"{name}-{key[:24]}.pkl"
        if path.is_file():
            try:
                doc = pickle.loads(path.read_bytes())
            except Exception:  # noqa: BLE001 -- unreadable (torn, another version's classes): recompute
                doc = None
            if isinstance(doc, dict) and doc.get("key") == key:
                self.n_replayed += 1
                return doc["value"]
        value = compute()
        with atomic_path(path) as tmp:
            tmp.write_bytes(pickle.dumps({"key": key, "value": value}))
        self.n_computed += 1
        return value
