"""Hydra schema of the ``posterior`` config group (conf/posterior/*.yaml extend it)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class PosteriorConfig:
    """Settings of the posterior stages (filled in as the stages are wired)."""

    enabled: bool = True
