"""Triangle meshes for cloth: a rectangular swatch and a skirt (truncated cone).

A :class:`ClothMesh` holds the rest shape (3D positions), the triangles, each triangle's
rest material coordinates (u = warp, v = weft, metres) from which the Baraff-Witkin
stretch/shear conditions are built, and the interior edges with their two opposite
vertices for the bend condition. Masses come from the area density at simulation time
(lumped: a third of each incident triangle's rest area per vertex).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["ClothMesh", "MeshError", "swatch", "skirt"]


class MeshError(ValueError):
    """A mesh is malformed (bad shapes, degenerate triangles, bad sizes)."""


@dataclass(frozen=True)
class ClothMesh:
    """A cloth triangle mesh with its rest state.

    Attributes:
        rest_positions: (N, 3) rest positions [m].
        triangles: (M, 3) int vertex indices, consistently oriented.
        tri_uv: (M, 3, 2) rest material coordinates of each triangle's corners [m]
            (u = warp direction, v = weft direction).
        tags: named vertex index sets, e.g. ``{"top_corners": array([0, nx-1])}``.

    Derived (filled at construction):
        tri_area: (M,) rest areas [m^2].
        tri_coef: (M, 6) d w_u / d x_{i,j,k} then d w_v / d x_{i,j,k} [1/m].
        bend_edges: (E, 4) int (x0, x1, x2, x3): shared edge x0->x1 as ordered in the
            first triangle (x0, x1, x2); the second triangle is (x1, x0, x3).
        bend_coef: (E,) |e|^2 / (A1 + A2) at rest (dimensionless).
        bend_rest: (E,) rest dihedral angles [rad] (zero for a flat rest shape).
        bend_tris: (E, 2) the two triangles of each bend edge.
        bend_quad: (E, 4) weights K_j / sqrt(A1 + A2) [1/m] of the quadratic bending model
            (Bergou et al. 2006): rest cotangent weights from the flat material (u, v)
            coordinates, so that sum_j K_j x_j = 0 for any in-plane (affine) state.
        vertex_area: (N,) lumped rest area per vertex [m^2].
        vertex_valence: (N,) number of triangles per vertex.
        tri_edge_share: (M, 3) triangles sharing the edge opposite each corner.
    """

    rest_positions: np.ndarray
    triangles: np.ndarray
    tri_uv: np.ndarray
    tags: dict[str, np.ndarray] = field(default_factory=dict)
    flat_rest_bend: bool = True
    tri_area: np.ndarray = field(init=False, repr=False)
    tri_coef: np.ndarray = field(init=False, repr=False)
    bend_edges: np.ndarray = field(init=False, repr=False)
    bend_coef: np.ndarray = field(init=False, repr=False)
    bend_rest: np.ndarray = field(init=False, repr=False)
    bend_tris: np.ndarray = field(init=False, repr=False)
    bend_quad: np.ndarray = field(init=False, repr=False)
    vertex_area: np.ndarray = field(init=False, repr=False)
    vertex_valence: np.ndarray = field(init=False, repr=False)
    tri_edge_share: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        X = np.ascontiguousarray(np.asarray(self.rest_positions, dtype=np.float64))
        T = np.ascontiguousarray(np.asarray(self.triangles, dtype=np.int64))
        UV = np.ascontiguousarray(np.asarray(self.tri_uv, dtype=np.float64))
        if X.ndim != 2 or X.shape[1] != 3:
            raise MeshError(f"rest_positions must have shape (N, 3), got {X.shape}")
        if T.ndim != 2 or T.shape[1] != 3:
            raise MeshError(f"triangles must have shape (M, 3), got {T.shape}")
        if UV.shape != (T.shape[0], 3, 2):
            raise MeshError(f"tri_uv must have shape (M, 3, 2) = {(T.shape[0], 3, 2)}, got {UV.shape}")
        if T.size and (T.min() < 0 or T.max() >= X.shape[0]):
            raise MeshError(f"triangle indices must lie in [0, {X.shape[0]}), got [{T.min()}, {T.max()}]")
        if not np.all(np.isfinite(X)) or not np.all(np.isfinite(UV)):
            raise MeshError("rest_positions and tri_uv must be finite")
        object.__setattr__(self, "rest_positions", X)
        object.__setattr__(self, "triangles", T)
        object.__setattr__(self, "tri_uv", UV)
        object.__setattr__(self, "tags", {k: np.asarray(v, dtype=np.int64) for k, v in self.tags.items()})

        du1 = UV[:, 1, 0] - UV[:, 0, 0]
        du2 = UV[:, 2, 0] - UV[:, 0, 0]
        dv1 = UV[:, 1, 1] - UV[:, 0, 1]
        dv2 = UV[:, 2, 1] - UV[:, 0, 1]
        det = du1 * dv2 - du2 * dv1
        if np.any(np.abs(det) < 1e-14):
            bad = int(np.argmin(np.abs(det)))
            raise MeshError(f"triangle {bad} has a degenerate rest (u, v) shape (area {0.5 * det[bad]:.3g} m^2)")
        area = 0.5 * np.abs(det)
        # w_u = dx1 * dv2/det - dx2 * dv1/det ; w_v = -dx1 * du2/det + dx2 * du1/det
        aj = dv2 / det
        ak = -dv1 / det
        bj = -du2 / det
        bk = du1 / det
        coef = np.stack([-(aj + ak), aj, ak, -(bj + bk), bj, bk], axis=1)
        object.__setattr__(self, "tri_area", area)
        object.__setattr__(self, "tri_coef", np.ascontiguousarray(coef))

        va = np.zeros(X.shape[0])
        for c in range(3):
            np.add.at(va, T[:, c], area / 3.0)
        if np.any(va <= 0):
            raise MeshError(f"{int(np.sum(va <= 0))} vertices belong to no triangle")
        object.__setattr__(self, "vertex_area", va)
        val = np.bincount(T.ravel(), minlength=X.shape[0]).astype(np.float64)
        object.__setattr__(self, "vertex_valence", val)
        # triangles sharing the edge opposite each corner (1 on the boundary, 2 inside)
        opp = np.stack([T[:, [1, 2]], T[:, [2, 0]], T[:, [0, 1]]], axis=1)  # (M, 3, 2)
        keys = np.sort(opp.reshape(-1, 2), axis=1)
        _, inv, cnt = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
        object.__setattr__(self, "tri_edge_share", cnt[inv.ravel()].reshape(-1, 3).astype(np.float64))

        edges, coefs, rest, etris = _bend_edges(X, T, area)
        object.__setattr__(self, "bend_tris", etris)
        object.__setattr__(self, "bend_quad", _quadratic_bend_weights(T, UV, area, edges, etris))
        if self.flat_rest_bend:
            rest = np.zeros_like(rest)
        object.__setattr__(self, "bend_edges", edges)
        object.__setattr__(self, "bend_coef", coefs)
        object.__setattr__(self, "bend_rest", rest)

    @property
    def n_vertices(self) -> int:
        """Number of vertices N."""
        return int(self.rest_positions.shape[0])

    @property
    def n_triangles(self) -> int:
        """Number of triangles M."""
        return int(self.triangles.shape[0])

    def masses(self, density: float) -> np.ndarray:
        """Lumped vertex masses [kg], shape (N,), for an area density [kg/m^2]."""
        if not (density > 0 and math.isfinite(density)):
            raise MeshError(f"density must be a positive finite number [kg/m^2], got {density!r}")
        return density * self.vertex_area

    def unique_edges(self) -> np.ndarray:
        """All undirected edges, shape (K, 2), sorted pairs."""
        T = self.triangles
        e = np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
        e.sort(axis=1)
        return np.unique(e, axis=0)

    def min_rest_edge(self) -> float:
        """Shortest rest edge length [m]."""
        e = self.unique_edges()
        return float(np.min(np.linalg.norm(self.rest_positions[e[:, 0]] - self.rest_positions[e[:, 1]], axis=1)))


def _dihedral(x0: np.ndarray, x1: np.ndarray, x2: np.ndarray, x3: np.ndarray) -> np.ndarray:
    e = x1 - x0
    n1 = np.cross(x1 - x0, x2 - x0)
    n2 = np.cross(x0 - x1, x3 - x1)
    en = e / np.linalg.norm(e, axis=1, keepdims=True)
    s = np.einsum("ij,ij->i", np.cross(n1, n2), en)
    c = np.einsum("ij,ij->i", n1, n2)
    return np.arctan2(s, c)


def _bend_edges(X: np.ndarray, T: np.ndarray, area: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Interior edges with opposite vertices; raises on non-manifold or flipped meshes."""
    first: dict[tuple[int, int], tuple[int, int]] = {}
    out = []
    for t, (a, b, c) in enumerate(T):
        for (p, q, r) in ((a, b, c), (b, c, a), (c, a, b)):
            key = (min(p, q), max(p, q))
            if key not in first:
                first[key] = (t, p)
                continue
            t0, p0 = first[key]
            if p0 == p:
                raise MeshError(f"triangles {t0} and {t} share edge {key} with the same orientation")
            ta = T[t0]
            # opposite vertex of the first triangle, ordered so that (x0, x1, x2) follows ta
            x0, x1 = p0, (q if p0 == p else p)
            x2 = int([v for v in ta if v not in key][0])
            x3 = int(r)
            out.append((x0, x1, x2, x3, t0, t))
    if not out:
        z = np.zeros((0, 4), dtype=np.int64)
        return z, np.zeros(0), np.zeros(0), np.zeros((0, 2), dtype=np.int64)
    arr = np.array(out, dtype=np.int64)
    edges = np.ascontiguousarray(arr[:, :4])
    L2 = np.sum((X[edges[:, 1]] - X[edges[:, 0]]) ** 2, axis=1)
    coefs = L2 / (area[arr[:, 4]] + area[arr[:, 5]])
    rest = _dihedral(X[edges[:, 0]], X[edges[:, 1]], X[edges[:, 2]], X[edges[:, 3]])
    return edges, coefs, rest, np.ascontiguousarray(arr[:, 4:6])


