"""Estimate a thrown rigid body's initial state and gravity direction from silhouettes (seed sec. 3.3).

Objective: the smoothed silhouette mismatch of :mod:`vidsim.rigid.silhouette` summed over frames
(seed eq. 5), per frame normalised to full-resolution pixels. Gradient: the seed's hybrid rule
``dE/dp = sum_k dE_k/dpose_k * dpose_k/dp`` (eq. 7), with ``dpose/dp`` from the variational
equations (:mod:`vidsim.rigid.dynamics`) and ``dE_k/dpose_k`` by image-space finite differences.
The descent is L-BFGS (a quasi-Newton gradient method) on scaled parameters.

What makes it robust where the seed was fragile:

* multi-start over orientation: the guess composed with the 60 rotations of the icosahedral group
  (reduced modulo the body's own symmetries), so some start lies within 44.5 degrees of the truth
  whatever the initial orientation error (the group's covering radius, 44.48 degrees found by
  maximising the distance to the nearest start; the worst of 4000 random orientations was 43.6);
* coarse-to-fine in time (first frames only, then all) and in space (image pyramid);
* a distance-transform term that attracts disjoint silhouettes (zero at the finest level);
* an explicit report of distinct solutions whose silhouettes explain the footage equally well.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import cv2
import numpy as np
from scipy.optimize import minimize

from vidsim.rigid.body import BoxBody, RigidBodyError
from vidsim.rigid.dynamics import (
    G_EARTH,
    N_PARAM,
    T0_TOL,
    pose_tangent_jacobian,
    quat_exp,
    quat_mul,
    quat_to_rot,
    rot_to_quat,
    rotation_angle_deg,
    simulate,
)
from vidsim.rigid.silhouette import render_coverage, sequence_costs, weight_maps
from vidsim.video.camera import PinholeCamera

FIT_VERSION = 1
"""Version of the fit's numerics (dynamics, silhouette metric, stage schedule semantics): part of a
checkpoint's context, so bump it when a change makes earlier stage results invalid."""

FAIL_COST = 1e9
"""Objective value of a diverged simulation (a very bad score, never an exception or a NaN)."""

PARAM_SCALE = np.array([0.01] * 3 + [0.02] * 3 + [0.05] * 3 + [0.2] * 3 + [0.005] * 2)
"""Typical size of a parameter step (m, rad, m/s, rad/s, rad): the optimiser's variable scaling."""


@dataclass
class Stage:
    """One step of the coarse-to-fine schedule.

    Attributes:
        scale: image scale of this level (1 = full resolution).
        frames: number of leading frames used (None: all).
        maxiter: L-BFGS iterations.
        lam: strength of the distance-transform term.
        ramp: anti-aliasing ramp, pixels at this level.
    """

    scale: float
    frames: int | None
    maxiter: int
    lam: float
    ramp: float = 1.0


