"""An append-only log of objective evaluations: the optimisers' checkpoint.

Every evaluation is appended as one JSON line (``{"key", "u", "f", "info"}``) and flushed and
fsync-ed before the optimiser continues. Optimisers are deterministic given their seed, so a
killed run resumes by running again from the start: every evaluation it already made is found
here (keyed by the exact unit-cube point) and returns at once, and the run continues past the
kill point with exactly the state it would have had. A torn last line (killed mid-write) is
ignored on reading.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any, Callable

import numpy as np

from vidsim.optim import FAILED_SCORE


def point_key(u: np.ndarray) -> str:
    """Exact, platform-stable key of a point (hex of the float64 values)."""
    return ",".join(float(x).hex() for x in np.asarray(u, float).ravel())


class EvalCache:
    """Cached, logged, NaN-safe objective.

    Args:
        fn: ``fn(u) -> float`` or ``fn(u) -> (float, info_dict)`` on the unit cube.
        path: the JSONL log (None: in memory only).
    """

    def __init__(self, fn: Callable[[np.ndarray], Any], path: str | os.PathLike | None = None) -> None:
        self.fn = fn
        self.path = Path(path) if path is not None else None
        self.store: dict[str, tuple[float, dict]] = {}
        self.history: list[tuple[np.ndarray, float]] = []  # in call order, including cache hits
        self.n_new = 0
        self.n_hits = 0
        if self.path is not None and self.path.is_file():
            for line in self.path.read_text().splitlines():
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue  # torn last line of a killed run
                self.store[rec["key"]] = (float(rec["f"]), rec.get("info", {}))
        self._fh = None
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._drop_torn_tail(self.path)
            self._fh = open(self.path, "a")

    @staticmethod
    def _drop_torn_tail(path: Path) -> None:
        """Cut a torn last line (a kill mid-write) so the next record starts on its own line."""
        if not path.is_file():
            return
        data = path.read_bytes()
        if data and not data.endswith(b"\n"):
            with open(path, "r+b") as fh:
                fh.truncate(data.rfind(b"\n") + 1)
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
            except FloatingPointError:
                out = FAILED_SCORE
            f, info = (out if isinstance(out, tuple) else (out, {}))
            f = float(f)
            if not math.isfinite(f):
                info = {**info, "failure": "non-finite objective"}
                f = FAILED_SCORE
            self.store[key] = (f, info)
            self.n_new += 1
            if self._fh is not None:
                self._fh.write(json.dumps({"key": key, "u": u.tolist(), "f": f, "info": info}) + "\n")
                self._fh.flush()
                os.fsync(self._fh.fileno())
        self.history.append((u.copy(), f))
        return f

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def __enter__(self) -> "EvalCache":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