def _quadratic_bend_weights(T: np.ndarray, UV: np.ndarray, area: np.ndarray, edges: np.ndarray,
                            etris: np.ndarray) -> np.ndarray:
    """Cotangent weights of the quadratic bending model, (E, 4), over (x0, x1, x2, x3).

    K = (c03 + c04, c01 + c02, -c01 - c03, -c02 - c04) / sqrt(A1 + A2), with c0k the
    cotangent of the rest angle at x0 and c(k) at x1 in triangle 1 (x0, x1, x2) and 2
    (x1, x0, x3), measured in the material (u, v) coordinates (Bergou et al. 2006, with
    their 3/(A1+A2) replaced by 1/(A1+A2) so that small-angle energies equal the dihedral
    model's k_b/2 |e|^2/(A1+A2) theta^2).
    """
    if edges.shape[0] == 0:
        return np.zeros((0, 4))

    def corner_uv(t: np.ndarray, vert: np.ndarray) -> np.ndarray:
        c = np.argmax(T[t] == vert[:, None], axis=1)
        return UV[t, c]

    t1, t2 = etris[:, 0], etris[:, 1]
    u0a, u1a, u2 = corner_uv(t1, edges[:, 0]), corner_uv(t1, edges[:, 1]), corner_uv(t1, edges[:, 2])
    u0b, u1b, u3 = corner_uv(t2, edges[:, 0]), corner_uv(t2, edges[:, 1]), corner_uv(t2, edges[:, 3])

    def cot(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        p, q = a - o, b - o
        return (p[:, 0] * q[:, 0] + p[:, 1] * q[:, 1]) / np.abs(p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0])

    c01 = cot(u0a, u1a, u2)  # at x0, triangle 1
    c03 = cot(u1a, u0a, u2)  # at x1, triangle 1
    c02 = cot(u0b, u1b, u3)  # at x0, triangle 2
    c04 = cot(u1b, u0b, u3)  # at x1, triangle 2
    K = np.stack([c03 + c04, c01 + c02, -c01 - c03, -c02 - c04], axis=1)
    return np.ascontiguousarray(K / np.sqrt(area[t1] + area[t2])[:, None])


