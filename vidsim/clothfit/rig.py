"""The estimator's rigs: known inputs of a trial -> model mesh, driven vertices, colliders.

A *swatch* trial knows the measured paths of its two gripped top corners
(:func:`vidsim.clothfit.film.swatch_model_mesh`, :func:`~vidsim.clothfit.film.swatch_driver`).
A *skirt* trial (the seed's Figure 9 generalisation) knows the skipping body's motion, as motion
capture would give it: the waist's position and orientation per frame and the two legs as
capsules, plus the skirt's cut (waist and hem radii, slant length). :func:`skirt_model_rig`
dresses that motion with the estimator's own skirt mesh: the waistband follows the measured
waist pose, the legs are kinematic capsule colliders. Units: metres, seconds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from vidsim.cloth import ClothMesh, Colliders, DrivenVertices, skirt
from vidsim.errors import VidsimError

__all__ = ["RigError", "SkirtBody", "skirt_fold_starts", "skirt_model_rig", "skirt_model_mesh"]


class RigError(VidsimError):
    """Known inputs of a trial are malformed (names the field and what was expected)."""


@dataclass(frozen=True)
class SkirtBody:
    """The skipping body and the skirt's cut, as measured (known inputs of a skirt trial).

    Attributes:
        waist_pos: (T, 3) waist centre per frame, metres.
        waist_rot: (T, 3, 3) world-from-waist rotation per frame (waist z up, waistband in its xy plane).
        legs: (T, 2, 2, 3) hip and ankle end points of the two leg capsules per frame, metres.
        leg_radius: capsule radius, metres.
        waist_radius, hem_radius, length: the skirt's cut (slant length from waist to hem), metres.
    """

    waist_pos: np.ndarray
    waist_rot: np.ndarray
    legs: np.ndarray
    leg_radius: float
    waist_radius: float
    hem_radius: float
    length: float

    def __post_init__(self) -> None:
        p = np.asarray(self.waist_pos, float)
        T = p.shape[0] if p.ndim == 2 else -1
        r = np.asarray(self.waist_rot, float)
        legs = np.asarray(self.legs, float)
        if p.ndim != 2 or p.shape[1] != 3 or T < 1:
            raise RigError(f"skirt body waist_pos must be (T, 3) metres, got shape {p.shape}")
        if r.shape != (T, 3, 3):
            raise RigError(f"skirt body waist_rot must be (T, 3, 3) = {(T, 3, 3)}, got {r.shape}")
        if legs.shape != (T, 2, 2, 3):
            raise RigError(f"skirt body legs must be (T, 2, 2, 3) = {(T, 2, 2, 3)}, got {legs.shape}")
        for name, a in (("waist_pos", p), ("waist_rot", r), ("legs", legs)):
            if not np.all(np.isfinite(a)):
                raise RigError(f"skirt body {name} must be finite")
        err = np.abs(np.einsum("tji,tjk->tik", r, r) - np.eye(3)).max()
        if err > 1e-3:
            raise RigError(f"skirt body waist_rot must be rotation matrices (max |R'R - I| = {err:.3g})")
        for name in ("leg_radius", "waist_radius", "hem_radius", "length"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0):
                raise RigError(f"skirt body {name} must be > 0 metres, got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)
        if not (self.hem_radius >= self.waist_radius and self.length > self.hem_radius - self.waist_radius):
            raise RigError(f"skirt cut needs hem_radius >= waist_radius and length > hem_radius - waist_radius, got "
                           f"{self.waist_radius}, {self.hem_radius}, {self.length}")
        object.__setattr__(self, "waist_pos", p)
        object.__setattr__(self, "waist_rot", r)
        object.__setattr__(self, "legs", legs)

    @property
    def n_frames(self) -> int:
        return int(self.waist_pos.shape[0])

    def subset(self, idx: np.ndarray) -> "SkirtBody":
        """The frames ``idx``."""
        return SkirtBody(self.waist_pos[idx], self.waist_rot[idx], self.legs[idx], self.leg_radius,
                         self.waist_radius, self.hem_radius, self.length)

    def to_meta(self) -> dict[str, Any]:
        """Plain lists for ``meta.yaml`` (the ``body`` field of a skirt footage folder)."""
        return {"waist_pos": np.round(self.waist_pos, 6).tolist(), "waist_rot": np.round(self.waist_rot, 7).tolist(),
                "legs": np.round(self.legs, 6).tolist(), "leg_radius": self.leg_radius,
                "cut": {"waist_radius": self.waist_radius, "hem_radius": self.hem_radius, "length": self.length}}

    @classmethod
    def from_meta(cls, d: Any, where: str) -> "SkirtBody":
        """Inverse of :meth:`to_meta`; errors name ``where`` (the meta.yaml path)."""
        if not isinstance(d, dict):
            raise RigError(f"{where}: field 'body' must be a mapping, got {type(d).__name__}")
        missing = [k for k in ("waist_pos", "waist_rot", "legs", "leg_radius", "cut") if k not in d]
        if missing:
            raise RigError(f"{where}: field 'body' lacks {missing}")
        cut = d["cut"]
        if not isinstance(cut, dict) or set(cut) != {"waist_radius", "hem_radius", "length"}:
            raise RigError(f"{where}: body.cut must give waist_radius, hem_radius and length (m), got {cut!r}")
        try:
            return cls(np.asarray(d["waist_pos"], float), np.asarray(d["waist_rot"], float), np.asarray(d["legs"], float),
                       d["leg_radius"], cut["waist_radius"], cut["hem_radius"], cut["length"])
        except RigError as e:
            raise RigError(f"{where}: {e}") from None
        except (TypeError, ValueError) as e:
            raise RigError(f"{where}: field 'body' is not numeric ({e})") from None


SKIRT_REST_BEND = ("cone", "flat")
"""Bending rest state of the estimator's skirt: ``cone`` (the sewn cone is the rest shape: no
bending force in the cone) or ``flat`` (the fabric's own rest curvature, zero: it was cut flat and
the seam alone holds it in a cone, so bending resists the cone's curvature as in a sewn garment)."""


def skirt_model_mesh(body: SkirtBody, rings: int, around: int, rest_bend: str = "cone"
                     ) -> tuple[ClothMesh, np.ndarray]:
    """The estimator's skirt at the frame-0 waist pose.

    Args:
        body: the measured body and cut.
        rings: vertex rings from waist to hem (>= 2). around: vertices per ring (>= 3).
        rest_bend: bending rest state, one of :data:`SKIRT_REST_BEND`.

    Returns:
        ``(mesh, waist_local)``: the mesh (starting in the sewn cone; its bending rest state per
        ``rest_bend``) and the (around, 3) waistband vertices in the waist frame.
    """
    if int(rings) < 2 or int(around) < 3:
        raise RigError(f"skirt model needs rings >= 2 and around >= 3, got {rings}, {around}")
    if rest_bend not in SKIRT_REST_BEND:
        raise RigError(f"cloth.skirt.model_rest_bend = {rest_bend!r}: expected one of {list(SKIRT_REST_BEND)}")
    flat = rest_bend == "flat"
    local = skirt(int(around), int(rings), body.waist_radius, body.hem_radius, body.length,
                  waist_center=(0.0, 0.0, 0.0), flat_rest_bend=flat)
    R0, p0 = body.waist_rot[0], body.waist_pos[0]
    X = p0 + local.rest_positions @ R0.T
    mesh = ClothMesh(X, local.triangles, local.tri_uv, local.tags, flat_rest_bend=flat)
    return mesh, local.rest_positions[local.tags["waistband"]].copy()


def skirt_model_rig(body: SkirtBody, times: np.ndarray, rings: int, around: int, settle_s: float,
                    rest_bend: str = "cone") -> tuple[ClothMesh, DrivenVertices, float, Colliders]:
    """Mesh, waistband driver and leg colliders for the estimator's skirt.

    The body stands still in its frame-0 pose for ``settle_s`` before the first frame (the skirt
    settles), then the waistband follows ``waist_pos + waist_rot @ local`` through the measured
    frames (cubic Hermite between them) and the legs move linearly between frames.

    Args:
        body: measured body motion, ``body.n_frames == len(times)``.
        times: (T,) frame times, seconds.
        rings, around: model resolution.
        settle_s: rest before ``times[0]``, seconds (> 0).
        rest_bend: bending rest state (:func:`skirt_model_mesh`).

    Returns:
        ``(mesh, driver, t0, colliders)`` with ``t0 = times[0] - settle_s``.
    """
    t = np.asarray(times, float)
    if t.shape != (body.n_frames,):
        raise RigError(f"skirt body has {body.n_frames} frames but {t.shape} times were given")
    if not settle_s > 0:
        raise RigError(f"settle_s must be > 0 s, got {settle_s}")
    mesh, local = skirt_model_mesh(body, rings, around, rest_bend)
    t0 = float(t[0] - settle_s)
    tt = np.concatenate([[t0, t[0] - 1e-3 * settle_s], t])
    pos = np.concatenate([body.waist_pos[:1], body.waist_pos[:1], body.waist_pos])
    rot = np.concatenate([body.waist_rot[:1], body.waist_rot[:1], body.waist_rot])
    ring = pos[:, None, :] + np.einsum("tij,nj->tni", rot, local)
    vel = np.gradient(ring, tt, axis=0)
    vel[:2] = 0.0
    drv = DrivenVertices(mesh.tags["waistband"], tt, ring, vel)
    legs = np.concatenate([body.legs[:1], body.legs])
    tc = np.concatenate([[t0], t])
    K = tc.size
    col = Colliders(tc, np.zeros((K, 0, 3)), np.zeros(0), legs[:, :, 0], legs[:, :, 1], np.full(2, body.leg_radius))
    return mesh, drv, t0, col


#: angular orders of the fold seeds (folds around the hem; the footage's skirts hang in ~4-8)
FOLD_ORDERS = tuple(range(3, 9))


def skirt_fold_starts(mesh: ClothMesh, body: SkirtBody, members: int, amplitude: float, seed: int = 0
                      ) -> list[np.ndarray]:
    """Fold-seeded start positions of the estimator's skirt: an ensemble over the unseen fold pattern.

    From the exact sewn cone the model skirt leaves its near-symmetric shape slowly or not at all
    (measured: a knit-like skirt folds only after ~1 s of settling, fleece- and linen-like ones stay
    open through 1.5 s), where a real (or MuJoCo) skirt hangs in folds; where the folds form is a
    symmetry-breaking choice the footage's known inputs do not give. Each member starts from the
    cone with a radial displacement ``amplitude * d * w(phi)``: ``d`` the depth below the waistband
    (0 at the waistband, 1 at the hem), ``w`` a random sum of ``cos(k phi + phase)`` over
    :data:`FOLD_ORDERS` scaled to ``max |w| = 1``. Member ``m`` draws from
    ``numpy.random.default_rng([seed, m])``: fixed, reproducible, different per member. The settle
    before frame 0 then lets the fabric's own stiffness decide how far the seed grows into folds.

    Args:
        mesh: the model skirt at the frame-0 waist pose (:func:`skirt_model_mesh`).
        body: the measured body (frame-0 waist pose and axis).
        members: ensemble size (>= 1).
        amplitude: largest radial displacement at the hem, metres (> 0).
        seed: ensemble seed.

    Returns:
        ``members`` arrays (N, 3) of start positions, metres.
    """
    if int(members) != members or members < 1:
        raise RigError(f"cloth.skirt.model_fold_members must be an integer >= 1, got {members!r}")
    if not (np.isfinite(amplitude) and 0 < amplitude < body.hem_radius):
        raise RigError(f"cloth.skirt.model_fold_amplitude must be in (0, hem radius {body.hem_radius} m), "
                       f"got {amplitude!r}")
    R0, p0 = np.asarray(body.waist_rot[0], float), np.asarray(body.waist_pos[0], float)
    X = mesh.rest_positions
    L = (X - p0) @ R0  # waist frame: z along the waist axis, the waistband in its xy plane
    phi = np.arctan2(L[:, 1], L[:, 0])
    depth = np.clip(-L[:, 2], 0.0, None)
    depth = depth / max(float(depth.max()), 1e-12)
    radial = np.stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)], axis=1) @ R0.T
    out = []
    for m in range(int(members)):
        rng = np.random.default_rng([int(seed), m])
        w = np.zeros(X.shape[0])
        for k in FOLD_ORDERS:
            w += rng.standard_normal() * np.cos(k * phi + rng.uniform(0.0, 2.0 * np.pi))
        w /= max(float(np.abs(w).max()), 1e-12)
        out.append(X + (amplitude * depth * w)[:, None] * radial)
    return out
