"""Public cloth simulation API: a pure function of (mesh, params, driver, times).

>>> from vidsim.cloth import swatch, mid_range_params, DrivenVertices, simulate
>>> mesh = swatch(20, 20, 0.3, 0.3)
>>> drv = DrivenVertices.fixed(mesh.tags["top_corners"], mesh.rest_positions[mesh.tags["top_corners"]])
>>> res = simulate(mesh, mid_range_params(), drv, np.arange(50) / 30.0, integrator="fast")
>>> res.ok, res.positions.shape
(True, (50, 400, 3))

A diverging run never raises: :class:`SimResult` has ``ok=False`` and a ``failure``
text, its unreached frames are NaN, and :meth:`SimResult.penalty` gives the optimiser
a finite very bad score. Bad *inputs* raise :class:`ClothInputError` (a ValueError)
naming the field.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from vidsim.cloth.collision import (
    Colliders,
    build_edge_pairs,
    build_self_pairs,
    collider_forces,
    edge_collision_forces,
    self_collision_forces,
)
from vidsim.cloth.forces import bend_forces, bend_forces_quadratic, drag_forces, gravity_forces, stretch_shear_forces
from vidsim.cloth.integrate import (
    _DP_A,
    _DP_C,
    _DP_E,
    N_P,
    P_BATH,
    P_BATH_END,
    P_BEND,
    P_BENDQ,
    P_CELL,
    P_COLH,
    P_COLK,
    P_KDB,
    P_KDS,
    P_KDSH,
    P_KF,
    P_KN,
    P_KT,
    P_MARGIN,
    P_SELFH,
    P_SELFK,
    P_SELFON,
    P_SHEAR,
    P_STRETCH,
    P_STRETCH_V,
    STATUS_TEXT,
    _accel,
    _rk45_loop,
    _symplectic_loop,
)
from vidsim.cloth.mesh import ClothMesh
from vidsim.cloth.params import ClothParams

__all__ = [
    "ClothInputError",
    "ClothStepError",
    "DrivenVertices",
    "SimResult",
    "simulate",
    "compute_forces",
    "energies",
    "stable_step",
]


class ClothInputError(ValueError):
    """Invalid input to the cloth simulator (shapes, times, driver coverage, ...)."""


class ClothStepError(ClothInputError):
    """A step beyond what these parameters allow with a settle bath (a fixed ``dt``, or the stable
    step of stiff parameters times a strong bath): for a caller that sweeps parameters (a fit, the
    gap diagnosis), a failed run of that parameter set rather than a wrong input."""


@dataclass(frozen=True)
class DrivenVertices:
    """Vertices that follow a prescribed trajectory (pins are constant trajectories).

    Between samples the trajectory is a cubic Hermite curve through the sampled
    positions and velocities (velocities default to finite differences).

    Attributes:
        indices: (D,) vertex indices.
        times: (K,) increasing sample times [s].
        positions: (K, D, 3) [m].
        velocities: (K, D, 3) [m/s].
    """

    indices: np.ndarray
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None = None

    def __post_init__(self) -> None:
        idx = np.ascontiguousarray(np.asarray(self.indices, dtype=np.int64).ravel())
        t = np.ascontiguousarray(np.asarray(self.times, dtype=np.float64).ravel())
        K, D = t.shape[0], idx.shape[0]
        if len(np.unique(idx)) != D:
            raise ClothInputError(f"driven indices must be unique, got {idx.tolist()}")
        if K < 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise ClothInputError("driver times must be one or more finite, strictly increasing values [s]")
        p = np.asarray(self.positions, dtype=np.float64)
        if p.shape != (K, D, 3):
            raise ClothInputError(f"driver positions must have shape (K, D, 3) = {(K, D, 3)}, got {p.shape}")
        if not np.all(np.isfinite(p)):
            raise ClothInputError("driver positions must be finite [m]")
        if self.velocities is None:
            vel = np.gradient(p, t, axis=0) if K > 1 else np.zeros_like(p)
        else:
            vel = np.asarray(self.velocities, dtype=np.float64)
            if vel.shape != p.shape or not np.all(np.isfinite(vel)):
                raise ClothInputError(f"driver velocities must be finite with shape {p.shape}, got {vel.shape}")
        object.__setattr__(self, "indices", idx)
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "positions", np.ascontiguousarray(p))
        object.__setattr__(self, "velocities", np.ascontiguousarray(vel))

    @staticmethod
    def none() -> "DrivenVertices":
        """No driven vertex."""
        return DrivenVertices(np.zeros(0, dtype=np.int64), np.zeros(1), np.zeros((1, 0, 3)))

    @staticmethod
    def fixed(indices: np.ndarray, positions: np.ndarray) -> "DrivenVertices":
        """Pinned vertices: ``indices`` (D,) held at ``positions`` (D, 3) [m]."""
        positions = np.asarray(positions, dtype=float)
        return DrivenVertices(indices, np.zeros(1), positions.reshape(1, -1, 3))

    @staticmethod
    def from_function(indices: np.ndarray, fn, t0: float, t1: float, rate: float = 1000.0) -> "DrivenVertices":
        """Sample ``fn(t) -> (D, 3)`` [m] on [t0, t1] at ``rate`` Hz (velocities by finite differences)."""
        n = max(2, int(math.ceil((t1 - t0) * rate)) + 1)
        ts = np.linspace(t0, t1, n)
        return DrivenVertices(indices, ts, np.stack([np.asarray(fn(t), dtype=float) for t in ts]))

    def at(self, t: float) -> np.ndarray:
        """Positions [m] at time t [s], shape (D, 3)."""
        from vidsim.cloth.integrate import driver_state

        D = self.indices.shape[0]
        out = np.zeros((3, max(D, 1), 3))
        driver_state(float(t), self.times, self.positions, self.velocities, out[0], out[1], out[2])
        return out[0, :D].copy()


@dataclass
class SimResult:
    """Outcome of :func:`simulate`.

    Attributes:
        times: (T,) frame times [s].
        positions: (T, N, 3) positions at the frame times [m]; NaN after a failure.
        velocities: (T, N, 3) [m/s]; NaN after a failure.
        ok: True when all frames were reached without divergence.
        failure: None, or what went wrong (non-finite state, energy blow-up, step
            collapse, step budget exhausted) and at which time.
        frames_done: number of leading frames that are valid.
        steps: accepted steps. rejected: rejected steps (RK45). evaluations: force
            evaluations. wall_time: seconds. dt: the fixed step of the fast scheme [s]
            (or the mean accepted step of RK45).
        integrator: "rk45" or "fast".
    """

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    ok: bool
    failure: str | None
    frames_done: int
    steps: int
    rejected: int
    evaluations: int
    wall_time: float
    dt: float
    integrator: str
    stats: dict = field(default_factory=dict)

    def penalty(self, bad: float = 1e6) -> float:
        """A finite score for optimisers: 0 when ok, else ``bad`` scaled up by the missing fraction."""
        if self.ok:
            return 0.0
        missing = 1.0 - self.frames_done / max(1, len(self.times))
        return float(bad * (1.0 + missing))


#: Bending discretisations: "dihedral" (Baraff-Witkin: C = sqrt(c_e) theta; the default),
#: "quadratic" (Bergou et al. 2006: the same energy to O(theta^4) on a flat rest shape,
#: linear forces, ~3x cheaper), "auto" (quadratic when the bending rest shape is flat,
#: else dihedral). The default stays dihedral: vidsim.clothfit is validated with it (with
#: the quadratic model its 12-evaluation stretch recovery test lands 2.4x off, measured).
BENDING_MODELS = ("auto", "dihedral", "quadratic")
DEFAULT_BENDING = "dihedral"


def _bending(mesh: ClothMesh, bending: str) -> bool:
    """True for the quadratic model; validates the choice against the mesh."""
    if bending not in BENDING_MODELS:
        raise ClothInputError(f"bending must be one of {BENDING_MODELS}, got {bending!r}")
    flat = not np.any(mesh.bend_rest != 0.0)
    if bending == "auto":
        return flat
    if bending == "quadratic" and not flat:
        raise ClothInputError("bending='quadratic' needs a flat bending rest shape (flat_rest_bend=True); "
                              "use bending='dihedral' for a curved rest shape")
    return bending == "quadratic"


#: the fast scheme's recovery from an unstable step: halvings allowed (each restarts from t0)
FAST_MAX_HALVINGS = 4
#: multirate="auto": the bending's outer step is at most this fraction of the bending's own stable
#: step (accuracy, not stability, sets it), and at most MULTIRATE_MAX inner steps
MULTIRATE_FRACTION = 0.25
MULTIRATE_MAX = 4


#: how the Baraff-Witkin condition dampings are integrated by the "fast" scheme
DAMPING_MODES = ("explicit", "split", "auto")
#: damping="auto" splits the dampings when that lengthens the stable step by more than this factor:
#: a split step costs about 1.5x an explicit one (the membrane decay pass ~30 us on a 20x20 swatch
#: against ~60 us for the forces; benchmarks/bench_cloth_sim.py split)
SPLIT_GAIN = 1.5


def _check_damping(damping: str) -> None:
    if damping not in DAMPING_MODES:
        raise ClothInputError(f"damping must be one of {DAMPING_MODES}, got {damping!r}")


def _fast_with_retry(t0, x0, v0, times, model, P, drv, col, h, max_steps, v_max, max_halvings, r=1, split=False):
    """Velocity Verlet at step ``h``; when the state blows up, halve the step and start again from t0.

    The stable step is estimated once, at the initial state; a soft fabric that stretches far
    (strain 1.3-1.7 at the grips of a 30 N/m swatch) stiffens its shear and damping operators
    (they scale with |w|^2) beyond that estimate. Halving the step, at most ``max_halvings`` times
    (``FAST_MAX_HALVINGS`` for the automatic step; none when the caller fixed ``dt``), and
    simulating again from the start recovers those runs: the result is the run at the smaller step.
    (Until 5 Dec 2026 only the last 3 frames were rolled back; an instability that had grown for
    seconds before it tripped the speed limit stayed in the kept frames: an undamped swatch
    returned ok with 0.7 MgL of spurious energy, review.) Deterministic.

    ``r``: the multirate factor (bending kicks once per ``r`` steps; 1: plain velocity Verlet),
    kept through the halvings. ``split``: the dampings as exact per-condition decays (``damping="split"``).

    Returns:
        ``(positions, velocities, frames_done, status, steps, 0, evaluations, halvings, final h)``.
    """
    out, outv, done, status, steps, rej, nev = _symplectic_loop(t0, x0, v0, times, model, P, drv, col, h,
                                                                max_steps, v_max, r, split)
    halvings = 0
    while status in (1, 2) and halvings < max_halvings and steps < max_steps:
        h *= 0.5
        halvings += 1
        out, outv, done, status, s2, _, n2 = _symplectic_loop(t0, x0, v0, times, model, P, drv, col, h,
                                                              max_steps - steps, v_max, r, split)
        steps, nev = steps + s2, nev + n2
    return out, outv, done, status, steps, rej, nev, halvings, h


def _multirate(multirate: int | str, mesh: ClothMesh, params: ClothParams, x: np.ndarray, driver, h: float,
               bending: str, stats: dict, damping: str = "explicit") -> int:
    """The multirate factor r of :func:`simulate` (validated; "auto" from the bending's stable step)."""
    if isinstance(multirate, str):
        if multirate != "auto":
            raise ClothInputError(f"multirate must be a whole number >= 1 or 'auto', got {multirate!r}")
        h_bend, _ = stable_step(mesh, params, x, driven=driver.indices, bending=bending, forces="bending", safety=1.0,
                                damping=damping)
        r = int(max(1, min(MULTIRATE_MAX, math.floor(MULTIRATE_FRACTION * h_bend / h))))
        stats["h_bend_stable"] = h_bend
    else:
        if isinstance(multirate, bool) or int(multirate) != multirate or multirate < 1:
            raise ClothInputError(f"multirate must be a whole number >= 1 or 'auto', got {multirate!r}")
        r = int(multirate)
    stats["multirate"] = r
    return r


def _param_vector(mesh: ClothMesh, params: ClothParams, self_collision: bool, bending: str = DEFAULT_BENDING) -> np.ndarray:
    P = np.zeros(N_P)
    P[P_BENDQ] = 1.0 if _bending(mesh, bending) else 0.0
    P[P_BEND] = params.bend
    P[P_STRETCH] = params.stretch_warp
    P[P_STRETCH_V] = params.stretch_weft
    P[P_SHEAR] = params.shear
    P[P_KDB] = params.bend_damping
    P[P_KDS] = params.stretch_damping
    P[P_KDSH] = params.shear_damping
    P[P_KT] = params.drag_linear
    P[P_KN] = params.drag_quad
    P[P_KF] = params.drag_degrade
    P[P_COLK] = params.collision_stiffness
    P[P_COLH] = params.collision_thickness
    P[P_SELFK] = params.self_collision_stiffness
    P[P_SELFH] = params.self_collision_thickness
    P[P_SELFON] = 1.0 if self_collision else 0.0
    e = mesh.unique_edges()
    mean_edge = float(np.mean(np.linalg.norm(mesh.rest_positions[e[:, 0]] - mesh.rest_positions[e[:, 1]], axis=1)))
    h = params.self_collision_thickness
    P[P_CELL] = max(mean_edge, 4.0 * h)
    # Verlet-list margin: large enough to rebuild rarely, small enough that the in-plane
    # neighbours of a flat sheet (>= ~0.7 edge lengths away) stay out of the list
    P[P_MARGIN] = min(2.0 * h, max(0.25 * h, 0.7 * mesh.min_rest_edge() - h))
    return P


def _model(mesh: ClothMesh, params: ClothParams, wind: np.ndarray) -> tuple:
    mass = mesh.masses(params.density)
    return (
        mesh.triangles,
        mesh.tri_coef,
        mesh.tri_area,
        mesh.bend_edges,
        mesh.bend_coef,
        mesh.bend_rest,
        mass,
        mesh.vertex_area,
        np.asarray(params.gravity, dtype=np.float64),
        np.ascontiguousarray(wind, dtype=np.float64),
        mesh.unique_edges(),
        mesh.vertex_valence,
        mesh.tri_edge_share,
        mesh.bend_tris,
        np.zeros((mesh.n_triangles, 3)),
        mesh.bend_quad,
        1.0 / mass,
    )


def _col(colliders: Colliders) -> tuple:
    c = colliders
    return (c.times, c.sphere_centers, c.sphere_radii, c.capsule_a, c.capsule_b, c.capsule_radii)


def _drv(driver: DrivenVertices) -> tuple:
    return (driver.indices, driver.times, driver.positions, driver.velocities)


def _wind(wind: np.ndarray | None) -> np.ndarray:
    if wind is None:
        return np.zeros(3)
    w = np.asarray(wind, dtype=np.float64).ravel()
    if w.shape != (3,) or not np.all(np.isfinite(w)):
        raise ClothInputError(f"wind must be 3 finite numbers [m/s], got {wind!r}")
    return w


def compute_forces(
    mesh: ClothMesh,
    params: ClothParams,
    x: np.ndarray,
    v: np.ndarray,
    *,
    t: float = 0.0,
    colliders: Colliders | None = None,
    self_collision: bool = False,
    wind: np.ndarray | None = None,
    bending: str = DEFAULT_BENDING,
) -> np.ndarray:
    """Total force on every vertex [N], shape (N, 3), at positions x and velocities v.

    Driven vertices are not treated specially here (this is the raw force field).
    ``bending``: "auto", "dihedral" or "quadratic" (see :func:`simulate`).
    """
    colliders = colliders or Colliders.none()
    model = _model(mesh, params, _wind(wind))
    P = _param_vector(mesh, params, self_collision, bending)
    x = np.array(x, dtype=np.float64)
    v = np.array(v, dtype=np.float64)
    acc = np.zeros_like(x)
    f = np.zeros_like(x)
    drv = _drv(DrivenVertices.none())
    _accel(float(t), x, v, acc, f, model, P, drv, np.zeros((3, 1, 3)), _col(colliders),
           -np.ones((1, 2), dtype=np.int64), np.zeros((0, 2), dtype=np.int64), x.copy())
    return f


def energies(
    mesh: ClothMesh,
    params: ClothParams,
    x: np.ndarray,
    v: np.ndarray,
    *,
    t: float = 0.0,
    colliders: Colliders | None = None,
    self_collision: bool = False,
    bending: str = DEFAULT_BENDING,
) -> dict[str, float]:
    """Energy components [J] at (x, v): kinetic, stretch, shear, bend, gravity, collision,
    self_collision and their sum ``total`` (gravity relative to the origin).
    ``bending`` selects the bending energy as in :func:`simulate`."""
    colliders = colliders or Colliders.none()
    quad = _bending(mesh, bending)
    x = np.ascontiguousarray(x, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    mass = mesh.masses(params.density)
    f = np.zeros_like(x)
    z = np.zeros_like(v)
    est, esh = stretch_shear_forces(x, z, mesh.triangles, mesh.tri_coef, mesh.tri_area,
                                    params.stretch_warp, params.stretch_weft, params.shear, 0.0, 0.0, f)
    if quad:
        eb = bend_forces_quadratic(x, z, mesh.bend_edges, mesh.bend_quad, params.bend, 0.0, f)
    else:
        eb = bend_forces(x, z, mesh.bend_edges, mesh.bend_coef, mesh.bend_rest, params.bend, 0.0, f)
    eg = gravity_forces(x, mass, np.asarray(params.gravity), f)
    ec = collider_forces(float(t), x, mesh.vertex_area, *_col(colliders), params.collision_stiffness,
                         params.collision_thickness, f)
    es = 0.0
    if self_collision:
        h = params.self_collision_thickness
        pairs = build_self_pairs(x, mesh.triangles, h, _param_vector(mesh, params, True)[P_CELL])
        es = self_collision_forces(x, mesh.triangles, mesh.vertex_area, pairs, params.self_collision_stiffness, h, f,
                                   mesh.vertex_valence, mesh.tri_edge_share)
        ue = mesh.unique_edges()
        epairs = build_edge_pairs(x, ue, h, _param_vector(mesh, params, True)[P_CELL])
        es += edge_collision_forces(x, ue, mesh.vertex_area, epairs, params.self_collision_stiffness, h, f)
    ek = 0.5 * float(np.sum(mass * np.sum(v * v, axis=1)))
    out = {"kinetic": ek, "stretch": est, "shear": esh, "bend": eb, "gravity": eg, "collision": ec,
           "self_collision": es}
    out["total"] = float(sum(out.values()))
    return out


def stable_step(
    mesh: ClothMesh,
    params: ClothParams,
    x: np.ndarray | None = None,
    *,
    driven: np.ndarray | None = None,
    self_collision: bool = False,
    colliders: Colliders | None = None,
    safety: float = 0.9,
    iterations: int = 30,
    v_ref: float = 5.0,
    bending: str = DEFAULT_BENDING,
    forces: str = "all",
    damping: str = "explicit",
) -> tuple[float, dict[str, float]]:
    """Largest stable step [s] of the "fast" scheme (velocity Verlet), from the stiffest mode.

    omega_max^2 is the largest eigenvalue of M^-1 K (power iteration on finite
    differences of the elastic forces at ``x``), plus the contact stiffness k/density
    of the colliders (and twice that for self contact); c_max is the largest
    eigenvalue of M^-1 D (damping) plus the drag rates (k_T + 2 k_N v_ref)/density.
    The step solves omega^2 h^2 + 2 c h = 4 (stability of velocity Verlet for a damped
    oscillator), times ``safety``. ``forces="bending"``: the same for the bending forces alone
    (stiffness and damping; no stretch, shear, drag or contact), the slow part of the multirate
    scheme. ``damping="split"``: the stretch, shear and bending dampings are applied as decays after
    each step (:func:`simulate`'s ``damping``) and do not count; drag still does. ``"auto"``: split
    when that makes the step more than ``SPLIT_GAIN`` times longer.

    Returns:
        (h [s], {"omega_max": rad/s, "c_max": 1/s (the rate that limits h), "c_conditions": 1/s (the
        condition dampings'), "h_stable": s, "h_explicit": s, "h_split": s, "damping": the mode
        chosen, "explicit" or "split"}).
    """
    if forces not in ("all", "bending"):
        raise ClothInputError(f"stable_step forces must be 'all' or 'bending', got {forces!r}")
    _check_damping(damping)
    membrane = forces == "all"  # stretch, shear, their dampings, drag and contact
    if not membrane:
        colliders, self_collision = None, False
    x = mesh.rest_positions if x is None else np.asarray(x, dtype=np.float64)
    N = mesh.n_vertices
    mass = mesh.masses(params.density)
    quad = _bending(mesh, bending)
    free = np.ones(N, dtype=bool)
    if driven is not None and len(driven):
        free[np.asarray(driven)] = False
    rng = np.random.default_rng(0)
    scale = float(np.sqrt(np.mean(mesh.tri_area)))
    z = np.zeros((N, 3))

    def kforce(xx: np.ndarray) -> np.ndarray:
        f = np.zeros((N, 3))
        if membrane:
            stretch_shear_forces(xx, z, mesh.triangles, mesh.tri_coef, mesh.tri_area, params.stretch_warp,
                                 params.stretch_weft, params.shear, 0.0, 0.0, f)
        if quad:
            bend_forces_quadratic(xx, z, mesh.bend_edges, mesh.bend_quad, params.bend, 0.0, f)
        else:
            bend_forces(xx, z, mesh.bend_edges, mesh.bend_coef, mesh.bend_rest, params.bend, 0.0, f)
        return f

    def dforce(vv: np.ndarray) -> np.ndarray:
        f = np.zeros((N, 3))
        if membrane:
            stretch_shear_forces(x, vv, mesh.triangles, mesh.tri_coef, mesh.tri_area, 0.0, 0.0, 0.0,
                                 params.stretch_damping, params.shear_damping, f)
        if quad:  # the unprojected damping: an upper bound of the projected one's rate
            bend_forces_quadratic(x, vv, mesh.bend_edges, mesh.bend_quad, 0.0, params.bend_damping, f, False)
        else:
            bend_forces(x, vv, mesh.bend_edges, mesh.bend_coef, mesh.bend_rest, 0.0, params.bend_damping, f)
        return f

    def power(op) -> float:
        u = rng.standard_normal((N, 3))
        u[~free] = 0.0
        lam = 0.0
        for _ in range(iterations):
            nu = np.linalg.norm(u)
            if nu == 0:
                return 0.0
            u /= nu
            w = op(u) / mass[:, None]
            w[~free] = 0.0
            lam = float(np.sum(u * w))
            u = w
        return abs(lam) * 1.05  # power iteration underestimates; small margin

    eps = 1e-7 * scale
    omega2 = power(lambda u: -(kforce(x + eps * u) - kforce(x - eps * u)) / (2 * eps))
    c_cond = power(lambda u: -dforce(u))  # the Baraff-Witkin condition dampings
    cols = colliders or Colliders.none()
    if not cols.empty:
        omega2 += params.collision_stiffness / params.density
    if self_collision:
        omega2 += 2.0 * params.self_collision_stiffness / params.density
    c_drag = (params.drag_linear + 2.0 * params.drag_quad * v_ref) / params.density if membrane else 0.0
    h_explicit = _verlet_limit(omega2, c_cond + c_drag)
    h_split = _verlet_limit(omega2, c_drag)
    split = damping == "split" or (damping == "auto" and h_split > SPLIT_GAIN * h_explicit)
    h = h_split if split else h_explicit
    return safety * h, {"omega_max": math.sqrt(max(omega2, 0.0)), "c_max": c_drag + (0.0 if split else c_cond),
                        "c_conditions": c_cond, "h_stable": h, "h_explicit": h_explicit, "h_split": h_split,
                        "damping": "split" if split else "explicit"}


def _verlet_limit(omega2: float, damp: float) -> float:
    """Largest stable velocity-Verlet step of a damped oscillator: omega^2 h^2 + 2 c h = 4."""
    if omega2 <= 0:
        return 4.0 / max(2 * damp, 1e-9)
    return (-damp + math.sqrt(damp * damp + 4.0 * omega2)) / omega2


def simulate(
    mesh: ClothMesh,
    params: ClothParams,
    driver: DrivenVertices | None,
    times: np.ndarray,
    *,
    integrator: Literal["rk45", "fast"] = "rk45",
    x0: np.ndarray | None = None,
    v0: np.ndarray | None = None,
    t0: float | None = None,
    colliders: Colliders | None = None,
    self_collision: bool = False,
    wind: np.ndarray | None = None,
    rtol: float = 1e-5,
    atol_x: float = 1e-6,
    atol_v: float = 1e-5,
    safety: float = 0.9,
    dt: float | None = None,
    max_steps: int = 2_000_000,
    v_max: float = 100.0,
    bending: str = DEFAULT_BENDING,
    settle_bath: float = 0.0,
    bath_until: float | None = None,
    multirate: int | str = 1,
    damping: str = "explicit",
) -> SimResult:
    """Simulate the cloth and return its state at the requested frame times.

    Args:
        mesh: the cloth mesh (rest state).
        params: physical parameters (SI).
        driver: driven/pinned vertices (None: all free). Must cover [t0, times[-1]].
        times: (T,) increasing frame times [s], e.g. ``np.arange(50) / 30``.
        integrator: "rk45" (adaptive Dormand-Prince, reference) or "fast"
            (velocity Verlet, symplectic, at the stiffest-mode step).
        x0, v0: (N, 3) initial positions [m] / velocities [m/s] (default: rest, zero).
        t0: time of the initial state [s] (default ``times[0]``).
        colliders: kinematic spheres/capsules (default none).
        self_collision: enable cloth self repulsion.
        wind: (3,) uniform air velocity [m/s] (hook for a wind field).
        rtol, atol_x [m], atol_v [m/s]: RK45 error tolerances. The step is set by
            stability, not accuracy, so tight defaults cost about 2 % more than rtol 1e-3
            but keep the energy honest: Dormand-Prince amplifies undamped oscillations
            slightly, and with rtol 1e-3 the released-swing energy grew by 57 %/s
            (benchmarks/bench_cloth_sim.py damping), with 1e-5 by 0.003 %/s.
        safety: fraction of the stable step used by "fast".
        dt: override of the "fast" step [s] (used as given; the automatic step instead rolls back
            and halves itself when a strongly stretched soft fabric outgrows it, see
            ``stats["dt_halvings"]``).
        max_steps: step budget (failure when exhausted).
        v_max: a vertex faster than this [m/s] counts as a blow-up.
        bending: "dihedral" (default: the Baraff-Witkin dihedral-angle condition),
            "quadratic" (Bergou et al. 2006 isometric bending: same energy to O(theta^4) on
            a flat rest shape, constant Hessian, a 3x cheaper bending force; flat rest
            shapes only), or "auto" (quadratic on a flat bending rest shape, dihedral
            otherwise). The same ``bend`` [N m] in all. See docs/cloth_parameters.md.
        settle_bath: viscous damping rate [1/s] applied to every free vertex (a = ... - c v)
            while t < ``bath_until``: a preparation that brings a swatch hanging from its grips to
            rest before the filmed motion starts (dynamic relaxation), so that the state at frame 0
            is the static equilibrium of the parameters rather than a phase of a swing that depends
            on them and on the settle's length. 0 (default): off.
        bath_until: end of the bath [s] (default ``times[0]``).
        multirate: ("fast" only) the bending forces kick the velocities once per ``multirate``
            steps (impulse multirate, r-RESPA), the other forces every step: on a stiff fabric
            the stable step is set by stretch, whose modes are ~30x faster than bending's, and
            the dihedral bending is about half of a step's cost. 1 (default): plain velocity
            Verlet. "auto": the largest r <= ``MULTIRATE_MAX`` whose outer step stays within
            ``MULTIRATE_FRACTION`` of the bending's own stable step (1 on soft fabrics).
            Recorded in ``stats["multirate"]``. See docs/cloth_parameters.md.
        damping: ("fast" only) "explicit" (default): the stretch, shear and bending dampings are
            forces like the others, and the step must resolve the fastest damping rate (on a light,
            strongly damped fabric they, not the stiffnesses, set the step: up to 2x more steps).
            "split": they are applied after each step as per-condition decays
            (:func:`vidsim.cloth.forces.damping_sweep`, dissipative and stable for any step), so
            only the stiffnesses and the drag set the step; a step costs about 1.5x more.
            "auto": split when the step grows by more than ``SPLIT_GAIN``. The same damping
            forces; split differs from explicit by a splitting error that vanishes with the step.
            The mode used is ``stats["damping"]``. ``rk45`` integrates the dampings as forces
            ("auto" means explicit there; "split" is refused).

    Returns:
        :class:`SimResult`; never raises for a diverging simulation.

    Raises:
        ClothInputError: malformed times, initial state, driver or options.
    """
    t_wall = time.perf_counter()
    if integrator not in ("rk45", "fast"):
        raise ClothInputError(f"integrator must be 'rk45' or 'fast', got {integrator!r}")
    _check_damping(damping)
    if damping == "split" and integrator != "fast":  # "auto" is explicit under rk45
        raise ClothInputError("damping='split' needs integrator='fast' (rk45 integrates the dampings as forces)")
    times = np.ascontiguousarray(np.asarray(times, dtype=np.float64).ravel())
    if times.size == 0 or not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0):
        raise ClothInputError("times must be one or more finite, strictly increasing frame times [s]")
    t0 = float(times[0]) if t0 is None else float(t0)
    if not math.isfinite(t0) or t0 > times[0]:
        raise ClothInputError(f"t0 must be finite and <= times[0] = {times[0]}, got {t0}")
    N = mesh.n_vertices
    x = mesh.rest_positions.copy() if x0 is None else np.array(x0, dtype=np.float64)
    v = np.zeros((N, 3)) if v0 is None else np.array(v0, dtype=np.float64)
    for name, arr in (("x0", x), ("v0", v)):
        if arr.shape != (N, 3) or not np.all(np.isfinite(arr)):
            raise ClothInputError(f"{name} must be finite with shape {(N, 3)}, got {arr.shape}")
    driver = driver if driver is not None else DrivenVertices.none()
    if driver.indices.size and (driver.indices.min() < 0 or driver.indices.max() >= N):
        raise ClothInputError(f"driver indices must lie in [0, {N}), got {driver.indices.tolist()}")
    if driver.times.size > 1 and (driver.times[0] > t0 + 1e-9 or driver.times[-1] < times[-1] - 1e-9):
        raise ClothInputError(
            f"driver covers [{driver.times[0]}, {driver.times[-1]}] s but the simulation needs [{t0}, {times[-1]}] s"
        )
    colliders = colliders or Colliders.none()
    w = _wind(wind)
    for name, val in (("rtol", rtol), ("atol_x", atol_x), ("atol_v", atol_v), ("safety", safety), ("v_max", v_max)):
        if not (val > 0 and math.isfinite(val)):
            raise ClothInputError(f"{name} must be a positive finite number, got {val!r}")
    if self_collision:
        h = params.self_collision_thickness
        P0 = _param_vector(mesh, params, True)
        rest_pairs = build_self_pairs(mesh.rest_positions, mesh.triangles, h, P0[P_CELL])
        rest_epairs = build_edge_pairs(mesh.rest_positions, mesh.unique_edges(), h, P0[P_CELL])
        if rest_pairs.shape[0] or rest_epairs.shape[0]:
            raise ClothInputError(
                f"self_collision_thickness {h} m is too large for this mesh: {rest_pairs.shape[0]} "
                f"vertex-triangle and {rest_epairs.shape[0]} edge-edge pairs already touch at rest (shortest edge {mesh.min_rest_edge():.4g} m)"
            )
    if not (math.isfinite(settle_bath) and settle_bath >= 0):
        raise ClothInputError(f"settle_bath must be a finite damping rate >= 0 [1/s], got {settle_bath!r}")
    if bath_until is not None and not math.isfinite(bath_until):
        raise ClothInputError(f"bath_until must be a finite time [s] (or None: times[0]), got {bath_until!r}")
    model = _model(mesh, params, w)
    P = _param_vector(mesh, params, self_collision, bending)
    P[P_BATH] = float(settle_bath)
    P[P_BATH_END] = float(times[0]) if bath_until is None else float(bath_until)
    drv = _drv(driver)
    col = _col(colliders)
    free = np.ones(N, dtype=np.bool_)
    free[driver.indices] = False
    stats: dict = {}
    if integrator == "fast":
        mode = damping
        if dt is not None and not (dt > 0 and math.isfinite(dt)):
            raise ClothInputError(f"dt must be a positive finite step [s], got {dt!r}")
        if dt is None or damping == "auto" or settle_bath > 0:
            h_auto, info = stable_step(mesh, params, x, driven=driver.indices, self_collision=self_collision,
                                       colliders=colliders, safety=safety, bending=bending, damping=damping)
            stats.update(info)
            mode = info["damping"] if (dt is None or damping == "auto") else damping
            if settle_bath > 0:
                # the bath is one more damping rate: velocity Verlet needs omega^2 h^2 + 2 (c + bath) h <= 4
                h_bath = _verlet_limit(info["omega_max"] ** 2, info["c_max"] + settle_bath)
                stats["h_stable_with_bath"] = h_bath
                if dt is None:
                    h_auto = min(h_auto, safety * h_bath)
                elif float(dt) > h_bath:
                    raise ClothStepError(f"settle_bath {settle_bath} 1/s is too strong for the fixed step dt = {dt:.3g} s "
                                          f"(velocity Verlet with the bath is stable up to {h_bath:.3g} s)")
        dt_used = h_auto if dt is None else float(dt)
        stats["damping"] = mode
        r = _multirate(multirate, mesh, params, x, driver, dt_used, bending, stats, mode)
        if settle_bath * dt_used > 0.5:
            # the step depends on the parameters: for an optimiser sweeping them, a failed run of this set
            raise ClothStepError(f"settle_bath {settle_bath} 1/s is too strong for the step {dt_used:.3g} s "
                                  f"(explicit damping needs settle_bath * dt <= 0.5)")
        out, outv, done, status, steps, rej, nev, halvings, dt_used = _fast_with_retry(
            t0, x, v, times, model, P, drv, col, dt_used, int(max_steps), float(v_max),
            FAST_MAX_HALVINGS if dt is None else 0, r, mode == "split")
        stats["dt_halvings"] = halvings
    else:
        span = max(times[-1] - t0, 1e-6)
        h_init = min(1e-4, span)
        out, outv, done, status, steps, rej, nev = _rk45_loop(
            t0, x, v, times, model, P, drv, col, free, float(rtol), float(atol_x), float(atol_v), h_init,
            1e-10 * max(span, 1.0), int(max_steps), float(v_max), _DP_A, _DP_C, _DP_E)
        dt_used = span * (done / len(times)) / max(steps, 1)
    failure = None
    if status != 0:
        t_fail = times[done] if done < len(times) else times[-1]
        failure = f"{STATUS_TEXT[int(status)]} before t = {t_fail:.4g} s (frame {done})"
    return SimResult(
        times=times,
        positions=out,
        velocities=outv,
        ok=status == 0,
        failure=failure,
        frames_done=int(done),
        steps=int(steps),
        rejected=int(rej),
        evaluations=int(nev),
        wall_time=time.perf_counter() - t_wall,
        dt=float(dt_used),
        integrator=integrator,
        stats=stats,
    )
