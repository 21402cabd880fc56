"""vidsim.cloth: Baraff-Witkin cloth with the seed's nonlinear air drag (SI units).

Meshes (:func:`swatch`, :func:`skirt`), parameters (:class:`ClothParams`,
:data:`PARAM_RANGES`), colliders (:class:`Colliders`) and the pure simulation function
:func:`simulate` returning a :class:`SimResult`. See ``docs/cloth_parameters.md``.
"""

from vidsim.cloth.collision import Colliders, ColliderError, count_self_intersections
from vidsim.cloth.mesh import ClothMesh, MeshError, skirt, swatch
from vidsim.cloth.params import (
    ESTIMATED_NAMES,
    PARAM_RANGES,
    PARAM_UNITS,
    ClothParamError,
    ClothParams,
    mid_range_params,
)
from vidsim.cloth.simulate import (
    ClothInputError,
    ClothStepError,
    DrivenVertices,
    SimResult,
    compute_forces,
    energies,
    simulate,
    stable_step,
)

__all__ = [
    "ClothMesh",
    "MeshError",
    "swatch",
    "skirt",
    "ClothParams",
    "ClothParamError",
    "ESTIMATED_NAMES",
    "PARAM_RANGES",
    "PARAM_UNITS",
    "mid_range_params",
    "Colliders",
    "ColliderError",
    "count_self_intersections",
    "ClothInputError",
    "ClothStepError",
    "DrivenVertices",
    "SimResult",
    "simulate",
    "compute_forces",
    "energies",
    "stable_step",
]
