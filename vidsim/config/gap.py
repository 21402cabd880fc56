"""Hydra schema of the ``gap`` config group (conf/gap/*.yaml extend it).

The gap stages diagnose the sim-to-real gap of a fit (issue 7): ``diagnose`` (one rigid fit:
where the gap lies, which candidate effect explains it, how far it shrinks), ``gap_suite``
(withheld-effect cases: film, fit, diagnose blind, score against the truth) and ``gap_ball``
(the real ball toss read at a constant 30 fps and with the container's timestamps). Units are SI
unless a name says otherwise (``_px``, ``_s``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


def _all_effects() -> list[str]:
    from vidsim.gap.rigid_model import RIGID_EFFECTS

    return list(RIGID_EFFECTS)


@dataclass
class GapDiagnoseConfig:
    """Settings of the rigid diagnosis (:class:`vidsim.gap.rigid_diagnose.DiagnoseConfig`, same names).

    Attributes:
        candidates: library effects considered (default: all of ``vidsim.gap.rigid_model.RIGID_EFFECTS``).
        holdout: fraction of the visible frames held out from every refit.
        split: "interleaved" (every round(1/holdout)-th frame) or "end" (the last frames).
        scale: image scale of the residuals (0.5 = half resolution).
        ramp: soft-silhouette anti-aliasing ramp, pixels at that scale.
        roi_px: region of interest around the silhouettes, pixels at that scale.
        top_k: screened candidates refitted; max_nfev: residual evaluations per refit.
        min_closure: held-out fraction of the excess over the noise floor an effect must close
            (of what the effects named before it leave).
        min_excess: the held-out gap must exceed the floor by this fraction for anything to be named.
        jitter_min_white: share of the fitted time errors' variance a cubic drift must leave.
        pairs: forward selection may name a second effect: while a gap beyond the floor remains
            after the first, screen again with it in the model and refit the best of the rest with it.
        joint_pairs: (with pairs) when no single effect is named although a gap remains, refit the pairs of the
            top_k screened candidates jointly and name a pair that closes min_closure and beats each
            member alone by pair_min_gain (held-out closure).
        pair_min_gain: held-out closure each member of a jointly named pair must add.
        blur_thresholds: segmentation thresholds (fractions of the exposure) tried in a refit with
            motion blur; the lowest training cost wins.
    """

    candidates: list[str] = field(default_factory=_all_effects)
    holdout: float = 0.3
    split: str = "interleaved"
    scale: float = 0.5
    ramp: float = 1.0
    roi_px: int = 12
    top_k: int = 3
    max_nfev: int = 15
    min_closure: float = 0.5
    min_excess: float = 0.15
    jitter_min_white: float = 0.5
    pairs: bool = True
    joint_pairs: bool = True
    pair_min_gain: float = 0.2
    blur_thresholds: list[float] = field(default_factory=lambda: [0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5])


@dataclass
class GapPathsConfig:
    """Extra inputs of the diagnose stage: the silhouettes (``masks.npz`` of the segment stage)
    and the fit (``fit.yaml`` of ``fit_rigid``); empty: ``<paths.out>/../rigid/<case>/...`` must be given."""

    masks: str = ""
    fit: str = ""


@dataclass
class GapSceneConfig:
    """The synthetic throws of the suite (see :class:`vidsim.reality.rigid.RigidRealityConfig`).

    Attributes:
        n_frames: frames of a throw; n_background: background frames before it.
        width, height: image size, pixels; focal: pixels.
    """

    n_frames: int = 40
    n_background: int = 3
    width: int = 640
    height: int = 480
    focal: float = 640.0


@dataclass
class GapClothConfig:
    """The cloth domain's withheld-effect cases (stage ``gap_cloth_suite``, :mod:`vidsim.gap.cloth_suite`).

    Attributes:
        diagnose: settings of :class:`vidsim.gap.cloth_diagnose.ClothDiagnoseConfig` that differ
            from its defaults (same names; an unknown name stops the stage before any case runs).
        scene: settings of :class:`vidsim.gap.cloth_suite.ClothSceneConfig` that differ from its
            defaults (same names, same check).
        cases: name -> ``{label, seed, kind, fabric, effects}`` (see :mod:`vidsim.gap.cloth_suite`).
        only: names of the cases to run (empty: all).
    """

    diagnose: dict[str, Any] = field(default_factory=dict)
    scene: dict[str, Any] = field(default_factory=dict)
    cases: dict[str, Any] = field(default_factory=dict)
    only: list[str] = field(default_factory=list)


@dataclass
class GapConfig:
    """Settings of the gap stages.

    Attributes:
        enabled: the family's switch inside Hydra (Snakemake's ``stages.gap`` decides what runs).
        diagnose: the diagnosis settings.
        paths: inputs of the ``diagnose`` stage.
        scene: the suite's synthetic throws.
        cases: the suite's cases, name -> ``{label, seed, effects | gust, render}`` (see
            :mod:`vidsim.gap.suite`); ``conf/gap/default.yaml`` holds the public suite.
        only: names of the cases to run (empty: all), e.g. the quick subset.
        cloth: the cloth domain's cases (``gap_cloth_suite``).
    """

    enabled: bool = True
    diagnose: GapDiagnoseConfig = field(default_factory=GapDiagnoseConfig)
    paths: GapPathsConfig = field(default_factory=GapPathsConfig)
    scene: GapSceneConfig = field(default_factory=GapSceneConfig)
    cases: dict[str, Any] = field(default_factory=dict)
    only: list[str] = field(default_factory=list)
    cloth: GapClothConfig = field(default_factory=GapClothConfig)
