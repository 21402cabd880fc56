"""Hydra schema of the ``fluid`` config group (conf/fluid/*.yaml extend it)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class FluidConfig:
    """Settings of the fluid stages (filled in as the stages are wired)."""

    enabled: bool = True
