"""Progress lines for long stages: one line per step (throttled) with the time left."""

from __future__ import annotations

import sys
import time


class Progress:
    """Print ``[desc] i/n  elapsed  ETA`` lines to stderr, at most every ``every_s`` seconds.

    Args:
        total: number of steps.
        desc: short label (stage and what is counted).
        every_s: minimum seconds between lines (the last step always prints).
        enabled: False silences it (tests).
    """

    def __init__(self, total: int, desc: str, every_s: float = 2.0, enabled: bool = True) -> None:
        self.total, self.desc, self.every_s, self.enabled = int(total), desc, every_s, enabled
        self.t0 = time.perf_counter()
        self._last = -1e9
        self.i = 0

    def update(self, n: int = 1, note: str = "") -> None:
        self.i += n
        now = time.perf_counter()
        if not self.enabled or (now - self._last < self.every_s and self.i < self.total):
            return
        self._last = now
        el = now - self.t0
        if self.i > self.total:  # the total was an estimate (e.g. a diagnosis's optional steps): no time left to give
            print(f"[{self.desc}] {self.i} (over the {self.total} estimated)  {el:6.1f}s elapsed  {note}",
                  file=sys.stderr, flush=True)
            return
        eta = el / self.i * (self.total - self.i) if self.i else float("nan")
        print(f"[{self.desc}] {self.i}/{self.total}  {el:6.1f}s elapsed  ~{eta:6.1f}s left  {note}", file=sys.stderr, flush=True)
