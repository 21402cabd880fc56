"""Hydra schema of the ``gap`` config group (conf/gap/*.yaml extend it)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class GapConfig:
    """Settings of the gap stages (filled in as the stages are wired)."""

    enabled: bool = True
