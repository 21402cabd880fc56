"""Hydra schema of the ``cloth`` config group (conf/cloth/*.yaml extend it)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class ClothConfig:
    """Settings of the cloth stages (filled in as the stages are wired)."""

    enabled: bool = True
