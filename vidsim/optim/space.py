"""Parameter spaces: named axes with bounds, linear or logarithmic, mapped to the unit cube."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from vidsim.errors import ConfigError


@dataclass(frozen=True)
class Axis:
    """One parameter: ``name``, bounds ``lo < hi`` (in the parameter's unit), ``log`` spacing."""

    name: str
    lo: float
    hi: float
    log: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lo) and math.isfinite(self.hi) and self.lo < self.hi):
            raise ConfigError(f"parameter '{self.name}': bounds must be finite with lo < hi, got [{self.lo}, {self.hi}]")
        if self.log and self.lo <= 0:
            raise ConfigError(f"parameter '{self.name}': a log axis needs lo > 0, got {self.lo}")


@dataclass(frozen=True)
class Space:
    """A box of parameters. ``to_unit``/``from_unit`` map (n,) or (m, n) arrays."""

    axes: tuple[Axis, ...]

    @property
    def names(self) -> list[str]:
        return [a.name for a in self.axes]

    @property
    def dim(self) -> int:
        return len(self.axes)

    def _lo_hi(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        lg = np.array([a.log for a in self.axes])
        lo = np.array([math.log(a.lo) if a.log else a.lo for a in self.axes])
        hi = np.array([math.log(a.hi) if a.log else a.hi for a in self.axes])
        return lo, hi, lg

    def to_unit(self, theta: np.ndarray) -> np.ndarray:
        """Parameter values (unit of each axis) to the unit cube (values outside the box map
        outside [0, 1]). A non-positive or NaN value on a log axis has no image: ConfigError."""
        lo, hi, lg = self._lo_hi()
        th = np.asarray(theta, float)
        bad = np.broadcast_to(lg, th.shape) & ~(th > 0)
        if np.any(bad):
            idx = tuple(np.argwhere(bad)[0])
            ax = self.axes[idx[-1]]
            raise ConfigError(f"parameter '{ax.name}' = {float(th[idx])!r}: its axis is logarithmic "
                              f"([{ax.lo}, {ax.hi}]), so values must be > 0")
        v = np.where(lg, np.log(np.where(lg, th, 1.0)), th)
        return (v - lo) / (hi - lo)

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        lo, hi, lg = self._lo_hi()
        v = lo + np.clip(np.asarray(u, float), 0.0, 1.0) * (hi - lo)
        return np.where(lg, np.exp(v), v)

    def as_dict(self, theta: np.ndarray) -> dict[str, float]:
        return {a.name: float(x) for a, x in zip(self.axes, np.asarray(theta, float))}

    @classmethod
    def from_config(cls, d: dict) -> "Space":
        """From ``{name: {lo, hi, log}}`` (a Hydra node converted to a dict)."""
        axes = []
        for name, spec in d.items():
            if not isinstance(spec, Mapping):
                raise ConfigError(f"parameter '{name}': expected a mapping {{lo, hi, log}}, got {spec!r}")
            unknown = set(spec) - {"lo", "hi", "log"}
            if unknown:
                raise ConfigError(f"parameter '{name}': unknown key(s) {sorted(unknown)} (expected lo, hi, log)")
            missing = [k for k in ("lo", "hi") if k not in spec]
            if missing:
                raise ConfigError(f"parameter '{name}': missing {missing} (expected lo, hi and optionally log)")
            if any(isinstance(spec[k], bool) for k in ("lo", "hi")):
                raise ConfigError(f"parameter '{name}': lo and hi must be numbers, got {spec['lo']!r}, {spec['hi']!r}")
            try:
                lo, hi = float(spec["lo"]), float(spec["hi"])
            except (TypeError, ValueError):
                raise ConfigError(f"parameter '{name}': lo and hi must be numbers, got {spec['lo']!r}, "
                                  f"{spec['hi']!r}") from None
            log = spec.get("log", False)
            if not isinstance(log, bool):
                # bool("no") and bool("false") are True: a string here would silently keep a log axis
                raise ConfigError(f"parameter '{name}': log must be true or false, got {log!r}")
            axes.append(Axis(name, lo, hi, log))
        return cls(tuple(axes))
