"""Candidate effects for a cloth (swatch) fit, as additive parameters with 0 = off.

The base model is the estimator's own (:mod:`vidsim.cloth`, the "fast" velocity-Verlet scheme)
driven by the *measured* corner paths of ``meta.yaml`` through the rig of
:mod:`vidsim.clothfit.film`, with the fit's estimated parameters free (stiffnesses in log units)
and the others at the fit's values. Each candidate of :data:`CLOTH_EFFECTS` adds a small block
of parameters; with every block at zero the extended model reproduces the base model.

Dynamics (what the simulator is given)::

    wind          w  (3, m/s)    steady uniform air velocity, world axes (the simulator's ``wind``)
    gravity_tilt  g  (2, -)      gravity direction (gx, gy, -1)/|.| x |g| (for a level fit; in
                                 general tilted from the fit's gravity, :func:`tilt_gravity`): a
                                 world frame (the calibration board) that is not level
    air_drag      d  (k, SI)     increments of the drag parameters the fit held fixed
                                 (drag_linear, drag_quad, drag_degrade; the value stays >= 0)
    damping       l  (k, -)      log-factors of the damping parameters the fit held fixed
                                 (bend, stretch and shear damping: value x exp(l))
    grip_slip     s  (2, m)      the fabric slides down through the left / right grip at a steady
                                 rate: true corner = measured - s (t - t_first)/(t_last - t_first) z
    anisotropic_stretch a (1, -) ln(warp / weft stretch stiffness) added to the fit's
                                 (``ClothParams.stretch_anisotropy``; the geometric mean stays the
                                 fit's ``stretch``), bounded to +-ANISO_BOUND so that the stiffer
                                 direction stays inside the fixed step's margin

Imaging and timing (the camera, not the motion; no re-simulation)::

    lens_k1         k1 (-)       radial distortion the calibration missed
    motion_blur     b  (s^2)     exposure^2: the silhouette is the mean of 3 renders spread
                                 evenly over sqrt(b) centred on the frame time (time variance
                                 b/6; a continuous exposure E has the same second moment at
                                 b = E^2/2, the twin's 5-sample one at 0.75 E^2; a one-sided
                                 exposure is this plus a time offset of half of it);
                                 ``blur_threshold`` segments it instead
                                 (rigid_model.segmented_blur; off by default here)
    rolling_shutter rs (s)       image row v is captured rs v / H after row 0
    time_offset     dt (s)       every frame is captured dt after the time the corner paths give
    time_rate       r  (-)       the frame clock runs fast: t -> t_first + (t - t_first)(1 + r)
    time_jitter     d_k (F, s)   one capture-time error per compared frame (``per_frame``): the
                                 diagnosis judges it as the rigid domain does (beyond an equally
                                 free placebo in the screen, by its training closure and the
                                 whiteness of its fitted errors, each held-out frame's own error
                                 fitted on that frame)

Not in the library, and why (stated, not hidden): strain-stiffening stretch (the simulator's
stretch is linear in the strain; the issue asks for anisotropic *or* strain-stiffening stretch, and
the anisotropic one is here); projector misalignment (it moves the stripes, not the silhouette this
model compares).
Stated alias: a grip that *lags* the measured path (the reality's ``grip_slip.lag``) is a
``time_offset`` of minus the lag for every frame after the motion started; ``grip_slip`` here is
the slow slide only.

Timing effects and blur sample the simulated trajectory between frames by cubic Hermite
interpolation of positions and velocities on the clip's frame grid (the simulation is run at every
clip frame), so they never change the simulation's steps. The simulation runs at a *fixed* step
(chosen once, from the stiffest mode of the starting parameters with a margin): the automatic
step is re-estimated per parameter set, which would make the trajectory jump with the parameters
and finite differences meaningless.

Silhouettes are *soft* (:func:`soft_coverage`): each projected triangle covers a pixel by the
product over its edges of ``clip(0.5 + d_e / ramp, 0, 1)`` (``d_e`` the signed distance to the
edge's line), the coverages are summed and clipped at 1, so interior edges vanish and the outline
has a ramp of ``ramp`` pixels. Units: SI; pixels at the
model's image scale unless a name says full resolution.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from vidsim.cloth import ClothParams, ClothStepError, simulate, stable_step
from vidsim.cloth.simulate import MULTIRATE_FRACTION, MULTIRATE_MAX
from vidsim.clothfit.film import swatch_driver, swatch_model_mesh
from vidsim.gap.rigid_model import EffectSpec, segmented_blur
from vidsim.video.camera import PinholeCamera

__all__ = ["ClothGapError", "ClothEffectSpec", "CLOTH_EFFECTS", "DRAG_NAMES", "DAMPING_NAMES", "ClothSetup",
           "ClothGapModel", "soft_coverage", "boundary_edges", "hermite", "tilt_gravity"]

DRAG_NAMES = ("drag_linear", "drag_quad", "drag_degrade")
DAMPING_NAMES = ("bend_damping", "stretch_damping", "shear_damping")
#: typical increment of each drag parameter (SI: N s/m^3, kg/m^3, s^2/m^2)
DRAG_SCALE = {"drag_linear": 0.2, "drag_quad": 0.3, "drag_degrade": 0.2}


class ClothGapError(ValueError):
    """Bad input to the cloth gap diagnosis (unknown effect, wrong shape); the message names it."""


@dataclass(frozen=True)
class ClothEffectSpec(EffectSpec):
    """One candidate effect: the rigid library's :class:`vidsim.gap.rigid_model.EffectSpec`
    (name, size, kind, scale, units, lower, alias, disp_power) plus the group's members.

    Attributes:
        size: number of parameters (-1: the fit's fixed members of a group; ignored when ``per_frame``).
        members: the cloth parameters a group effect frees (those the fit did not estimate).
        per_frame: one parameter per compared frame (time jitter).
    """

    members: tuple[str, ...] = ()
    per_frame: bool = False


#: |ln(warp/weft)| at most (a factor 1.9 on the stiffer direction's stiffness: the fixed step is
#: chosen for the starting stiffnesses doubled)
ANISO_BOUND = 1.3

CLOTH_EFFECTS: dict[str, ClothEffectSpec] = {e.name: e for e in (
    ClothEffectSpec("wind", 3, "dynamics", 0.3, "m/s"),
    ClothEffectSpec("gravity_tilt", 2, "dynamics", 0.02, "-"),
    ClothEffectSpec("air_drag", -1, "dynamics", 1.0, "SI (drag parameter units)", members=DRAG_NAMES),
    ClothEffectSpec("damping", -1, "dynamics", 0.5, "log-factor", members=DAMPING_NAMES),
    ClothEffectSpec("grip_slip", 2, "dynamics", 0.005, "m", 0.0),
    ClothEffectSpec("anisotropic_stretch", 1, "dynamics", 0.3, "ln(warp/weft)", -ANISO_BOUND),
    ClothEffectSpec("lens_k1", 1, "imaging", 0.01, "-"),
    ClothEffectSpec("motion_blur", 1, "imaging", 1e-4, "s^2", 0.0, disp_power=0.5),
    ClothEffectSpec("rolling_shutter", 1, "timing", 0.004, "s"),
    ClothEffectSpec("time_offset", 1, "timing", 0.005, "s"),
    ClothEffectSpec("time_rate", 1, "timing", 0.01, "-"),
    ClothEffectSpec("time_jitter", 0, "timing", 0.002, "s", per_frame=True),
)}

#: base parameters whose internal unit is the natural log (stiffnesses, dampings)
LOG_PARAMS = ("bend", "stretch", "shear", "bend_damping", "stretch_damping", "shear_damping")


# ----------------------------------------------------------------------------- soft silhouette
@njit(cache=True)
def _soft_frame(uv: np.ndarray, tris: np.ndarray, boundary: np.ndarray, H: int, W: int, ramp: float, bias: float,
                out: np.ndarray) -> None:
    inv = 1.0 / ramp
    for k in range(tris.shape[0]):
        a, b, c = tris[k, 0], tris[k, 1], tris[k, 2]
        ax, ay, bx, by, cx, cy = uv[a, 0], uv[a, 1], uv[b, 0], uv[b, 1], uv[c, 0], uv[c, 1]
        if not (np.isfinite(ax) and np.isfinite(bx) and np.isfinite(cx)):
            continue
        area2 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if abs(area2) < 1e-12:
            continue
        sgn = 1.0 if area2 > 0 else -1.0
        # inward unit normals of the three edges (ab, bc, ca) and offsets: d = n . p + o; the
        # outline offset moves the mesh's boundary edges only (interior seams stay complementary)
        ex = np.empty(3)
        ey = np.empty(3)
        eo = np.empty(3)
        px = (ax, bx, cx)
        py = (ay, by, cy)
        for e in range(3):
            x0, y0 = px[e], py[e]
            x1, y1 = px[(e + 1) % 3], py[(e + 1) % 3]
            dx, dy = x1 - x0, y1 - y0
            ln = np.sqrt(dx * dx + dy * dy)
            if ln < 1e-12:
                ln = 1e-12
            nx, ny = -dy * sgn / ln, dx * sgn / ln
            ex[e], ey[e], eo[e] = nx, ny, -(nx * x0 + ny * y0) + (bias if boundary[k, e] else 0.0)
        pad = 0.5 * ramp + abs(bias) + 1.0
        u0 = max(int(np.floor(min(ax, bx, cx) - pad)), 0)
        u1 = min(int(np.ceil(max(ax, bx, cx) + pad)), W - 1)
        v0 = max(int(np.floor(min(ay, by, cy) - pad)), 0)
        v1 = min(int(np.ceil(max(ay, by, cy) + pad)), H - 1)
        for v in range(v0, v1 + 1):
            for u in range(u0, u1 + 1):
                cov = 1.0
                for e in range(3):
                    f = 0.5 + (ex[e] * u + ey[e] * v + eo[e]) * inv
                    if f <= 0.0:
                        cov = 0.0
                        break
                    if f < 1.0:
                        cov *= f
                if cov > 0.0:
                    out[v, u] += cov


def boundary_edges(tris: np.ndarray) -> np.ndarray:
    """(M, 3) bool: edge ``(tris[k, e], tris[k, (e + 1) % 3])`` belongs to one triangle only."""
    t = np.asarray(tris, np.int64)
    e = np.stack([t, np.roll(t, -1, axis=1)], axis=-1).reshape(-1, 2)
    key = np.sort(e, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return (cnt[inv.ravel()] == 1).reshape(t.shape)


def soft_coverage(uv: np.ndarray, tris: np.ndarray, H: int, W: int, ramp: float = 1.0, bias: float = 0.0,
                  boundary: np.ndarray | None = None) -> np.ndarray:
    """Soft silhouette of a projected triangle mesh.

    Each triangle covers a pixel by the product over its edges of ``clip(0.5 + d_e / ramp, 0, 1)``
    (``d_e``: signed distance to the edge's line, > 0 inside; ``bias`` added on the mesh's
    boundary edges); the sum over triangles is clipped at 1. Two triangles sharing an edge have
    complementary factors there, so interior seams vanish, and a straight outline has a linear
    ramp of ``ramp`` pixels moved outward by ``bias`` (measured: a 12 x 12 swatch 50 px wide
    covers its area to 0.3 %). An earlier sum of per-triangle min-distance ramps over-covered by
    one to two pixels wherever an interior edge met the outline (5 % of the area of that swatch).
    Outlines formed by folds (interior edges seen edge-on) are not moved by ``bias``.

    Args:
        uv: (N, 2) projected vertices, pixels (NaN: behind the camera, its triangles are skipped).
        tris: (M, 3) triangles.
        H, W: image size; ramp: width of the outline's ramp, pixels; bias: outline offset, pixels
            (< 0 shrinks the silhouette: a segmentation that misses the outline's mixed pixels).
        boundary: (M, 3) boundary-edge flags (:func:`boundary_edges`; computed when None).

    Returns:
        (H, W) coverage in [0, 1].
    """
    out = np.zeros((int(H), int(W)))
    t = np.ascontiguousarray(tris, np.int64)
    bnd = boundary_edges(t) if boundary is None else np.ascontiguousarray(boundary, np.bool_)
    _soft_frame(np.ascontiguousarray(uv, float), t, bnd, int(H), int(W), float(ramp), float(bias), out)
    return np.minimum(out, 1.0)


def hermite(grid_t: np.ndarray, P: np.ndarray, V: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation of a trajectory sampled on ``grid_t`` (uniform or not).

    Args:
        grid_t: (G,) increasing sample times; P, V: (G, N, 3) positions and velocities there.
        q: (N,) query time per vertex (or a scalar for all), seconds; outside the grid the end
            intervals' cubics are extended.

    Returns:
        (N, 3) positions.
    """
    N = P.shape[1]
    qq = np.broadcast_to(np.asarray(q, float), (N,))
    j = np.clip(np.searchsorted(grid_t, qq, side="right") - 1, 0, len(grid_t) - 2)
    t0, t1 = grid_t[j], grid_t[j + 1]
    h = t1 - t0
    s = ((qq - t0) / h)[:, None]
    idx = np.arange(N)
    p0, p1 = P[j, idx], P[j + 1, idx]
    v0, v1 = V[j, idx] * h[:, None], V[j + 1, idx] * h[:, None]
    s2, s3 = s * s, s * s * s
    return (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * v0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * v1


def tilt_gravity(g0: tuple[float, float, float] | np.ndarray, gx: float, gy: float) -> tuple[float, float, float]:
    """Gravity ``g0`` tilted by the small slopes ``(gx, gy)``, its magnitude kept.

    The direction is ``normalise(g0/|g0| + gx e1 + gy e2)`` with ``e1`` the world x axis made
    perpendicular to ``g0`` and ``e2 = e1 x g0/|g0|``; for a level ``g0 = (0, 0, -g)`` this is
    ``(gx, gy, -1)/|.| g`` (the slopes are ``g_x / -g_z`` and ``g_y / -g_z``).

    Args:
        g0: (3,) the fit's gravity, m/s^2; gx, gy: slopes, dimensionless.

    Returns:
        (3,) tilted gravity, m/s^2.
    """
    g0 = np.asarray(g0, float)
    mag = float(np.linalg.norm(g0))
    gh = g0 / mag
    e1 = np.array([1.0, 0.0, 0.0]) - gh[0] * gh
    if np.linalg.norm(e1) < 1e-6:  # gravity along world x: use y instead
        e1 = np.array([0.0, 1.0, 0.0]) - gh[1] * gh
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(e1, gh)
    d = gh + float(gx) * e1 + float(gy) * e2
    return tuple(float(x) for x in mag * d / np.linalg.norm(d))


# ----------------------------------------------------------------------------- the model
@dataclass
class ClothSetup:
    """What the estimator knows about one swatch trial (never truth).

    Attributes:
        times: (T,) frame times of the whole clip (cloth frames), seconds.
        corner_paths: (T, 2, 3) measured corner positions, metres.
        obs: (F,) indices into ``times`` of the frames the residuals compare (e.g. every 2nd).
        camera: calibrated camera at full resolution.
        size: swatch side, metres; density: kg/m^2.
        resolution: model vertices per side; settle_s: rest before the first frame, seconds.
        settle_bath: viscous damping rate of the settle, 1/s (0: off; see
            :func:`vidsim.cloth.simulate`): the model then starts the clip from its equilibrium.
        multirate, damping: the fast scheme's bending multirate factor ("auto" or a whole number
            >= 1) and damping mode ("explicit", "split" or "auto"), as ``cloth.model`` gives them
            to the fit's objective (:func:`vidsim.cloth.simulate`); the defaults, 1 and "explicit",
            are plain velocity Verlet with the dampings as forces. The gap model resolves "auto"
            once, at its fixed step (:class:`ClothGapModel`), so that its refits see one scheme.
    """

    times: np.ndarray
    corner_paths: np.ndarray
    obs: np.ndarray
    camera: PinholeCamera
    size: float
    density: float
    resolution: int = 12
    settle_s: float = 0.5
    settle_bath: float = 0.0
    multirate: int | str = 1
    damping: str = "explicit"

    def __post_init__(self) -> None:
        if self.damping not in ("explicit", "split", "auto"):
            raise ClothGapError(f"damping must be 'explicit', 'split' or 'auto', got {self.damping!r}")
        mr = str(self.multirate).strip()
        if mr != "auto" and not (mr.isdigit() and int(mr) >= 1):
            raise ClothGapError(f"multirate must be 'auto' or a whole number >= 1, got {self.multirate!r}")
        self.multirate = "auto" if mr == "auto" else int(mr)
        self.times = np.asarray(self.times, float)
        self.corner_paths = np.asarray(self.corner_paths, float)
        self.obs = np.asarray(self.obs, int)
        T = self.times.size
        if self.times.ndim != 1 or T < 4 or np.any(np.diff(self.times) <= 0):
            raise ClothGapError(f"times must be >= 4 increasing frame times, got shape {self.times.shape}")
        if self.corner_paths.shape != (T, 2, 3) or not np.all(np.isfinite(self.corner_paths)):
            raise ClothGapError(f"corner_paths must be finite ({T}, 2, 3) metres, got {self.corner_paths.shape}")
        if self.obs.ndim != 1 or self.obs.size < 4 or self.obs.min() < 0 or self.obs.max() >= T:
            raise ClothGapError(f"obs must list >= 4 frame indices below {T}, got {self.obs.tolist()[:8]}...")
        if not (self.size > 0 and self.density > 0):
            raise ClothGapError(f"size and density must be > 0, got {self.size}, {self.density}")


class ClothGapModel:
    """The base cloth model plus a chosen set of candidate effects.

    Parameters are one flat vector ``[base, effect blocks in the order of effects]``; the base is
    the estimated names (stiffnesses and dampings as natural logs, drags in SI) followed by
    ``sil_bias``, the outline offset of the soft silhouette in pixels at the model's scale (a
    nuisance of the comparison: segmentation with a threshold misses part of the outline's mixed
    pixels; measured on twin footage at the true parameters: -0.37 px at half resolution).

    Args:
        setup: the trial as the estimator knows it.
        params0: the fit's complete parameters (the values of everything not estimated).
        estimated: names of the base parameters (the fit's estimated ones).
        effects: names from :data:`CLOTH_EFFECTS`.
        scale: image scale of the residuals; ramp: soft-silhouette ramp, pixels at that scale.
        dt: fixed simulation step, seconds (None: from the stiffest mode of ``params0`` with its
            stiffnesses and dampings doubled, times 0.9, under the setup's damping mode).

    The setup's "auto" settings are resolved here, once, on that doubled ``params0`` (a refit moves
    the parameters, and a scheme that switched with them would make the residuals jump):
    ``damping_mode`` is "split" where splitting the dampings off lengthens the step by more than
    :data:`vidsim.cloth.simulate.SPLIT_GAIN`, and ``multirate_r`` the largest factor whose outer
    step stays within ``MULTIRATE_FRACTION`` of the doubled bending's stable step, the rules
    :func:`vidsim.cloth.simulate` applies per run.
    """

    def __init__(self, setup: ClothSetup, params0: ClothParams, estimated: list[str] | tuple[str, ...],
                 effects: tuple[str, ...] | list[str] = (), scale: float = 0.5, ramp: float = 1.0,
                 dt: float | None = None) -> None:
        from vidsim.cloth import ESTIMATED_NAMES

        bad = [n for n in estimated if n not in ESTIMATED_NAMES]
        if bad or not estimated:
            raise ClothGapError(f"estimated parameters {list(estimated)} must be a non-empty subset of "
                                f"{list(ESTIMATED_NAMES)}")
        for e in effects:
            if e not in CLOTH_EFFECTS:
                raise ClothGapError(f"unknown effect {e!r}; the library has {sorted(CLOTH_EFFECTS)}")
        self.setup = setup
        self.params0 = params0
        self.estimated = tuple(estimated)
        self.effects = tuple(effects)
        #: segmentation threshold of the blur (:func:`vidsim.gap.rigid_model.segmented_blur`; None,
        #: the default in this domain: the plain mean coverage over the exposure)
        self.blur_threshold: float | None = None
        self.scale = float(scale)
        self.ramp = float(ramp)
        self.cam_full = setup.camera
        self.cam = setup.camera if scale == 1.0 else setup.camera.scaled(scale)
        self.mesh = swatch_model_mesh(setup.corner_paths[0], setup.resolution, setup.size)
        self.tris = np.ascontiguousarray(self.mesh.triangles, np.int64)
        self.boundary = boundary_edges(self.tris)
        self.slices: dict[str, slice] = {}
        self.n_est = len(self.estimated)
        k = self.n_est + 1
        for name in self.effects:
            n = self.effect_size(name)
            self.slices[name] = slice(k, k + n)
            k += n
        self.n_params = k
        self.n_base = self.n_est + 1
        big = params0.replace(**{n: 2.0 * getattr(params0, n) for n in ("bend", "stretch", "shear") + DAMPING_NAMES})
        driven = self.mesh.tags["top_corners"]
        self.damping_mode = setup.damping
        if dt is None or setup.damping == "auto":
            h, info = stable_step(self.mesh, big, driven=driven, safety=0.9, damping=setup.damping)
            self.damping_mode = str(info["damping"])
            dt = float(h) if dt is None else dt
        self.dt = float(dt)
        if setup.multirate == "auto":
            h_bend, _ = stable_step(self.mesh, big, driven=driven, forces="bending", safety=1.0,
                                    damping=self.damping_mode)
            self.multirate_r = int(max(1, min(MULTIRATE_MAX, math.floor(MULTIRATE_FRACTION * h_bend / self.dt))))
        else:
            self.multirate_r = int(setup.multirate)
        self._sim_cache: list[tuple[bytes, tuple]] = []
        self.n_sims = 0
        self._steps: np.ndarray | None = None

    # ------------------------------------------------------------------ parameters
    def members(self, name: str) -> tuple[str, ...]:
        """The cloth parameters a group effect frees (those not estimated by the fit)."""
        return tuple(m for m in CLOTH_EFFECTS[name].members if m not in self.estimated)

    def effect_size(self, name: str) -> int:
        """Number of parameters of effect ``name`` in this model (0: nothing left to free)."""
        if name not in CLOTH_EFFECTS:
            raise ClothGapError(f"unknown effect {name!r}; the library has {sorted(CLOTH_EFFECTS)}")
        if CLOTH_EFFECTS[name].per_frame:
            return int(self.setup.obs.size)
        s = CLOTH_EFFECTS[name].size
        return len(self.members(name)) if s < 0 else s

    def theta0(self) -> np.ndarray:
        """The base vector of ``params0`` with every effect at zero."""
        b = [np.log(getattr(self.params0, n)) if n in LOG_PARAMS else getattr(self.params0, n) for n in self.estimated]
        return np.r_[np.asarray(b, float), 0.0, np.zeros(self.n_params - self.n_base)]

    def get(self, theta: np.ndarray, name: str) -> np.ndarray:
        """Parameters of effect ``name`` in ``theta`` (zeros when the effect is not in the model)."""
        if name in self.slices:
            return np.asarray(theta[self.slices[name]], float)
        return np.zeros(self.effect_size(name))

    def x_scale(self) -> np.ndarray:
        """(n_params,) typical step of each parameter (optimiser scaling)."""
        s = [0.3 if n in LOG_PARAMS else DRAG_SCALE.get(n, 0.2) for n in self.estimated] + [0.2 * self.ramp]
        for name in self.effects:
            if name == "air_drag":
                s += [DRAG_SCALE[m] for m in self.members(name)]
            else:
                s += [CLOTH_EFFECTS[name].scale] * self.effect_size(name)
        return np.asarray(s, float)

    def lower(self) -> np.ndarray:
        """(n_params,) lower bounds (-inf where unbounded): drags >= 0."""
        lo = np.full(self.n_params, -np.inf)
        for i, n in enumerate(self.estimated):
            if n not in LOG_PARAMS:
                lo[i] = 0.0
        lo[self.n_est] = -self.ramp
        for name, sl in self.slices.items():
            if name == "air_drag":
                lo[sl] = [-getattr(self.params0, m) for m in self.members(name)]
            elif CLOTH_EFFECTS[name].lower is not None:
                lo[sl] = CLOTH_EFFECTS[name].lower
        return lo

    def upper(self) -> np.ndarray:
        """(n_params,) upper bounds (inf where unbounded): the silhouette bias <= ramp."""
        hi = np.full(self.n_params, np.inf)
        hi[self.n_est] = self.ramp
        if "anisotropic_stretch" in self.slices:
            hi[self.slices["anisotropic_stretch"]] = ANISO_BOUND
        return hi

    def params(self, theta: np.ndarray) -> ClothParams:
        """Complete :class:`ClothParams` of ``theta`` (dynamics effects applied)."""
        theta = np.asarray(theta, float)
        kw: dict = {}
        for i, n in enumerate(self.estimated):
            kw[n] = float(np.exp(theta[i])) if n in LOG_PARAMS else max(float(theta[i]), 0.0)
        if "air_drag" in self.slices:
            for m, d in zip(self.members("air_drag"), self.get(theta, "air_drag")):
                kw[m] = max(getattr(self.params0, m) + float(d), 0.0)
        if "damping" in self.slices:
            for m, lf in zip(self.members("damping"), self.get(theta, "damping")):
                kw[m] = getattr(self.params0, m) * float(np.exp(lf))
        if "anisotropic_stretch" in self.slices:
            a = float(self.get(theta, "anisotropic_stretch")[0])
            if a != 0.0:  # zero is off exactly
                kw["stretch_anisotropy"] = self.params0.stretch_anisotropy + a
        if "gravity_tilt" in self.slices:
            gx, gy = (float(x) for x in self.get(theta, "gravity_tilt"))
            if gx != 0.0 or gy != 0.0:  # zero is off exactly: the fit's gravity, bit for bit
                kw["gravity"] = tilt_gravity(self.params0.gravity, gx, gy)
        return self.params0.replace(**kw)

    def dynamics_key(self, theta: np.ndarray) -> bytes:
        """Bytes of the parameters the simulation depends on (the cache key)."""
        theta = np.asarray(theta, float)
        parts = [theta[: self.n_est]]
        for name, sl in self.slices.items():
            if CLOTH_EFFECTS[name].kind == "dynamics":
                parts.append(theta[sl])
        return np.concatenate(parts).tobytes()

    # ------------------------------------------------------------------ motion
    def corner_paths(self, theta: np.ndarray) -> np.ndarray:
        """(T, 2, 3) corner paths the model is driven by (measured, minus the grip slip)."""
        cp = self.setup.corner_paths.copy()
        s = self.get(theta, "grip_slip")
        if np.any(s):
            t = self.setup.times
            f = (t - t[0]) / (t[-1] - t[0])
            cp[:, :, 2] -= f[:, None] * np.asarray(s, float)[None, :]
        return cp

    def simulate(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
        """Positions and velocities (T, N, 3) at every clip frame, and an ok flag (cached)."""
        key = self.dynamics_key(theta)
        for k, v in self._sim_cache:
            if k == key:
                return v
        p = self.params(theta)
        drv, t0 = swatch_driver(self.mesh, self.setup.times, self.corner_paths(theta), self.setup.settle_s)
        wind = self.get(theta, "wind") if "wind" in self.slices else None
        self.n_sims += 1
        try:
            res = simulate(self.mesh, p, drv, self.setup.times, integrator="fast", t0=t0, dt=self.dt, wind=wind,
                           settle_bath=self.setup.settle_bath, multirate=self.multirate_r,
                           damping=self.damping_mode)
            out = (res.positions, res.velocities, bool(res.ok))
        except (ArithmeticError, ClothStepError):  # a numerical fault, or a set too stiff for the fixed step
            T, N = self.setup.times.size, self.mesh.n_vertices
            out = (np.full((T, N, 3), np.nan), np.full((T, N, 3), np.nan), False)
        self._sim_cache.append((key, out))
        if len(self._sim_cache) > 3:
            self._sim_cache.pop(0)
        return out

    def capture_times(self, theta: np.ndarray) -> np.ndarray:
        """(F,) capture times of the observed frames implied by the timing effects, seconds."""
        t = self.setup.times[self.setup.obs]
        t_first = self.setup.times[0]
        r = float(self.get(theta, "time_rate")[0])
        dt = float(self.get(theta, "time_offset")[0])
        jit = self.get(theta, "time_jitter")
        if r == 0.0 and dt == 0.0 and not np.any(jit):  # zero is off exactly: the frame times themselves
            return t.copy()
        return t_first + (t - t_first) * (1.0 + r) + dt + jit

    def _camera(self, theta: np.ndarray, full: bool = False) -> PinholeCamera:
        """The calibrated camera (at the model's scale, or ``full`` resolution) with the
        candidate lens distortion added to its k1 (the same camera object when k1 is zero)."""
        k1 = float(self.get(theta, "lens_k1")[0])
        c = self.cam_full if full else self.cam
        if k1 == 0.0:
            return c
        dist = np.array(c.dist, float)
        dist[0] += k1
        return PinholeCamera(c.K, c.R, c.t, c.width, c.height, dist)

    def camera_full(self, theta: np.ndarray) -> PinholeCamera:
        """The calibrated camera at full resolution with the candidate lens distortion added."""
        return self._camera(theta, full=True)

    def frame_vertices(self, theta: np.ndarray, frames: np.ndarray | None = None
                       ) -> tuple[list[list[np.ndarray]], bool]:
        """Per observed frame, the vertex sets to render (one, or one per exposure sample).

        Returns:
            ``(verts, ok)`` with ``verts[i]`` a list of (N, 3) world positions.
        """
        theta = np.asarray(theta, float)
        idx = np.arange(self.setup.obs.size) if frames is None else np.asarray(frames, int)
        P, V, ok = self.simulate(theta)
        if not ok:
            return [], False
        tc = self.capture_times(theta)[idx]
        b = float(self.get(theta, "motion_blur")[0])
        offs = np.linspace(-0.5, 0.5, 3) * np.sqrt(max(b, 0.0)) if b > 0 else np.zeros(1)
        rs = float(self.get(theta, "rolling_shutter")[0])
        g = self.setup.times
        obs_k = self.setup.obs[idx]
        cam = self._camera(theta)
        out = []
        for i, t in enumerate(tc):
            exact = t == g[obs_k[i]] and rs == 0.0
            samples = []
            for o in offs:
                if exact and o == 0.0:
                    samples.append(P[obs_k[i]])
                    continue
                q = np.full(P.shape[1], t + o)
                if rs != 0.0:
                    uv = cam.project(hermite(g, P, V, t + o))
                    q = q + rs * np.nan_to_num(uv[:, 1], nan=0.0) / cam.height
                samples.append(hermite(g, P, V, q))
            out.append(samples)
        return out, True

    def image_points(self, theta: np.ndarray) -> np.ndarray:
        """(F, N, 2) projected vertices of the observed frames (no blur), model scale (NaN: failed)."""
        verts, ok = self.frame_vertices(np.asarray(theta, float) * np.r_[np.ones(self.n_base), self._no_blur()])
        F, N = self.setup.obs.size, self.mesh.n_vertices
        if not ok:
            return np.full((F, N, 2), np.nan)
        cam = self._camera(theta)
        return np.stack([cam.project(v[0]) for v in verts])

    def image_speed(self, theta: np.ndarray) -> np.ndarray:
        """(F,) fastest vertex image speed of each observed frame at its capture time, pixels per
        second at the model's scale (0 where the simulation failed): how much a frame can say about
        its own capture time (a frame before the motion starts cannot)."""
        theta = np.asarray(theta, float)
        P, V, ok = self.simulate(theta)
        if not ok:
            return np.zeros(self.setup.obs.size)
        cam = self._camera(theta)
        g = self.setup.times
        out = np.zeros(self.setup.obs.size)
        for i, t in enumerate(self.capture_times(theta)):
            q = np.full(P.shape[1], t)
            d = cam.project(hermite(g, P, V, q + 1e-4)) - cam.project(hermite(g, P, V, q))
            out[i] = float(np.nanmax(np.linalg.norm(d, axis=1))) / 1e-4 if np.any(np.isfinite(d)) else 0.0
        return out

    def _no_blur(self) -> np.ndarray:
        m = np.ones(self.n_params - self.n_base)
        if "motion_blur" in self.slices:
            m[self.slices["motion_blur"].start - self.n_base] = 0.0
        return m

    def render(self, theta: np.ndarray, frames: np.ndarray | None = None, duv: np.ndarray | None = None
               ) -> tuple[np.ndarray, bool]:
        """Soft silhouettes (F, h, w) of the observed frames ``frames`` (indices into ``setup.obs``)
        at this model's scale, and an ok flag (False: the simulation diverged; images are zeros).
        ``duv``: optional (F, N, 2) image offsets of the vertices, pixels at this scale, added to
        every exposure sample of a frame (the time-jitter placebo's shift)."""
        idx = np.arange(self.setup.obs.size) if frames is None else np.asarray(frames, int)
        H, W = self.cam.height, self.cam.width
        verts, ok = self.frame_vertices(theta, idx)
        if not ok:
            return np.zeros((len(idx), H, W)), False
        cam = self._camera(theta)
        bias = float(np.asarray(theta, float)[self.n_est])
        out = np.zeros((len(idx), H, W))
        for i, samples in enumerate(verts):
            off = 0.0 if duv is None else np.asarray(duv[i], float)
            cov = [soft_coverage(cam.project(v) + off, self.tris, H, W, self.ramp, bias, self.boundary) for v in samples]
            out[i] = np.mean(cov, axis=0)
            if len(cov) > 1 and self.blur_threshold is not None:
                out[i] = segmented_blur(cov[len(cov) // 2], out[i], self.blur_threshold)
        return out, True

    def fd_steps(self, theta: np.ndarray, target_px: float, probe: float = 0.25) -> np.ndarray:
        """Finite-difference step of each parameter: ``probe`` x its scale, shrunk so that the
        largest vertex motion in the image is ``target_px`` (model scale); computed once and kept
        (one simulation per dynamics parameter). Blur keeps its probe step (second order)."""
        if self._steps is not None and len(self._steps) == self.n_params:
            return self._steps
        theta = np.asarray(theta, float)
        base = probe * self.x_scale()
        steps = base.copy()
        P0 = self.image_points(theta)
        if not np.all(np.isfinite(P0)):
            return steps
        steps[self.n_est] = target_px
        for j in range(self.n_params):
            name = next((n for n, sl in self.slices.items() if sl.start <= j < sl.stop), None)
            if j == self.n_est or (name is not None and CLOTH_EFFECTS[name].disp_power != 1.0):
                continue
            tp = theta.copy()
            tp[j] += base[j]
            d = np.linalg.norm(self.image_points(tp) - P0, axis=-1)
            dmax = float(np.nanmax(d)) if np.any(np.isfinite(d)) else np.inf
            # a perturbed run that failed (inf) keeps the typical-scale step: a zero step would make
            # every later Jacobian column NaN
            if np.isfinite(dmax) and dmax > target_px:
                steps[j] = base[j] * target_px / dmax
        self._steps = steps
        return steps
