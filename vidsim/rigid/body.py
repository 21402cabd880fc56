"""Rigid-body description: a union of boxes with uniform density (the thrown T-object).

The body frame has its origin at the centre of mass (as the body description *states* it) and
axes along the boxes. All lengths are metres, masses kilograms, inertia kg m^2.

The description round-trips through a plain dictionary (``to_meta``/``from_meta``) so that it can
be written to a footage folder's ``meta.yaml`` as a known input of the estimation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


class RigidBodyError(ValueError):
    """A rigid-body description or parameter is malformed; the message names the field."""


INERTIA_TRIANGLE_RTOL = 1e-3
"""Relative slack of the check ``I3 <= I1 + I2`` on the principal moments (room for rounded values
of a thin plate, which lies on the bound)."""

ROTATION_ATOL = 1e-6
"""How far a symmetry may be from orthonormal with determinant +1 (elementwise)."""

SYMMETRY_RTOL = 1e-3
"""A symmetry must map every box corner to within this fraction of the body's radius of a corner."""


# the 12 triangles of a unit cube with vertices ordered as in ``_BOX_SIGNS``
_BOX_SIGNS = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=float,
)
_BOX_FACES = np.array(
    [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
     [2, 3, 7], [2, 7, 6], [1, 2, 6], [1, 6, 5], [0, 4, 7], [0, 7, 3]],
    dtype=np.int64,
)


@dataclass
class BoxBody:
    """A rigid body made of axis-aligned boxes (in the body frame) of one uniform density.

    Attributes:
        centers: (B, 3) box centres in the body frame, metres, relative to the stated centre of mass.
        half_sizes: (B, 3) box half extents, metres.
        mass: total mass, kg.
        inertia: (3, 3) inertia tensor about the stated centre of mass in body axes, kg m^2.
        symmetries: (S, 3, 3) proper rotations (body frame, about the centre of mass) mapping the
            shape onto itself, the identity first. Orientations are only defined modulo these.
            Checked: each must be orthonormal with determinant +1 and map the set of box corners
            onto itself (within ``SYMMETRY_RTOL`` of the radius); the identity is added when
            missing (without it every orientation would differ from itself).

    Every field must be finite; ``inertia`` symmetric positive definite with principal moments
    obeying ``I3 <= I1 + I2`` (as every real mass distribution does, within ``INERTIA_TRIANGLE_RTOL``).
    """

    centers: np.ndarray
    half_sizes: np.ndarray
    mass: float
    inertia: np.ndarray
    symmetries: np.ndarray

    def __post_init__(self) -> None:
        for name, shape in (("centers", (-1, 3)), ("half_sizes", (-1, 3)), ("inertia", (3, 3)), ("symmetries", (-1, 3, 3))):
            v = getattr(self, name)
            try:
                arr = np.asarray(v, float)
                arr = arr.reshape(shape)
            except (TypeError, ValueError):
                want = "a 3x3 matrix (the full tensor in body axes, not 3 principal moments)" if name == "inertia" \
                    else f"numbers in groups of {shape[1:]}"
                raise RigidBodyError(f"body: '{name}' must be {want}, got {np.shape(v) if not isinstance(v, str) else repr(v)}") from None
            setattr(self, name, arr)
        try:
            self.mass = float(self.mass)
        except (TypeError, ValueError):
            raise RigidBodyError(f"body: 'mass' must be a number (kg), got {self.mass!r}") from None
        for name in ("centers", "half_sizes", "inertia", "symmetries"):
            arr = getattr(self, name)
            if not np.all(np.isfinite(arr)):
                raise RigidBodyError(f"body: '{name}' must be finite numbers, got {arr.tolist()}")
        if self.centers.shape != self.half_sizes.shape:
            raise RigidBodyError(
                f"body: 'centers' {self.centers.shape} and 'half_sizes' {self.half_sizes.shape} must match")
        if not np.all(self.half_sizes > 0):
            raise RigidBodyError(f"body: 'half_sizes' must be positive, got {self.half_sizes.tolist()}")
        if not (np.isfinite(self.mass) and self.mass > 0):
            raise RigidBodyError(f"body: 'mass' must be positive and finite, got {self.mass}")
        ev = np.linalg.eigvalsh(0.5 * (self.inertia + self.inertia.T))
        if not np.allclose(self.inertia, self.inertia.T, atol=1e-12) or ev.min() <= 0:
            raise RigidBodyError(f"body: 'inertia' must be symmetric positive definite, got {self.inertia.tolist()} "
                                 f"(eigenvalues {ev.tolist()})")
        # principal moments of any mass distribution obey I_a <= I_b + I_c (equality: a flat plate)
        if ev[2] > (ev[0] + ev[1]) * (1.0 + INERTIA_TRIANGLE_RTOL):
            raise RigidBodyError(
                f"body: 'inertia' is not the inertia of any rigid body: its principal moments {ev.tolist()} violate "
                f"I3 <= I1 + I2 ({ev[2]:.6g} > {ev[0] + ev[1]:.6g}; relative tolerance {INERTIA_TRIANGLE_RTOL:g}). "
                "Expected the full 3x3 tensor about the centre of mass in body axes, kg m^2")
        self.symmetries = self._checked_symmetries(self.symmetries)

    def _checked_symmetries(self, sym: np.ndarray) -> np.ndarray:
        """``sym`` validated: each a proper rotation mapping the box corners onto themselves; the
        identity first (added when missing, moved to the front when elsewhere)."""
        V = self.box_vertices().reshape(-1, 3)
        tol = SYMMETRY_RTOL * float(np.linalg.norm(V, axis=1).max())
        for i, S in enumerate(sym):
            if (np.abs(S.T @ S - np.eye(3)).max() > ROTATION_ATOL or abs(np.linalg.det(S) - 1.0) > ROTATION_ATOL):
                raise RigidBodyError(
                    f"body: 'symmetries[{i}]' = {S.tolist()} is not a proper rotation: expected an orthonormal "
                    f"3x3 matrix with determinant +1 (det = {np.linalg.det(S):.6g}; tolerance {ROTATION_ATOL:g})")
            W = V @ S.T
            miss = float(np.linalg.norm(W[:, None, :] - V[None, :, :], axis=2).min(axis=1).max())
            if miss > tol:
                raise RigidBodyError(
                    f"body: 'symmetries[{i}]' = {S.tolist()} does not map the boxes onto themselves: a rotated "
                    f"corner is {miss:.3g} m from every corner (tolerance {tol:.3g} m = {SYMMETRY_RTOL:g} x the "
                    "body's radius). Expected rotations about the centre of mass that leave the shape unchanged")
        is_id = [bool(np.abs(S - np.eye(3)).max() <= ROTATION_ATOL) for S in sym]
        rest = [S for S, e in zip(sym, is_id) if not e]
        return np.stack([np.eye(3), *rest])

    @property
    def n_boxes(self) -> int:
        """Number of boxes."""
        return self.centers.shape[0]

    def box_vertices(self) -> np.ndarray:
        """(B, 8, 3) box corners in the body frame, metres."""
        return self.centers[:, None, :] + _BOX_SIGNS[None, :, :] * self.half_sizes[:, None, :]

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """Triangle mesh of the boxes: vertices (8B, 3) body frame, faces (12B, 3) int."""
        V = self.box_vertices().reshape(-1, 3)
        F = np.concatenate([_BOX_FACES + 8 * b for b in range(self.n_boxes)])
        return V, F

    def radius(self) -> float:
        """Largest distance of a corner from the centre of mass, metres."""
        return float(np.linalg.norm(self.box_vertices().reshape(-1, 3), axis=1).max())

    def to_meta(self) -> dict:
        """Plain dictionary for ``meta.yaml`` (the known shape, mass and inertia)."""
        return {
            "type": "boxes",
            "centers": self.centers.tolist(),
            "half_sizes": self.half_sizes.tolist(),
            "mass": self.mass,
            "inertia": self.inertia.tolist(),
            "symmetries": self.symmetries.round(12).tolist(),
        }

    @classmethod
    def from_meta(cls, d: dict, where: str = "meta.object") -> "BoxBody":
        """Inverse of :meth:`to_meta`; errors name ``where`` and the missing field."""
        if not isinstance(d, dict):
            raise RigidBodyError(f"{where}: expected a mapping, got {type(d).__name__}")
        missing = [k for k in ("centers", "half_sizes", "mass", "inertia") if k not in d]
        if missing:
            raise RigidBodyError(f"{where}: missing field(s) {missing}")
        sym = d.get("symmetries", [np.eye(3).tolist()])
        try:
            return cls(d["centers"], d["half_sizes"], d["mass"], d["inertia"], sym)
        except RigidBodyError as e:
            raise RigidBodyError(f"{where}: {e}") from e


