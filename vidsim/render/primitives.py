"""Small triangle meshes for tests, benchmarks and examples (pure geometry, metres).

Every function returns ``(V, F)``: (N, 3) float64 vertices and (M, 3) int64 triangles with
outward (counter-clockwise seen from outside) winding for closed shapes.
"""

from __future__ import annotations

import numpy as np

__all__ = ["box", "icosphere", "grid_sheet", "t_shape", "merge", "transform"]


def box(size: tuple[float, float, float] = (1.0, 1.0, 1.0), center: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned box with edge lengths ``size`` (metres) centred at ``center``: 8 vertices, 12 triangles."""
    s = np.asarray(size, float) / 2.0
    if s.shape != (3,) or np.any(s <= 0):
        raise ValueError(f"box: 'size' must be three positive lengths, got {size!r}")
    c = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    V = c * s + np.asarray(center, float)
    # vertex index = 4*(x>0) + 2*(y>0) + (z>0)
    F = np.array([
        [0, 1, 3], [0, 3, 2],  # -x
        [4, 6, 7], [4, 7, 5],  # +x
        [0, 4, 5], [0, 5, 1],  # -y
        [2, 3, 7], [2, 7, 6],  # +y
        [0, 2, 6], [0, 6, 4],  # -z
        [1, 5, 7], [1, 7, 3],  # +z
    ], dtype=np.int64)
    return V, F


def icosphere(radius: float = 1.0, subdivisions: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Sphere of ``radius`` metres from a subdivided icosahedron: 20 * 4**subdivisions triangles."""
    if radius <= 0 or subdivisions < 0 or int(subdivisions) != subdivisions:
        raise ValueError(f"icosphere: need radius > 0 and integer subdivisions >= 0, got {radius}, {subdivisions}")
    p = (1 + 5 ** 0.5) / 2
    V = [[-1, p, 0], [1, p, 0], [-1, -p, 0], [1, -p, 0], [0, -1, p], [0, 1, p], [0, -1, -p], [0, 1, -p],
         [p, 0, -1], [p, 0, 1], [-p, 0, -1], [-p, 0, 1]]
    F = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
         [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11],
         [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    V = [np.array(v, float) / np.linalg.norm(v) for v in V]
    for _ in range(int(subdivisions)):
        cache: dict[tuple[int, int], int] = {}

        def mid(a: int, b: int) -> int:
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = V[a] + V[b]
                V.append(m / np.linalg.norm(m))
                cache[key] = len(V) - 1
            return cache[key]

        F2 = []
        for a, b, c in F:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            F2 += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        F = F2
    return np.array(V) * radius, np.array(F, dtype=np.int64)


def grid_sheet(nx: int, ny: int, size: tuple[float, float] = (1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Flat rectangular sheet in the z = 0 plane, ``nx`` x ``ny`` vertices (row-major, x fastest),
    centred at the origin, ``2 (nx - 1)(ny - 1)`` triangles (a cloth swatch)."""
    if nx < 2 or ny < 2:
        raise ValueError(f"grid_sheet: need nx, ny >= 2, got {nx}, {ny}")
    x = np.linspace(-size[0] / 2, size[0] / 2, nx)
    y = np.linspace(-size[1] / 2, size[1] / 2, ny)
    X, Y = np.meshgrid(x, y)
    V = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    i, j = np.meshgrid(np.arange(ny - 1), np.arange(nx - 1), indexing="ij")
    a = (i * nx + j).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + nx + 1], 1), np.stack([a, a + nx + 1, a + nx], 1)])
    return V, F.astype(np.int64)


def merge(*meshes: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate meshes into one (faces re-indexed)."""
    Vs, Fs, off = [], [], 0
    for V, F in meshes:
        Vs.append(np.asarray(V, float))
        Fs.append(np.asarray(F, np.int64) + off)
        off += len(V)
    return np.vstack(Vs), np.vstack(Fs)


def t_shape(bar: tuple[float, float, float] = (0.6, 0.15, 0.15), stem: tuple[float, float, float] = (0.15, 0.15, 0.5)) -> tuple[np.ndarray, np.ndarray]:
    """A 'T' of two boxes (a horizontal bar on top of a vertical stem along +z), centred near the origin."""
    top = box(bar, (0.0, 0.0, stem[2] / 2 + bar[2] / 2))
    return merge(top, box(stem, (0.0, 0.0, 0.0)))


def transform(V: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Rigidly move vertices: ``V @ R.T + t`` for (N, 3) V, (3, 3) R, (3,) t (metres)."""
    return np.asarray(V, float) @ np.asarray(R, float).T + np.asarray(t, float)