def _grid_triangles(nu: int, nv: int, wrap_u: bool = False) -> np.ndarray:
    """Triangles of an nv-row by nu-column vertex grid, alternating diagonals."""
    tris = []
    ncols = nu if wrap_u else nu - 1
    for r in range(nv - 1):
        for c in range(ncols):
            c1 = (c + 1) % nu
            i00 = r * nu + c
            i01 = r * nu + c1
            i10 = (r + 1) * nu + c
            i11 = (r + 1) * nu + c1
            if (r + c) % 2 == 0:
                tris.append((i00, i10, i11))
                tris.append((i00, i11, i01))
            else:
                tris.append((i00, i10, i01))
                tris.append((i01, i10, i11))
    return np.array(tris, dtype=np.int64)


def swatch(
    nu: int,
    nv: int,
    width: float = 0.3,
    height: float = 0.3,
    *,
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
    axis_u: tuple[float, float, float] = (1.0, 0.0, 0.0),
    axis_v: tuple[float, float, float] = (0.0, 0.0, -1.0),
) -> ClothMesh:
    """A rectangular swatch of nu x nv vertices.

    Vertex ``r * nu + c`` sits at ``origin + (c/(nu-1))*width*axis_u + (r/(nv-1))*height*axis_v``.
    By default the swatch hangs in the x-z plane with its top edge along +x at z = 0.

    Args:
        nu: vertices along the warp (u, width) direction, >= 2.
        nv: vertices along the weft (v, height) direction, >= 2.
        width: size along u [m].
        height: size along v [m].
        origin: position of vertex 0 (top-left corner) [m].
        axis_u, axis_v: orthonormal directions of u and v in space.

    Returns:
        The mesh, tagged with ``top_corners`` (2,), ``top_row`` (nu,), ``corners`` (4,)
        ordered top-left, top-right, bottom-left, bottom-right.
    """
    if int(nu) != nu or int(nv) != nv or nu < 2 or nv < 2:
        raise MeshError(f"swatch needs integer nu, nv >= 2, got nu={nu!r}, nv={nv!r}")
    if not (width > 0 and height > 0):
        raise MeshError(f"swatch width and height must be > 0 [m], got {width!r}, {height!r}")
    au = np.asarray(axis_u, dtype=float)
    av = np.asarray(axis_v, dtype=float)
    if abs(np.linalg.norm(au) - 1) > 1e-9 or abs(np.linalg.norm(av) - 1) > 1e-9 or abs(au @ av) > 1e-9:
        raise MeshError(f"axis_u and axis_v must be orthonormal, got {axis_u!r}, {axis_v!r}")
    nu, nv = int(nu), int(nv)
    cu, rv = np.meshgrid(np.arange(nu), np.arange(nv))
    u = (cu.ravel() / (nu - 1)) * width
    v = (rv.ravel() / (nv - 1)) * height
    X = np.asarray(origin, dtype=float)[None, :] + u[:, None] * au[None, :] + v[:, None] * av[None, :]
    T = _grid_triangles(nu, nv)
    # orient so that normals are au x av... consistent anyway; material coords (u, v)
    uv = np.stack([u, v], axis=1)[T]
    tags = {
        "top_corners": np.array([0, nu - 1]),
        "top_row": np.arange(nu),
        "corners": np.array([0, nu - 1, (nv - 1) * nu, nv * nu - 1]),
    }
    return ClothMesh(X, T, uv, tags)