def box_union_mass_properties(centers: np.ndarray, half_sizes: np.ndarray, density: float
                              ) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass, centre of mass and inertia (about the centre of mass) of disjoint uniform boxes.

    Args:
        centers: (B, 3) box centres, metres.
        half_sizes: (B, 3) half extents, metres.
        density: kg / m^3.

    Returns:
        (mass kg, com (3,) metres, inertia (3, 3) kg m^2 about com, same axes).
    """
    c = np.asarray(centers, float).reshape(-1, 3)
    h = np.asarray(half_sizes, float).reshape(-1, 3)
    m = density * 8.0 * np.prod(h, axis=1)
    M = m.sum()
    com = (m[:, None] * c).sum(0) / M
    Itot = np.zeros((3, 3))
    for mi, ci, hi in zip(m, c, h):
        a, b, cc = 2 * hi
        Ib = mi / 12.0 * np.diag([b * b + cc * cc, a * a + cc * cc, a * a + b * b])
        d = ci - com
        Itot += Ib + mi * (d @ d * np.eye(3) - np.outer(d, d))
    return float(M), com, Itot


def t_object(bar_length: float = 0.30, stem_length: float = 0.24, thickness: float = 0.06,
             density: float = 600.0) -> tuple[BoxBody, np.ndarray]:
    """The T-shaped object: a bar along body x on top of a stem along body -y.

    Args:
        bar_length: length of the top bar (x), metres.
        stem_length: length of the stem below the bar (y), metres.
        thickness: square cross-section side of both boxes, metres.
        density: kg / m^3 (600 is a light wood).

    Returns:
        (body, com_in_shape_frame): the body with its frame at the centre of mass, and where that
        centre lies in the shape frame (bar centre at the origin), metres.
    """
    for name, v in (("bar_length", bar_length), ("stem_length", stem_length),
                    ("thickness", thickness), ("density", density)):
        if not (np.isfinite(v) and v > 0):
            raise RigidBodyError(f"t_object: '{name}' must be positive, got {v}")
    t = thickness
    centers = np.array([[0.0, 0.0, 0.0], [0.0, -(t / 2 + stem_length / 2), 0.0]])
    half = np.array([[bar_length / 2, t / 2, t / 2], [t / 2, stem_length / 2, t / 2]])
    M, com, inertia = box_union_mass_properties(centers, half, density)
    ry_pi = np.diag([-1.0, 1.0, -1.0])  # half turn about the stem axis maps the T onto itself
    body = BoxBody(centers - com, half, M, inertia, np.stack([np.eye(3), ry_pi]))
    return body, com