@dataclass
class FitConfig:
    """Optimiser settings (Hydra-friendly plain fields).

    Attributes:
        screen: stages run for the starts (cheap: coarse, early frames).
        screen_keep: after screen stage ``i`` only the ``screen_keep[i]`` best starts go on; the
            last entry is the number of candidates that are refined.
        refine: stages run for the surviving candidates.
        final: full-resolution polish, run for the candidates whose cost after ``refine`` is
            within ``final_ratio`` times the best.
        multistart: "icosahedral" (60 orientations around the guess) or "none" (the guess only).
        hmax: RK4 step bound, seconds.
        distinct_deg: two solutions are distinct when their orientations (modulo symmetry) differ
            by more than this at any fitted frame, degrees.
        tie_iou: and "equally good" when their mean IoUs differ by less than this.
        dist_scale: distance normaliser of the smoothed term, full-resolution pixels.
        gravity: known gravity magnitude, m/s^2 (the footage's ``meta.gravity_magnitude``).
    """

    screen: list[Stage] = field(default_factory=lambda: [
        Stage(0.25, 10, 20, 1.0, 1.0), Stage(0.25, 20, 25, 1.0, 1.0)])
    screen_keep: list[int] = field(default_factory=lambda: [8, 3])
    refine: list[Stage] = field(default_factory=lambda: [
        Stage(0.25, None, 30, 1.0, 1.0), Stage(0.5, None, 40, 0.3, 1.0)])
    final: list[Stage] = field(default_factory=lambda: [Stage(1.0, None, 60, 0.0, 1.0)])
    final_ratio: float = 1.3
    multistart: str = "icosahedral"
    hmax: float = 1.0 / 60.0
    distinct_deg: float = 10.0
    tie_iou: float = 0.01
    dist_scale: float = 20.0
    gravity: float = G_EARTH

    @classmethod
    def from_dict(cls, d: dict | None) -> "FitConfig":
        """Build from a plain mapping (e.g. a Hydra node); unknown keys are an error."""
        cfg = cls()
        if not d:
            return cfg
        for k, v in d.items():
            if not hasattr(cfg, k):
                raise RigidBodyError(f"fit config: unknown field '{k}' (known: {sorted(vars(cfg))})")
            if k in ("screen", "refine", "final"):
                v = [s if isinstance(s, Stage) else Stage(**s) for s in v]
            setattr(cfg, k, v)
        if len(cfg.screen_keep) != len(cfg.screen) or min(cfg.screen_keep, default=1) < 1:
            raise RigidBodyError(f"fit config: 'screen_keep' {cfg.screen_keep} needs one count >= 1 per screen stage")
        if cfg.multistart not in ("icosahedral", "none"):
            raise RigidBodyError(f"fit config: 'multistart' must be 'icosahedral' or 'none', got {cfg.multistart!r}")
        if not (np.isfinite(cfg.gravity) and cfg.gravity > 0):
            raise RigidBodyError(f"fit config: 'gravity' must be a finite magnitude > 0 m/s^2, got {cfg.gravity}")
        return cfg


@dataclass
class Candidate:
    """One optimised start.

    Attributes:
        params: (14,) parameters with the rotation part folded into ``q_base`` (so it is zero).
        q_base: (4,) initial orientation quaternion.
        cost: final objective (mean smoothed mismatch per frame, full-resolution pixels).
        mean_iou: mean silhouette IoU over fitted frames (full resolution, hard silhouettes).
        iou: (T,) per-frame IoU.
        history: objective after each iteration, all stages concatenated.
        start: index of the multi-start orientation.
    """

    params: np.ndarray
    q_base: np.ndarray
    cost: float
    mean_iou: float
    iou: np.ndarray
    history: list[float]
    start: int


