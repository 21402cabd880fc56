"""The Hydra schemas (``vidsim/config``) and the settings classes the Python API takes mirror each
other field by field; their defaults must agree, or a run through the API differs from the stage's
with the same (default) settings. Until 6 Dec 2026 the cloth posterior's did not (see
:class:`vidsim.posterior.cloth.ClothPosteriorSettings`)."""

from __future__ import annotations

import dataclasses

import pytest

from vidsim.clothfit.features import FeatureSettings
from vidsim.clothfit.film import FilmSettings
from vidsim.clothfit.objective import ModelSettings
from vidsim.config.cloth import ClothFeaturesConfig, ClothFitConfig, ClothModelConfig, ClothRealityConfig
from vidsim.config.gap import GapDiagnoseConfig
from vidsim.config.posterior import PosteriorClothConfig, PosteriorRigidConfig
from vidsim.config.rigid import RigidFitConfig, RigidSceneConfig, RigidSegmentConfig
from vidsim.config.schema import DynamicsEffects
from vidsim.gap.rigid_diagnose import DiagnoseConfig
from vidsim.optim.anneal import AnnealConfig
from vidsim.posterior.cloth import ClothPosteriorSettings
from vidsim.posterior.rigid import NoiseConfig
from vidsim.reality.rigid import RigidEffects, RigidRealityConfig
from vidsim.rigid.fit import FitConfig
from vidsim.video.segment import SegmentConfig

PAIRS = [
    (ClothFeaturesConfig, FeatureSettings),
    (ClothFitConfig, AnnealConfig),
    (ClothModelConfig, ModelSettings),
    (ClothRealityConfig, FilmSettings),
    (GapDiagnoseConfig, DiagnoseConfig),
    (PosteriorClothConfig, ClothPosteriorSettings),
    (PosteriorRigidConfig, NoiseConfig),
    (RigidFitConfig, FitConfig),
    (RigidSceneConfig, RigidRealityConfig),
    (RigidSegmentConfig, SegmentConfig),
    (DynamicsEffects, RigidEffects),
]


def defaults(obj) -> dict:
    """Field name -> default value of a dataclass instance, nested dataclasses flattened in (the
    cloth posterior's ``sampler`` holds the schema's emcee fields)."""
    out = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v):
            out.update({k: w for k, w in defaults(v).items() if k not in out})
        else:
            out[f.name] = list(v) if isinstance(v, tuple) else v
    return out


def plain(v):
    return list(v) if isinstance(v, tuple) else v


@pytest.mark.parametrize("schema, runtime", PAIRS, ids=[f"{a.__name__}-{b.__name__}" for a, b in PAIRS])
def test_schema_and_api_defaults_agree(schema, runtime):
    ds, dr = defaults(schema()), defaults(runtime())
    common = sorted(set(ds) & set(dr))
    assert len(common) >= 4, f"{schema.__name__} and {runtime.__name__} share only {common}: not a mirror pair"
    differ = {k: (plain(ds[k]), plain(dr[k])) for k in common if plain(ds[k]) != plain(dr[k])}
    assert not differ, f"defaults differ (schema, API): {differ}"
