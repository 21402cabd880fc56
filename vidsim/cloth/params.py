"""Cloth model parameters (SI units) and their plausible ranges.

The nine *estimated* parameters follow the order of Table 1 of the seed (bend, stretch,
shear, bend damping, stretch damping, shear damping, linear drag kT, quadratic drag kN,
drag degradation kf). The *known* parameters (area density, gravity, collision settings)
are measured or chosen by hand, as in the seed.

Units and meaning (energies scale linearly with rest area, seed section 4.2, so the same
numbers hold on any mesh resolution):

=================  ==========  =============================================================
name               unit        meaning
=================  ==========  =============================================================
bend               N m         bending rigidity D: energy per area D/2 * curvature^2
stretch            N/m         membrane stretch stiffness: energy per area k/2 * strain^2,
                               applied to the warp (u) and weft (v) directions alike
                               (their geometric mean with ``stretch_anisotropy``, below)
shear              N/m         in-plane shear stiffness: energy per area k/2 * (w_u . w_v)^2
bend_damping       N m s       Rayleigh damping on the dihedral-angle rate (per area)
stretch_damping    N s/m       Rayleigh damping on the strain rate
shear_damping      N s/m       Rayleigh damping on the shear rate
drag_linear (kT)   N s/m^3     tangential (Stokes-like) drag per area: a*kT*vT
drag_quad (kN)     kg/m^3      normal drag per area: a*kN*|vN|^2/(1+kf|vN|^2)
drag_degrade (kf)  s^2/m^2     drag degradation; normal drag saturates at a*kN/kf
                               (a: the triangle's current, deformed area)
=================  ==========  =============================================================

Not estimated by the study (known or 0): ``stretch_anisotropy`` (-), the natural log of the
warp-to-weft stretch stiffness ratio; the warp (u) stiffness is ``stretch * exp(a/2)`` and the weft
(v) one ``stretch * exp(-a/2)`` (their geometric mean stays ``stretch``; 0 = isotropic, bit for bit
the isotropic model). The sim-to-real gap's cloth library frees it as the candidate
``anisotropic_stretch``.

Relation to the seed's Table 1. The seed reports per-mesh numbers of an unstated
normalisation (e.g. stretch 50-4000, bend 1e-6-1e-3, damping 0.6-10, drag 0.3-9).
Its stretch and shear magnitudes happen to be plausible as SI membrane stiffnesses in
N/m (Kawabata tensile tests of woven fabrics give a few hundred to a few thousand N/m,
knits tens of N/m), and its bend values as SI bending rigidities in N m for light
fabrics (1e-6-1e-4 N m). Its damping and drag numbers cannot be mapped without the
unknown mass and length normalisation, so our ranges for them are set from physics
instead: quadratic normal drag 0.5*rho_air*C_d ~ 0.7 kg/m^3 for a flat plate, damping
from undamped up to 0.1 N s/m, which damps the lowest in-plane membrane mode of a 0.3 m swatch
(top row held) by a damping ratio of only 0.29 at the soft corner of the box (20 / 2 N/m) and
0.014 at the stiff one (2000 / 500 N/m): critical damping would need about 0.4-4 N s/m (the
range was described as reaching critical damping until a review measured it, 6 Dec 2026; not
widened, so that the fits stay comparable). :data:`PARAM_RANGES` holds these ranges and the mid-range values of parameters a
fit does not estimate (``docs/cloth_parameters.md`` explains them). The fit's search box
(``cloth.fit.space``) mirrors it except for ``stretch``, searched up to 4000 N/m rather than 2000 so
that the stiffest woven fabrics (MuJoCo linen: the oracle fit gives 3690 N/m) lie inside it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import ClassVar

import numpy as np

__all__ = [
    "ClothParamError",
    "ClothParams",
    "ESTIMATED_NAMES",
    "PARAM_RANGES",
    "PARAM_UNITS",
    "mid_range_params",
]


class ClothParamError(ValueError):
    """A cloth parameter is invalid (negative, NaN, wrong shape, ...)."""


#: Names of the nine estimated parameters in the seed's Table 1 order.
ESTIMATED_NAMES: tuple[str, ...] = (
    "bend",
    "stretch",
    "shear",
    "bend_damping",
    "stretch_damping",
    "shear_damping",
    "drag_linear",
    "drag_quad",
    "drag_degrade",
)

#: SI unit of every parameter.
PARAM_UNITS: dict[str, str] = {
    "bend": "N m",
    "stretch": "N/m",
    "shear": "N/m",
    "bend_damping": "N m s",
    "stretch_damping": "N s/m",
    "shear_damping": "N s/m",
    "drag_linear": "N s/m^3",
    "drag_quad": "kg/m^3",
    "drag_degrade": "s^2/m^2",
    "density": "kg/m^2",
    "gravity": "m/s^2",
    "collision_stiffness": "N/m^3",
    "collision_thickness": "m",
    "self_collision_stiffness": "N/m^3",
    "self_collision_thickness": "m",
    "stretch_anisotropy": "-",
}

#: Plausible (low, high) range of each estimated parameter, SI units. Sampling is
#: meant to be log-uniform for the stiffnesses and dampings (they span decades).
PARAM_RANGES: dict[str, tuple[float, float]] = {
    "bend": (1e-7, 1e-4),
    "stretch": (20.0, 2000.0),
    "shear": (2.0, 500.0),
    "bend_damping": (1e-9, 1e-6),
    "stretch_damping": (1e-4, 0.1),
    "shear_damping": (1e-4, 0.1),
    "drag_linear": (0.0, 2.0),
    "drag_quad": (0.0, 3.0),
    "drag_degrade": (0.0, 1.0),
}


@dataclass(frozen=True)
class ClothParams:
    """Physical parameters of the cloth model, SI units.

    Attributes:
        bend: bending rigidity D [N m].
        stretch: membrane stretch stiffness [N/m] (warp and weft).
        shear: in-plane shear stiffness [N/m].
        bend_damping: damping of the dihedral-angle rate [N m s].
        stretch_damping: damping of the strain rate [N s/m].
        shear_damping: damping of the shear rate [N s/m].
        drag_linear: kT, tangential linear drag [N s/m^3].
        drag_quad: kN, normal quadratic drag [kg/m^3].
        drag_degrade: kf, drag degradation [s^2/m^2].
        density: area density of the fabric [kg/m^2] (known, measured).
        gravity: gravity vector [m/s^2], shape (3,) (known; direction configurable).
        collision_stiffness: repulsion pressure per metre of penetration into the
            thickness layer of spheres/capsules [N/m^3].
        collision_thickness: distance from a collider surface at which repulsion
            starts [m].
        self_collision_stiffness: same for cloth-cloth repulsion [N/m^3].
        self_collision_thickness: cloth-cloth repulsion distance [m]; must be smaller
            than about 0.7 rest edge lengths (checked by :func:`vidsim.cloth.simulate`).
        stretch_anisotropy: ln(warp / weft stretch stiffness) [-], any finite value (0:
            isotropic); see :attr:`stretch_warp` and :attr:`stretch_weft`.

    Raises:
        ClothParamError: at construction when a value is NaN/inf, negative, or the
            gravity vector is not three finite numbers.
    """

    bend: float = 1e-5
    stretch: float = 200.0
    shear: float = 30.0
    bend_damping: float = 3e-8
    stretch_damping: float = 3e-3
    shear_damping: float = 3e-3
    drag_linear: float = 0.5
    drag_quad: float = 0.7
    drag_degrade: float = 0.2
    density: float = 0.2
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    collision_stiffness: float = 2e5
    collision_thickness: float = 3e-3
    self_collision_stiffness: float = 3e5
    self_collision_thickness: float = 3e-3
    stretch_anisotropy: float = 0.0

    _POSITIVE: ClassVar[tuple[str, ...]] = (
        "density",
        "collision_thickness",
        "self_collision_thickness",
    )
    _SIGNED: ClassVar[tuple[str, ...]] = ("stretch_anisotropy",)

    def __post_init__(self) -> None:
        for f in fields(self):
            name = f.name
            val = getattr(self, name)
            if name == "gravity":
                try:
                    g = tuple(float(c) for c in val)
                except TypeError as exc:
                    raise ClothParamError(
                        f"gravity must be a sequence of 3 numbers [m/s^2], got {val!r}"
                    ) from exc
                if len(g) != 3 or not all(math.isfinite(c) for c in g):
                    raise ClothParamError(
                        f"gravity must be 3 finite numbers [m/s^2], got {val!r}"
                    )
                object.__setattr__(self, "gravity", g)
                continue
            try:
                fval = float(val)
            except (TypeError, ValueError) as exc:
                raise ClothParamError(f"{name} must be a number, got {val!r}") from exc
            if not math.isfinite(fval):
                raise ClothParamError(
                    f"{name} must be finite [{PARAM_UNITS[name]}], got {val!r}"
                )
            if fval < 0.0 and name not in self._SIGNED:
                raise ClothParamError(
                    f"{name} must be >= 0 [{PARAM_UNITS[name]}], got {fval!r}"
                )
            if name in self._POSITIVE and fval <= 0.0:
                raise ClothParamError(
                    f"{name} must be > 0 [{PARAM_UNITS[name]}], got {fval!r}"
                )
            object.__setattr__(self, name, fval)

    @property
    def stretch_warp(self) -> float:
        """Stretch stiffness along the warp (u) [N/m]: ``stretch * exp(stretch_anisotropy / 2)``."""
        return self.stretch if self.stretch_anisotropy == 0.0 else self.stretch * math.exp(0.5 * self.stretch_anisotropy)

    @property
    def stretch_weft(self) -> float:
        """Stretch stiffness along the weft (v) [N/m]: ``stretch * exp(-stretch_anisotropy / 2)``."""
        return self.stretch if self.stretch_anisotropy == 0.0 else self.stretch * math.exp(-0.5 * self.stretch_anisotropy)

    def estimated_vector(self) -> np.ndarray:
        """The nine estimated parameters in Table 1 order, shape (9,)."""
        return np.array([getattr(self, n) for n in ESTIMATED_NAMES], dtype=float)

    def with_estimated(self, theta: np.ndarray | list[float]) -> "ClothParams":
        """A copy with the nine estimated parameters replaced (Table 1 order).

        Args:
            theta: shape (9,), SI units as in :data:`PARAM_UNITS`.

        Raises:
            ClothParamError: wrong length or an invalid value.
        """
        theta = np.asarray(theta, dtype=float).ravel()
        if theta.shape != (len(ESTIMATED_NAMES),):
            raise ClothParamError(
                f"theta must have {len(ESTIMATED_NAMES)} entries ({', '.join(ESTIMATED_NAMES)}), "
                f"got shape {theta.shape}"
            )
        kw = {f.name: getattr(self, f.name) for f in fields(self)}
        kw.update({n: float(v) for n, v in zip(ESTIMATED_NAMES, theta)})
        return ClothParams(**kw)

    def replace(self, **changes: float) -> "ClothParams":
        """A validated copy with some fields changed."""
        kw = {f.name: getattr(self, f.name) for f in fields(self)}
        unknown = set(changes) - set(kw)
        if unknown:
            raise ClothParamError(f"unknown cloth parameter(s) {sorted(unknown)}; known: {sorted(kw)}")
        kw.update(changes)
        return ClothParams(**kw)


def mid_range_params(**known: float) -> ClothParams:
    """Parameters at the middle of :data:`PARAM_RANGES`.

    Geometric mean of the range for parameters whose low end is > 0, arithmetic mean
    otherwise.

    Args:
        **known: overrides of known or estimated fields (e.g. ``density=0.2``).
    """
    kw: dict[str, float] = {}
    for name in ESTIMATED_NAMES:
        lo, hi = PARAM_RANGES[name]
        kw[name] = math.sqrt(lo * hi) if lo > 0 else 0.5 * (lo + hi)
    kw.update(known)
    return ClothParams(**kw)