def skirt(
    n_around: int,
    n_down: int,
    waist_radius: float = 0.14,
    hem_radius: float = 0.30,
    length: float = 0.45,
    *,
    waist_center: tuple[float, float, float] = (0.0, 0.0, 1.0),
    flat_rest_bend: bool = True,
) -> ClothMesh:
    """A skirt: a truncated cone hanging from a waistband (z up).

    Ring 0 is the waistband (tag ``waistband``) at ``waist_center``; ring ``n_down - 1``
    is the hem, ``length`` below along the slant. Material u runs around the hoop, v
    down the slant; each triangle's rest (u, v) is the flat triangle itself laid in its
    plane, u along the hoop's tangent at its centroid, so the sewn skirt is stress-free
    (zero stretch and shear energy) at rest. (Until 5 Dec 2026 the rest (u, v) came from the
    smooth cone's development, whose hoop arcs are longer than the mesh's chords: every hoop
    edge was compressed at rest, -0.44 % at 18 around, a hoop stress comparable to the
    gravity tension that drives the skirt's folds; review.)

    Args:
        n_around: vertices per ring, >= 3.
        n_down: rings, >= 2.
        waist_radius: [m], > 0.
        hem_radius: [m], >= waist_radius.
        length: slant length from waist to hem [m], > hem_radius - waist_radius.
        waist_center: centre of the waistband ring [m].
        flat_rest_bend: True: the fabric's natural state is flat (bend energy of the
            cone curvature is present, as for a real sewn skirt); False: the cone is the
            bending rest shape.
    """
    if int(n_around) != n_around or n_around < 3 or int(n_down) != n_down or n_down < 2:
        raise MeshError(f"skirt needs n_around >= 3 and n_down >= 2, got {n_around!r}, {n_down!r}")
    if not (waist_radius > 0 and hem_radius >= waist_radius and length > hem_radius - waist_radius):
        raise MeshError(
            "skirt needs 0 < waist_radius <= hem_radius and length > hem_radius - waist_radius, got "
            f"waist_radius={waist_radius!r}, hem_radius={hem_radius!r}, length={length!r}"
        )
    n_around, n_down = int(n_around), int(n_down)
    s = np.linspace(0.0, length, n_down)  # slant distance from the waist
    dr = hem_radius - waist_radius
    sin_a = dr / length
    cos_a = math.sqrt(1.0 - sin_a**2)
    phi = 2.0 * math.pi * np.arange(n_around) / n_around
    S, PHI = np.meshgrid(s, phi, indexing="ij")
    R = waist_radius + S * sin_a
    c = np.asarray(waist_center, dtype=float)
    X = np.stack([c[0] + R * np.cos(PHI), c[1] + R * np.sin(PHI), c[2] - S * cos_a], axis=-1).reshape(-1, 3)
    T = _grid_triangles(n_around, n_down, wrap_u=True)
    # orient triangles so that normals point outward
    P = X[T]
    n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    radial = P.mean(axis=1) - c
    radial[:, 2] = 0.0
    flip = np.einsum("ij,ij->i", n, radial) < 0
    T[flip] = T[flip][:, [0, 2, 1]]
    # exact development of each triangle, in a frame with u along the hoop at its centroid
    ring = T // n_around
    col = T % n_around
    sv = s[ring]
    ph = phi[col]
    ph0 = ph[:, :1]
    dph = (ph - ph0 + math.pi) % (2 * math.pi) - math.pi  # unwrap across the seam
    ph_c = ph0 + dph.mean(axis=1, keepdims=True)
    ph_u = ph0 + dph
    if dr > 1e-12:
        rho0 = waist_radius / sin_a  # apex distance of the waist
        rho = rho0 + sv
        psi = (ph_u - ph_c) * sin_a  # development angle
        u = rho * np.sin(psi)
        v = rho * np.cos(psi)
    else:
        u = waist_radius * (ph_u - ph_c)
        v = sv
    dev = np.stack([u, v], axis=-1)  # the smooth cone's development: orientation and directions only
    # each flat triangle in its own plane: u along the hoop tangent at the centroid (projected
    # into the plane), v across it, mirrored where needed to keep the development's orientation
    P = X[T]
    nrm = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    tan = np.stack([-np.sin(ph_c[:, 0]), np.cos(ph_c[:, 0]), np.zeros(len(T))], axis=1)
    e_u = tan - np.einsum("ij,ij->i", tan, nrm)[:, None] * nrm
    e_u /= np.linalg.norm(e_u, axis=1, keepdims=True)
    e_v = np.cross(nrm, e_u)
    D = P - P.mean(axis=1, keepdims=True)
    uv = np.stack([np.einsum("tkj,tj->tk", D, e_u), np.einsum("tkj,tj->tk", D, e_v)], axis=-1)

    def signed_area(q: np.ndarray) -> np.ndarray:
        a, b = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
        return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]

    mirror = np.sign(signed_area(uv)) != np.sign(signed_area(dev))
    uv[mirror, :, 1] *= -1.0
    # v down the slant, as in the development
    down = np.einsum("tk,tk->t", dev[:, :, 1] - dev[:, :, 1].mean(1, keepdims=True), uv[:, :, 1]) < 0
    uv[down] *= -1.0  # a half-turn keeps the orientation
    tags = {"waistband": np.arange(n_around), "hem": np.arange((n_down - 1) * n_around, n_down * n_around)}
    return ClothMesh(X, T, uv, tags, flat_rest_bend=flat_rest_bend)
