"""Hydra schema of the ``rigid`` config group (conf/rigid/*.yaml extend it)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class RigidConfig:
    """Settings of the rigid stages (filled in as the stages are wired)."""

    enabled: bool = True