@dataclass
class FitResult:
    """Estimate of a throw.

    Attributes:
        params: (14,) best parameters ``[X0, 0, 0, 0, V0, W0 (world), tilt, roll]``, all in the
            camera's world frame (see :func:`fit_throw`).
        q0: (4,) best initial orientation quaternion (w, x, y, z), body -> world frame (the
            calibration's world frame; the camera's axes when the calibration has R = I, t = 0).
        t0: time of the initial state, seconds.
        times: (T,) fitted frame times, seconds; frames: (T,) their indices in the footage.
        states: (T, 13) simulated states at those times.
        iou: (T,) per-frame IoU of the best fit; mean_iou its mean.
        history: objective per iteration of the best start.
        alternatives: the other refined candidates, best first.
        ambiguous: True when a distinct candidate explains the silhouettes as well (within
            ``tie_iou``): the footage does not decide between them (seed Figure 2, row c). None
            when fewer than two candidates were refined (``multistart="none"`` or a last
            ``screen_keep`` of 1): nothing was compared, so the fit cannot say.
        seconds: wall time of the whole estimation.
        n_starts: number of starts screened.
        distinct: indices into ``alternatives`` of the distinct, equally good solutions.
        gravity: gravity magnitude the fit assumed, m/s^2; hmax: its RK4 step bound, seconds.
        replayed_stages: stages taken from the checkpoint of a killed run (0: none, or no checkpoint).
    """

    params: np.ndarray
    q0: np.ndarray
    t0: float
    times: np.ndarray
    frames: np.ndarray
    states: np.ndarray
    iou: np.ndarray
    mean_iou: float
    history: list[float]
    alternatives: list[Candidate]
    ambiguous: bool | None
    seconds: float
    n_starts: int
    distinct: list[int] = field(default_factory=list)
    gravity: float = G_EARTH
    hmax: float = 1.0 / 60.0
    replayed_stages: int = 0

    def summary(self) -> dict:
        """Plain dictionary (YAML friendly) of the estimate."""
        return {
            "t0": float(self.t0),
            "position": self.params[0:3].tolist(),
            "quaternion": self.q0.tolist(),
            "velocity": self.params[6:9].tolist(),
            "omega_world": self.params[9:12].tolist(),
            "tilt": float(self.params[12]),
            "roll": float(self.params[13]),
            "mean_iou": float(self.mean_iou),
            "iou": self.iou.tolist(),
            "ambiguous": None if self.ambiguous is None else bool(self.ambiguous),
            "distinct_alternatives": list(self.distinct),
            "alternatives": [
                {"quaternion": c.q_base.tolist(), "mean_iou": c.mean_iou, "cost": c.cost,
                 "omega_world": c.params[9:12].tolist()} for c in self.alternatives],
            "seconds": float(self.seconds),
            "n_starts": int(self.n_starts),
        }


# ----------------------------------------------------------------------------- objective
class SilhouetteObjective:
    """Smoothed silhouette mismatch of a simulated throw against observed masks at one level.

    Args:
        body: the known body.
        cam: full-resolution camera.
        times: (T,) frame times, seconds.
        masks: (T, H, W) observed silhouettes at full resolution.
        t0: time of the initial state.
        scale: pyramid scale of this level.
        lam: distance-term strength; ramp: anti-aliasing ramp (pixels at this level).
        dist_scale: distance normaliser, full-resolution pixels.
        hmax: RK4 step bound, seconds.
        g: gravity magnitude, m/s^2.
    """

    def __init__(self, body: BoxBody, cam: PinholeCamera, times: np.ndarray, masks: np.ndarray, t0: float,
                 scale: float = 1.0, lam: float = 0.0, ramp: float = 1.0, dist_scale: float = 20.0,
                 hmax: float = 1.0 / 60.0, g: float = G_EARTH) -> None:
        self.g = float(g)
        self.body = body
        self.cam = cam if scale == 1.0 else cam.scaled(scale)
        self.times = np.asarray(times, float)
        self.t0 = float(t0)
        self.scale = float(scale)
        self.ramp = float(ramp)
        self.hmax = float(hmax)
        self.corners = body.box_vertices()
        m = np.asarray(masks, np.float32)
        if scale != 1.0:
            m = np.stack([cv2.resize(f, (self.cam.width, self.cam.height), interpolation=cv2.INTER_AREA) for f in m])
        self.W, self.base = weight_maps(m, lam, dist_scale * scale, 10.0 * dist_scale * scale)
        self.n_evals = 0

    def __call__(self, p: np.ndarray, q_base: np.ndarray, grad: bool = True) -> tuple[float, np.ndarray, bool]:
        """Objective (mean per frame, full-resolution pixels), its gradient (14,) and an ok flag."""
        self.n_evals += 1
        tr = simulate(p, q_base, self.body.inertia, self.times, self.t0, self.hmax, sensitivities=grad, g=self.g)
        if not tr.ok:
            return FAIL_COST, np.zeros(N_PARAM), False
        X = tr.states[:, 0:3]
        Q = tr.states[:, 3:7]
        if np.any((X @ self.cam.R.T + self.cam.t)[:, 2] < 0.05):
            return FAIL_COST, np.zeros(N_PARAM), False
        costs, g6 = sequence_costs(X, Q, self.corners, self.cam, self.W, self.base, self.ramp, 0.5, grad)
        norm = 1.0 / (self.scale ** 2 * len(self.times))
        E = float(costs.sum() * norm)
        G = np.zeros(N_PARAM)
        if grad:
            for k in range(len(self.times)):
                G += g6[k] @ pose_tangent_jacobian(tr.states[k], tr.sens[k])
            G *= norm
        if not np.isfinite(E) or not np.all(np.isfinite(G)):
            return FAIL_COST, np.zeros(N_PARAM), False
        return E, G, True


def silhouette_iou(p: np.ndarray, q_base: np.ndarray, body: BoxBody, cam: PinholeCamera, times: np.ndarray,
                   t0: float, masks: np.ndarray, hmax: float = 1.0 / 60.0, g: float = G_EARTH) -> np.ndarray:
    """Per-frame IoU (T,) of the simulated hard silhouettes against ``masks`` (T, H, W) bool."""
    tr = simulate(p, q_base, body.inertia, times, t0, hmax, sensitivities=False, g=g)
    if not tr.ok:
        return np.zeros(len(times))
    sim = render_coverage(tr.states[:, 0:3], tr.states[:, 3:7], body.box_vertices(), cam) > 0.5
    obs = np.asarray(masks, bool)
    inter = (sim & obs).sum((1, 2))
    union = (sim | obs).sum((1, 2))
    return np.where(union > 0, inter / np.maximum(union, 1), 1.0)


def _fold(p: np.ndarray, qb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fold the rotation increment of ``p`` into the base quaternion."""
    q = quat_mul(qb, quat_exp(p[3:6]))
    q /= np.linalg.norm(q)
    p = p.copy()
    p[3:6] = 0.0
    return p, q


def run_stage(obj: SilhouetteObjective, p: np.ndarray, qb: np.ndarray, maxiter: int
              ) -> tuple[np.ndarray, np.ndarray, float, list[float]]:
    """L-BFGS on the scaled parameters from ``(p, qb)``; returns (p, qb, cost, history)."""
    p0, qb = _fold(np.asarray(p, float), qb)
    hist: list[float] = []

    def fun(x: np.ndarray) -> tuple[float, np.ndarray]:
        E, G, _ = obj(p0 + x * PARAM_SCALE, qb)
        return E, G * PARAM_SCALE

    def record(intermediate_result) -> None:  # scipy >= 1.11 passes the iterate's value: no re-evaluation
        hist.append(float(intermediate_result.fun))

    res = minimize(fun, np.zeros(N_PARAM), jac=True, method="L-BFGS-B",
                   options={"maxiter": int(maxiter), "maxcor": 20, "ftol": 1e-10, "gtol": 1e-8},
                   callback=record)
    p1, q1 = _fold(p0 + res.x * PARAM_SCALE, qb)
    E = float(res.fun)
    if not hist or hist[-1] != E:
        hist.append(E)
    return p1, q1, E, hist


# ----------------------------------------------------------------------------- multi-start
def icosahedral_group() -> np.ndarray:
    """(60, 3, 3) rotations of the icosahedral group (2-fold axes along x, y, z), identity first."""
    phi = (1 + 5 ** 0.5) / 2

    def rot(axis: np.ndarray, ang: float) -> np.ndarray:
        a = np.asarray(axis, float)
        return quat_to_rot(quat_exp(a / np.linalg.norm(a) * ang))

    gens = [rot([0, 1, phi], 2 * np.pi / 5), rot([1, 1, 1], 2 * np.pi / 3), np.diag([1.0, -1, -1])]
    G = [np.eye(3)]
    frontier = [np.eye(3)]
    while frontier:
        new = []
        for A in frontier:
            for B in gens:
                C = A @ B
                if not any(np.allclose(C, D, atol=1e-8) for D in G):
                    G.append(C)
                    new.append(C)
        frontier = new
    return np.stack(G)


def orientation_error_deg(Ra: np.ndarray, Rb: np.ndarray, symmetries: np.ndarray) -> float:
    """Smallest angle (degrees) between ``Ra`` and ``Rb S`` over the body's symmetries ``S``."""
    return min(rotation_angle_deg(Ra, Rb @ S) for S in symmetries)


def start_orientations(R_guess: np.ndarray, symmetries: np.ndarray, mode: str = "icosahedral") -> np.ndarray:
    """Start orientations (N, 3, 3): the guess composed with group rotations, modulo symmetry."""
    if mode == "none":
        return R_guess[None]
    out: list[np.ndarray] = []
    for C in icosahedral_group():
        R = R_guess @ C
        if all(orientation_error_deg(R, S, symmetries) > 1.0 for S in out):
            out.append(R)
    return np.stack(out)


#: below this mean IoU a fit explains too little of the silhouettes to call anything "equally good"
#: (and ``fit_rigid`` warns that the fit failed)
MIN_EXPLAINED_IOU = 0.5


def distinct_alternatives(best: Candidate, alts: list[Candidate], body: BoxBody, times: np.ndarray, t0: float,
                          tie_iou: float = 0.01, distinct_deg: float = 10.0, hmax: float = 1.0 / 60.0,
                          g: float = G_EARTH) -> list[int]:
    """Indices of ``alts`` that explain the silhouettes as well as ``best`` but move differently.

    A candidate ties when its mean IoU is within ``tie_iou`` of the best, and is distinct when its
    orientation differs from the best's by more than ``distinct_deg`` (modulo the body's
    symmetries) at some frame time. Such a pair is the seed's "two solutions" (Figure 2, row c).
    A best fit that does not explain the silhouettes (mean IoU below ``MIN_EXPLAINED_IOU``) has no
    "equally good" alternatives: two candidates that both miss the object are not two solutions.
    """
    if best.mean_iou < MIN_EXPLAINED_IOU:
        return []
    tr_best = simulate(best.params, best.q_base, body.inertia, times, t0, hmax, sensitivities=False, g=g)
    out = []
    for i, c in enumerate(alts):
        if best.mean_iou - c.mean_iou > tie_iou:
            continue
        tr_c = simulate(c.params, c.q_base, body.inertia, times, t0, hmax, sensitivities=False, g=g)
        if not (tr_c.ok and tr_best.ok):
            continue
        d = max(orientation_error_deg(quat_to_rot(a[3:7]), quat_to_rot(b[3:7]), body.symmetries)
                for a, b in zip(tr_best.states, tr_c.states))
        if d > distinct_deg:
            out.append(i)
    return out


# ----------------------------------------------------------------------------- driver
_GUESS_UNITS = {"position": "m", "velocity": "m/s", "omega_world": "rad/s"}


def _guess_number(guess: dict, name: str, unit: str) -> float:
    """``guess[name]`` as a finite float; a RigidBodyError naming the field and value otherwise."""
    v = guess[name]
    try:
        if isinstance(v, (bool, np.bool_)):
            raise TypeError
        x = float(v)
    except (TypeError, ValueError):
        raise RigidBodyError(f"initial guess: '{name}' must be a number ({unit}), got {v!r}") from None
    if not np.isfinite(x):
        raise RigidBodyError(f"initial guess: '{name}' must be a finite number ({unit}), got {v!r}")
    return x


def _guess_vector(guess: dict, name: str, n: int, what: str) -> np.ndarray:
    """``guess[name]`` as ``n`` finite floats; a RigidBodyError naming the field and value otherwise."""
    v = guess[name]
    try:
        if isinstance(v, (str, bytes, bool)):
            raise TypeError
        a = np.asarray(v, float)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != (n,) or not np.all(np.isfinite(a)):
        raise RigidBodyError(f"initial guess: '{name}' must be {n} finite numbers{what}, got {v!r}")
    return a


def _parse_guess(guess: dict) -> tuple[np.ndarray, np.ndarray, float | None]:
    """(parameters (14,), unit quaternion (4,), t0 or None) of an initial-guess mapping.

    Every field must be finite numbers (a NaN ``t0`` simulated a motionless object and a word raised
    a bare ValueError); a missing ``tilt``/``roll`` is 0, a missing or null ``t0`` the first frame.
    """
    if not isinstance(guess, Mapping):
        raise RigidBodyError(f"initial guess: expected a mapping (position, quaternion, velocity, omega_world, "
                             f"tilt, roll, t0), got {type(guess).__name__}")
    missing = [k for k in ("position", "quaternion", "velocity", "omega_world") if k not in guess]
    if missing:
        raise RigidBodyError(f"initial guess: missing field(s) {missing}")
    q = _guess_vector(guess, "quaternion", 4, " (w,x,y,z)")
    if np.linalg.norm(q) < 1e-9:
        raise RigidBodyError(f"initial guess: 'quaternion' must be 4 finite numbers (w,x,y,z), not all zero, "
                             f"got {guess['quaternion']!r}")
    p = np.zeros(N_PARAM)
    for name, sl in (("position", slice(0, 3)), ("velocity", slice(6, 9)), ("omega_world", slice(9, 12))):
        p[sl] = _guess_vector(guess, name, 3, f" ({_GUESS_UNITS[name]})")
    p[12] = _guess_number(guess, "tilt", "rad") if "tilt" in guess else 0.0
    p[13] = _guess_number(guess, "roll", "rad") if "roll" in guess else 0.0
    t0 = None if guess.get("t0") is None else _guess_number(guess, "t0", "s")
    return p, q / np.linalg.norm(q), t0


def visible_frames(masks: np.ndarray, min_pixels: int = 20) -> np.ndarray:
    """Indices of the longest run of consecutive frames whose silhouette has >= ``min_pixels``."""
    area = np.asarray(masks, bool).reshape(len(masks), -1).sum(1)
    vis = area >= min_pixels
    best, cur, start, best_start = 0, 0, 0, 0
    for i, v in enumerate(vis):
        if v:
            if cur == 0:
                start = i
            cur += 1
            if cur > best:
                best, best_start = cur, start
        else:
            cur = 0
    return np.arange(best_start, best_start + best)


def fit_throw(masks: np.ndarray, times: np.ndarray, cam: PinholeCamera, body: BoxBody, guess: dict,
              cfg: FitConfig | dict | None = None,
              on_step: Callable[[int, int, str], None] | None = None,
              checkpoint: str | Path | None = None) -> FitResult:
    """Estimate initial state and gravity direction of a throw from its silhouettes.

    Args:
        masks: (N, H, W) bool silhouettes of the whole clip (background-only frames allowed;
            the longest run of frames showing the object is fitted).
        times: (N,) frame times, seconds.
        cam: calibrated camera. Its world frame (``R``, ``t``: world -> camera) is the frame of
            the guess, of the estimate and of the gravity angles (tilt = roll = 0: gravity along
            world +y). Only when ``R = I, t = 0`` (the rigid footage's and ``calibrate_real``'s) is that the
            camera frame (x right, y down, z forward); ``fit_rigid`` warns otherwise.
        body: the known body (from ``meta.yaml``).
        guess: initial guess ``{position, quaternion (w,x,y,z), velocity, omega_world, tilt,
            roll, t0}`` at time ``t0`` (default: the first fitted frame) -- the seed's user-given
            approximate initial state. Every field must be finite numbers (a RigidBodyError names
            the field and value otherwise); ``t0`` must not lie after the first fitted frame by more
            than ``T0_TOL`` (within it, ``t0`` becomes that frame's time).
        cfg: :class:`FitConfig` or a mapping of its fields.
        on_step: called after every optimised stage of a start as ``on_step(done, total, note)``, in
            work units (scale^2 x frames x iterations, integers); ``total`` is an upper bound (the
            final polish may skip candidates). For progress lines.
        checkpoint: a JSONL file where every finished stage of every start is logged (fsync-ed) as
            it ends (:class:`vidsim.optim.cache.EvalCache`, keyed by the stage's settings and its
            exact starting point). A killed fit run again with the same file replays those stages
            and continues where it stopped, with the result it would have had uninterrupted; a file
            written for other inputs (masks, times, camera, body, guess, settings, ``FIT_VERSION``)
            is moved aside and not replayed. None: no checkpoint.

    Returns:
        :class:`FitResult`.
    """
    t_start = time.perf_counter()
    cfg = cfg if isinstance(cfg, FitConfig) else FitConfig.from_dict(cfg)
    masks = np.asarray(masks, bool)
    times = np.asarray(times, float)
    if masks.ndim != 3 or masks.shape[0] != times.shape[0]:
        raise RigidBodyError(f"masks must be (N, H, W) with N = len(times); got {masks.shape} and {times.shape}")
    if masks.shape[1:] != (cam.height, cam.width):
        raise RigidBodyError(f"masks are {masks.shape[2]}x{masks.shape[1]} but the camera is {cam.width}x{cam.height}")
    frames = visible_frames(masks)
    if len(frames) < 5:
        raise RigidBodyError(f"masks: the object is visible in only {len(frames)} consecutive frames (need >= 5)")
    ft = times[frames]
    fm = masks[frames]
    p_guess, q_guess, t0 = _parse_guess(guess)
    t0 = float(ft[0]) if t0 is None else t0
    if t0 > ft[0] + T0_TOL:
        raise RigidBodyError(f"initial guess: 't0' = {t0!r} s is after the first visible frame at {ft[0]!r} s "
                             f"(frame {frames[0]}): expected a time at or before it")
    t0 = min(t0, float(ft[0]))  # within T0_TOL after it: the state at that frame

    objs: dict[tuple, SilhouetteObjective] = {}
    log = _stage_log(checkpoint, fm, ft, t0, cam, body, p_guess, q_guess, cfg)

    def objective(st: Stage) -> SilhouetteObjective:
        n = len(ft) if st.frames is None else min(st.frames, len(ft))
        key = (st.scale, n, st.lam, st.ramp)
        if key not in objs:
            objs[key] = SilhouetteObjective(body, cam, ft[:n], fm[:n], t0, st.scale, st.lam, st.ramp,
                                            cfg.dist_scale, cfg.hmax, cfg.gravity)
        return objs[key]

    R_guess = quat_to_rot(q_guess)
    starts = start_orientations(R_guess, body.symmetries, cfg.multistart)
    pool = [(FAIL_COST, i, p_guess.copy(), rot_to_quat(R), []) for i, R in enumerate(starts)]
    def work(st: Stage) -> int:
        n = len(ft) if st.frames is None else min(st.frames, len(ft))
        return max(1, int(round(st.scale ** 2 * n * st.maxiter)))

    n_pool = [len(starts)] + [min(k, len(starts)) for k in cfg.screen_keep]
    total = sum(n * work(st) for n, st in zip(n_pool, cfg.screen))
    total += n_pool[-1] * sum(work(st) for st in cfg.refine + cfg.final)
    done = 0

    def step(st: Stage, note: str) -> None:
        nonlocal done
        done += work(st)
        if on_step is not None:
            on_step(done, total, note)

    def stage(st: Stage, p: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, list[float]]:
        if log is None:
            return run_stage(objective(st), p, q, st.maxiter)
        return _logged_stage(log, objective, st, p, q)

    try:
        res = _fit_starts(cfg, pool, stage, step, body, cam, ft, fm, frames, t0, len(starts), t_start)
        res.replayed_stages = 0 if log is None else log.n_hits
        return res
    finally:
        if log is not None:
            log.close()


def _stage_log(checkpoint, fm, ft, t0, cam, body, p_guess, q_guess, cfg):
    """The checkpoint of :func:`fit_throw` (an :class:`~vidsim.optim.cache.EvalCache` whose context
    fingerprints every input of the fit), or None."""
    if checkpoint is None:
        return None
    from vidsim.optim.cache import EvalCache, fingerprint

    ctx = fingerprint("fit_throw", FIT_VERSION, np.packbits(fm), fm.shape, ft, float(t0), cam, body, p_guess,
                      q_guess, cfg)
    return EvalCache(lambda u: None, checkpoint, context=ctx)


def _logged_stage(log, objective, st: Stage, p: np.ndarray, q: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, float, list[float]]:
    """:func:`run_stage` through the checkpoint: the key is the stage's settings and the exact
    starting point, the record the stage's end point, cost and history."""
    frames = -1.0 if st.frames is None else float(st.frames)
    u = np.concatenate([[st.scale, frames, float(st.maxiter), st.lam, st.ramp], np.asarray(p, float),
                        np.asarray(q, float)])

    def run(_u: np.ndarray) -> tuple[float, dict]:
        p1, q1, E, h = run_stage(objective(st), p, q, st.maxiter)
        return E, {"p": p1.tolist(), "q": q1.tolist(), "h": [float(x) for x in h]}

    E, info = log.evaluate(u, run)
    if "p" not in info:  # the stage raised a floating-point error: a failed start, never a crash
        return np.asarray(p, float), np.asarray(q, float), FAIL_COST, [FAIL_COST]
    return np.asarray(info["p"], float), np.asarray(info["q"], float), float(E), list(info["h"])


def _fit_starts(cfg: FitConfig, pool: list, stage, step, body: BoxBody, cam: PinholeCamera, ft: np.ndarray,
                fm: np.ndarray, frames: np.ndarray, t0: float, n_starts: int, t_start: float) -> FitResult:
    """Screen, refine and polish the starts of :func:`fit_throw` (``stage(st, p, q)`` runs one
    stage), then rank the candidates."""
    for st, keep in zip(cfg.screen, cfg.screen_keep):
        nxt = []
        for E, i, p, q, hist in pool:
            p, q, E, h = stage(st, p, q)
            nxt.append((E, i, p, q, hist + h))
            step(st, f"screen start {i} at scale {st.scale}: {E:.1f}")
        nxt.sort(key=lambda s: s[0])
        pool = nxt[:keep]
    refined = []
    for E, i, p, q, hist in pool:
        for st in cfg.refine:
            p, q, E, h = stage(st, p, q)
            hist = hist + h
            step(st, f"refine start {i} at scale {st.scale}: {E:.1f}")
        refined.append((E, i, p, q, hist))
    E_best = min(r[0] for r in refined)
    cands: list[Candidate] = []
    for E, i, p, q, hist in refined:
        if E <= cfg.final_ratio * E_best or not cands:
            for st in cfg.final:
                p, q, E, h = stage(st, p, q)
                hist = hist + h
                step(st, f"polish start {i} at scale {st.scale}: {E:.1f}")
        iou = silhouette_iou(p, q, body, cam, ft, t0, fm, cfg.hmax, cfg.gravity)
        cands.append(Candidate(p, q, float(E), float(iou.mean()), iou, hist, i))
    cands.sort(key=lambda c: (-c.mean_iou, c.cost))
    best = cands[0]
    alts = cands[1:]
    tr_best = simulate(best.params, best.q_base, body.inertia, ft, t0, cfg.hmax, sensitivities=False, g=cfg.gravity)
    distinct = distinct_alternatives(best, alts, body, ft, t0, cfg.tie_iou, cfg.distinct_deg, cfg.hmax, cfg.gravity)
    ambiguous = bool(distinct) if alts else None  # one candidate: no two-solution check was made
    return FitResult(best.params, best.q_base, t0, ft, frames, tr_best.states, best.iou, best.mean_iou,
                     best.history, alts, ambiguous, time.perf_counter() - t_start, n_starts, distinct,
                     float(cfg.gravity), float(cfg.hmax))
