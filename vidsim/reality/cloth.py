"""Cloth reality: MuJoCo flex cloth, an engine the estimator does not use (issue 5).

This module stands in for the real fabrics of the seed (section 4.5): a 0.3 m square swatch
whose two top corners are moved along a known trajectory (the seed measured it with motion
capture), and a skirt on a skipping, kinematic body. It returns pure data (vertex positions per
frame, faces, times, the measured corner paths and a truth dictionary); filming and file I/O are
done elsewhere.

Physics (MuJoCo >= 4.0 ``flexcomp``, ``dim=2``)
    * Membrane + bending elasticity of MuJoCo's shell model: Saint Venant-Kirchhoff stretching
      (Young's modulus ``E``, Poisson ``nu``, thickness ``t``) and a discrete-hinge bending energy
      with rigidity ``D = E t^3 / (12 (1 - nu^2))``, Rayleigh damping. A fabric is described by
      its membrane stiffness ``K = E t`` (N/m) and bending rigidity ``D`` (N m); ``t`` and ``E``
      are derived so both hold. MuJoCo 4.0 integrates flex elasticity only with the ``discrete``
      integrator (``implicitfast`` is refused at load time), so that is what is used.
    * MuJoCo's own fluid forces act per body, not per face, so the air model here is this
      module's: per triangle, with the face velocity ``v`` relative to the wind ``w``
      (``u = v - w``, unit normal ``n``, area ``A``, air density ``rho``):
      pressure drag ``-C_d 1/2 rho A |u.n| (u.n) n``, a flat-plate lift
      ``C_l 1/2 rho A |u|^2 sin(a) cos(a)`` perpendicular to ``u`` in the (n, u) plane, and skin
      friction ``-C_f 1/2 rho A |u_t| u_t`` on the tangential part. Each face force is shared
      equally by its three vertices and applied through ``data.xfrc_applied``. This differs from
      the estimator's linear + quadratic drag law on purpose.
    * What MuJoCo allows for stretch: an isotropic, linear stress-strain (SVK) membrane only; it
      has no anisotropic or strain-stiffening membrane. Those effects are therefore added by this
      module as explicit per-edge springs on the grid's warp (vertical) and weft (horizontal)
      edges, ``f = -k (eps + c3 eps^3)``, with the time step reduced to keep them stable.
      Bending plasticity (MuJoCo's ``yield``) is native and exposed as the
      ``bending_plasticity`` effect (bending hysteresis).
    * The gripped corners are kinematic: before every step their slide joints are set to the
      prescribed position and velocity (a rigid grip). Their bodies are made heavy (1 kg,
      gravity-compensated): the discrete integrator solves all flex dofs implicitly inside a
      step, and a light gripped vertex would follow the cloth within the step, leaving the cloth
      hanging ~100 % over-stretched at the grip (seen, then fixed; tested). With grip slip on, the *true* corner path
      (used by the simulation) differs from the *measured* one (returned as the known input).

Frames: world z up, gravity -z; the swatch hangs in the x-z plane (y = 0 at rest), its top edge
at the motion's centre height. Units: metres, seconds, kilograms, newtons.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

__all__ = [
    "ClothRealityError",
    "ClothRealityRun",
    "FABRICS",
    "MOTIONS",
    "DEFAULT_EFFECTS",
    "fabric_profile",
    "swatch_motion",
    "resolve_effects",
    "corner_paths",
    "simulate_swatch",
    "air_forces",
    "SKIRT_MOTIONS",
    "skirt_motion",
    "skirt_frames",
    "simulate_skirt",
]


class ClothRealityError(ValueError):
    """Bad fabric, motion or effects description (names the field and what was expected)."""


# --------------------------------------------------------------------------------------- fabrics
#: Fabric profiles named after the seed's fabrics. Units: areal_density kg/m^2, stretch N/m
#: (membrane stiffness E t), bend N m (bending rigidity D), poisson [-], damping s (Rayleigh),
#: drag/lift/friction coefficients [-] used by the per-face air model.
FABRICS: dict[str, dict[str, float]] = {
    "linen": {"areal_density": 0.20, "stretch": 3000.0, "bend": 4.0e-5, "poisson": 0.25,
              "damping": 4.0e-3, "drag": 1.2, "lift": 0.6, "friction": 0.02},
    "fleece": {"areal_density": 0.30, "stretch": 300.0, "bend": 1.0e-5, "poisson": 0.30,
               "damping": 6.0e-3, "drag": 1.4, "lift": 0.5, "friction": 0.05},
    "satin": {"areal_density": 0.10, "stretch": 800.0, "bend": 4.0e-7, "poisson": 0.30,
              "damping": 1.0e-3, "drag": 1.1, "lift": 0.8, "friction": 0.01},
    "knit": {"areal_density": 0.25, "stretch": 25.0, "bend": 3.0e-6, "poisson": 0.35,
             "damping": 5.0e-3, "drag": 1.3, "lift": 0.5, "friction": 0.04},
}
_FABRIC_KEYS = set(FABRICS["linen"])


def fabric_profile(name: str) -> dict[str, float]:
    """A copy of one of the four fabric profiles (``linen``, ``fleece``, ``satin``, ``knit``)."""
    if name not in FABRICS:
        raise ClothRealityError(f"fabric name must be one of {sorted(FABRICS)}, got {name!r}")
    return dict(FABRICS[name])


def _check_fabric(fabric: dict[str, Any]) -> dict[str, float]:
    if not isinstance(fabric, dict):
        raise ClothRealityError(f"fabric must be a dict, got {type(fabric).__name__}")
    unknown = set(fabric) - _FABRIC_KEYS - {"name"}
    missing = _FABRIC_KEYS - set(fabric)
    if unknown or missing:
        raise ClothRealityError(f"fabric keys: unknown {sorted(unknown)}, missing {sorted(missing)}")
    f = {k: float(fabric[k]) for k in _FABRIC_KEYS}
    for k in ("areal_density", "stretch", "bend"):
        if not (np.isfinite(f[k]) and f[k] > 0):
            raise ClothRealityError(f"fabric['{k}'] must be positive, got {fabric[k]!r}")
    if not 0 <= f["poisson"] < 0.5:
        raise ClothRealityError(f"fabric['poisson'] must be in [0, 0.5), got {fabric['poisson']!r}")
    for k in ("damping", "drag", "lift", "friction"):
        if not (np.isfinite(f[k]) and f[k] >= 0):
            raise ClothRealityError(f"fabric['{k}'] must be >= 0, got {fabric[k]!r}")
    return f


def _shell_parameters(f: dict[str, float]) -> tuple[float, float]:
    """(young Pa, thickness m) such that ``E t = stretch`` and ``E t^3/(12(1-nu^2)) = bend``."""
    t = float(np.sqrt(12.0 * (1.0 - f["poisson"] ** 2) * f["bend"] / f["stretch"]))
    return f["stretch"] / t, t


# --------------------------------------------------------------------------------------- motions
#: Corner motions: the seed's two waving trials (slightly different) and a held-out motion
#: (the seed's robot waving: a rolling, bobbing bar instead of a sideways wave).
MOTIONS: dict[str, dict[str, Any]] = {
    "exp1": {"center": [0.0, 0.0, 1.0], "width": 0.3, "amplitude": [0.10, 0.06, 0.02],
             "frequency": 1.2, "phase": 0.0, "roll": 0.0, "yaw": 0.15, "bob": 0.0, "ramp": 0.25},
    "exp2": {"center": [0.0, 0.0, 1.0], "width": 0.3, "amplitude": [0.09, 0.075, 0.025],
             "frequency": 1.35, "phase": 0.4, "roll": 0.0, "yaw": 0.12, "bob": 0.0, "ramp": 0.25},
    "robot": {"center": [0.0, 0.0, 1.0], "width": 0.3, "amplitude": [0.02, 0.10, 0.0],
              "frequency": 0.9, "phase": 0.0, "roll": 0.45, "yaw": 0.0, "bob": 0.04, "ramp": 0.25},
}
#: optional motion keys and their defaults (older motion dicts without them stay valid)
_MOTION_OPTIONAL = {"squeeze": 0.0}
_MOTION_KEYS = set(MOTIONS["exp1"]) | set(_MOTION_OPTIONAL)


def swatch_motion(name: str) -> dict[str, Any]:
    """A copy of a named corner motion (``exp1``, ``exp2``, ``robot``)."""
    if name not in MOTIONS:
        raise ClothRealityError(f"motion name must be one of {sorted(MOTIONS)}, got {name!r}")
    return copy.deepcopy(MOTIONS[name])


def _check_motion(motion: dict[str, Any]) -> dict[str, Any]:
    if not isinstance(motion, dict):
        raise ClothRealityError(f"motion must be a dict, got {type(motion).__name__}")
    unknown = set(motion) - _MOTION_KEYS - {"name"}
    missing = _MOTION_KEYS - set(motion) - set(_MOTION_OPTIONAL)
    if unknown or missing:
        raise ClothRealityError(f"motion keys: unknown {sorted(unknown)}, missing {sorted(missing)}")
    m = {**_MOTION_OPTIONAL, **motion}
    for k in ("center", "amplitude"):
        v = np.asarray(m[k], dtype=float)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ClothRealityError(f"motion['{k}'] must be 3 finite numbers (m), got {m[k]!r}")
        m[k] = v
    if not (m["width"] > 0):
        raise ClothRealityError(f"motion['width'] must be > 0 m, got {m['width']!r}")
    if not (m["frequency"] >= 0 and m["ramp"] >= 0):
        raise ClothRealityError("motion['frequency'] and motion['ramp'] must be >= 0")
    if not 0 <= float(m["squeeze"]) < 0.8:
        raise ClothRealityError(f"motion['squeeze'] must be in [0, 0.8) (fraction of the width), got {m['squeeze']!r}")
    return m


def corner_paths(motion: dict[str, Any], times: np.ndarray) -> np.ndarray:
    """Positions of the two gripped corners (left = -x, right = +x) at the given times.

    The bar between the corners translates by ``amplitude * sin(2 pi f t + phase)``, bobs by
    ``bob * sin(4 pi f t)`` in z, rolls (about y) by ``roll * sin(2 pi f t)`` and yaws (about z)
    by ``yaw * sin(2 pi f t + phase)``, and the grips move towards each other by the fraction
    ``squeeze * (1 - cos(2 pi f t)) / 2`` of the width (the top edge is pushed together and the
    fabric folds, as hands do); everything is multiplied by a smooth ramp that rises from 0 (at
    rest, zero velocity at t = 0) to 1 at ``t = ramp``.

    Args:
        motion: a motion dict (see :data:`MOTIONS`).
        times: ``(T,)`` times in seconds (t < 0 means at rest).

    Returns:
        ``(T, 2, 3)`` corner positions in metres.
    """
    m = _check_motion(motion)
    t = np.asarray(times, dtype=float).reshape(-1)
    if m["ramp"] > 0:
        s = np.clip(t / m["ramp"], 0.0, 1.0)
        env = s * s * s * (10 - 15 * s + 6 * s * s)  # C2 smoothstep
    else:
        env = (t >= 0).astype(float)
    w = 2 * np.pi * m["frequency"]
    disp = env[:, None] * m["amplitude"][None, :] * np.sin(w * t + m["phase"])[:, None]
    disp[:, 2] += env * m["bob"] * np.sin(2 * w * t)
    roll = env * m["roll"] * np.sin(w * t)
    yaw = env * m["yaw"] * np.sin(w * t + m["phase"])
    half = 0.5 * m["width"] * (1.0 - float(m["squeeze"]) * env * 0.5 * (1.0 - np.cos(w * t)))
    half = half[:, None]
    # bar direction: +x rotated by roll (about y, lifts +x end when positive) then yaw (about z)
    d = np.stack([np.cos(roll) * np.cos(yaw), np.cos(roll) * np.sin(yaw), np.sin(roll)], axis=1)
    mid = m["center"][None, :] + disp
    return np.stack([mid - half * d, mid + half * d], axis=1)


# --------------------------------------------------------------------------------------- effects
#: Effects, each off by default. Units: wind m/s, gust fraction of the steady wind and Hz,
#: extra warp/weft stiffness N/m, strain-stiffening c3 [-], grip drop m and lag s, tilt degrees,
#: bending plasticity: MuJoCo's native bending yield (outer-fibre strain ``t/2 |dkappa|``, [-]),
#: a bending hysteresis: folds beyond the yield stay partly set; mocap noise: Gaussian error (m,
#: per axis) of the *measured* corner paths only (the cloth follows the true path).
DEFAULT_EFFECTS: dict[str, dict[str, Any]] = {
    "air_drag": {"on": False, "density": 1.2},
    "wind": {"on": False, "velocity": [0.0, 1.0, 0.0], "gust": 0.0, "gust_frequency": 1.5},
    "anisotropy": {"on": False, "warp": 0.0, "weft": 0.0},
    "strain_stiffening": {"on": False, "c3": 0.0, "stiffness": 0.0},
    "grip_slip": {"on": False, "drop": 0.01, "lag": 0.03, "jitter": 0.0},
    "gravity_tilt": {"on": False, "degrees": 3.0, "azimuth_deg": 90.0},
    "bending_plasticity": {"on": False, "yield_strain": 2.0e-4},
    "mocap_noise": {"on": False, "sigma": 5.0e-4},
}


def resolve_effects(effects: dict[str, Any] | None) -> dict[str, dict[str, Any]]:
    """Merge an effects dict over :data:`DEFAULT_EFFECTS`; unknown names are errors.

    Args:
        effects: ``{effect: {key: value}}``; missing effects/keys take the defaults (off).

    Returns:
        A complete effects dict.
    """
    out = copy.deepcopy(DEFAULT_EFFECTS)
    for name, spec in (effects or {}).items():
        if name not in out:
            raise ClothRealityError(f"unknown effect {name!r}; expected one of {sorted(out)}")
        if not isinstance(spec, dict):
            raise ClothRealityError(f"effects['{name}'] must be a dict, got {spec!r}")
        for k, v in spec.items():
            if k not in out[name]:
                raise ClothRealityError(f"unknown key {k!r} in effects['{name}']; expected {sorted(out[name])}")
            out[name][k] = v
    _check_effect_values(out)
    return out


def _check_effect_values(eff: dict[str, dict[str, Any]]) -> None:
    """Refuse effect values that are not physical or not of the expected kind, naming the key, before
    any simulation (a string ``on: "false"`` counted as on; a negative air density fed energy in)."""

    def num(name: str, key: str, lo: float | None = 0.0, hi: float | None = None, lo_open: bool = False) -> None:
        v = eff[name][key]
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        if ok and lo is not None:
            ok = v > lo if lo_open else v >= lo
        if ok and hi is not None:
            ok = v <= hi
        if not ok:
            rng = (f"{'>' if lo_open else '>='} {lo}" if lo is not None else "finite") + (f" and <= {hi}" if hi is not None else "")
            raise ClothRealityError(f"effects['{name}']['{key}'] must be a number {rng}, got {v!r}")

    for name, spec in eff.items():
        if not isinstance(spec["on"], bool):
            raise ClothRealityError(f"effects['{name}']['on'] must be true or false, got {spec['on']!r}")
    num("air_drag", "density")
    vel = eff["wind"]["velocity"]
    try:
        ok = np.asarray(vel, dtype=float).shape == (3,) and bool(np.all(np.isfinite(np.asarray(vel, dtype=float))))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ClothRealityError(f"effects['wind']['velocity'] must be 3 finite numbers (m/s), got {vel!r}")
    num("wind", "gust")
    num("wind", "gust_frequency")
    num("anisotropy", "warp")
    num("anisotropy", "weft")
    num("strain_stiffening", "c3")
    num("strain_stiffening", "stiffness")
    for key in ("drop", "lag", "jitter"):
        num("grip_slip", key)
    num("gravity_tilt", "degrees", 0.0, 90.0)
    num("gravity_tilt", "azimuth_deg", None)
    num("bending_plasticity", "yield_strain", 0.0, lo_open=True)
    num("mocap_noise", "sigma")
    if eff["wind"]["on"] and not eff["air_drag"]["on"]:
        # the wind acts through the air model, whose density air_drag holds: "wind without drag" is not a thing
        raise ClothRealityError("effects['wind'] is on but effects['air_drag'] is off: the wind acts through the air "
                                "(its density is air_drag's), so switch air_drag on too")


# --------------------------------------------------------------------------------------- result
@dataclass
class ClothRealityRun:
    """Pure-data result of a cloth reality simulation.

    Attributes:
        vertices: ``(T, N, 3)`` vertex positions per frame, metres (frames completed so far if
            the run failed).
        faces: ``(F, 3)`` int vertex indices of the triangles.
        times: ``(T,)`` frame times, seconds (frame 0 at t = 0, after settling at rest).
        corner_paths_measured: ``(T, 2, 3)`` the gripped corners' trajectory as measured (the
            known input for ``meta.yaml``); ``(T, 0, 3)`` for the skirt.
        truth: everything the estimator must not read (fabric, derived MuJoCo parameters,
            effects, true corner paths, wall time, ...).
        ok: False when the simulation diverged; ``failure`` then says why.
        failure: None or a message.
        colliders: for the skirt, the kinematic body (known input, like motion capture):
            ``{"capsules": (T, K, 2, 3) leg endpoints, "radii": (K,), "waist_pos": (T, 3),
            "waist_rot": (T, 3, 3), "waist_ring": (T, A, 3) waistband vertex positions}``;
            empty for the swatch.
    """

    vertices: np.ndarray
    faces: np.ndarray
    times: np.ndarray
    corner_paths_measured: np.ndarray
    truth: dict[str, Any]
    ok: bool = True
    failure: str | None = None
    colliders: dict[str, np.ndarray] = field(default_factory=dict)


# --------------------------------------------------------------------------------------- air model
def air_forces(
    x: np.ndarray,
    v: np.ndarray,
    faces: np.ndarray,
    wind: np.ndarray,
    rho: float,
    c_drag: float,
    c_lift: float,
    c_fric: float,
) -> np.ndarray:
    """Per-face aerodynamic force, shared equally by each face's vertices.

    Args:
        x: ``(N, 3)`` vertex positions, m.
        v: ``(N, 3)`` vertex velocities, m/s.
        faces: ``(F, 3)`` triangles.
        wind: ``(3,)`` air velocity, m/s.
        rho: air density, kg/m^3.
        c_drag, c_lift, c_fric: pressure-drag, lift and skin-friction coefficients.

    Returns:
        ``(N, 3)`` forces on the vertices, newtons.
    """
    a, b, c = x[faces[:, 0]], x[faces[:, 1]], x[faces[:, 2]]
    cr = np.cross(b - a, c - a)
    dbl = np.linalg.norm(cr, axis=1)
    area = 0.5 * dbl
    n = cr / np.maximum(dbl, 1e-15)[:, None]
    u = (v[faces[:, 0]] + v[faces[:, 1]] + v[faces[:, 2]]) / 3.0 - wind[None, :]
    un = np.einsum("ij,ij->i", u, n)
    ut = u - un[:, None] * n
    speed = np.linalg.norm(u, axis=1)
    q = 0.5 * rho * area
    f = -(c_drag * q * np.abs(un) * un)[:, None] * n
    f -= (c_fric * q * np.linalg.norm(ut, axis=1))[:, None] * ut
    # flat-plate lift: |F| = C_l q |u|^2 sin(a) cos(a), perpendicular to u, in the (n, u) plane,
    # pointing away from the side the air comes from (sign of -u.n).
    uh = u / np.maximum(speed, 1e-12)[:, None]
    ns = -np.sign(un)[:, None] * n
    perp = ns - np.einsum("ij,ij->i", ns, uh)[:, None] * uh
    pn = np.linalg.norm(perp, axis=1)
    sin_a = np.abs(un) / np.maximum(speed, 1e-12)
    cos_a = np.sqrt(np.clip(1 - sin_a**2, 0.0, 1.0))
    lift = c_lift * q * speed**2 * sin_a * cos_a
    f += (lift / np.maximum(pn, 1e-12))[:, None] * perp * (pn > 1e-9)[:, None]
    idx = faces.ravel()
    fv = np.repeat(f / 3.0, 3, axis=0)
    return np.stack([np.bincount(idx, weights=fv[:, c], minlength=len(x)) for c in range(3)], axis=1)


def _wind_at(eff: dict[str, Any], t: float, phases: np.ndarray) -> np.ndarray:
    w = eff["wind"]
    if not w["on"]:
        return np.zeros(3)
    base = np.asarray(w["velocity"], dtype=float)
    g = float(w["gust"])
    if g == 0:
        return base
    f0 = float(w["gust_frequency"])
    # three incommensurate sinusoids with seeded phases: a reproducible gusting profile
    mod = (np.sin(2 * np.pi * f0 * t + phases[0]) + 0.6 * np.sin(2 * np.pi * 1.73 * f0 * t + phases[1])
           + 0.3 * np.sin(2 * np.pi * 3.11 * f0 * t + phases[2])) / 1.9
    return base * (1.0 + g * mod)


def _gravity(eff: dict[str, Any]) -> np.ndarray:
    g = np.array([0.0, 0.0, -9.81])
    if eff["gravity_tilt"]["on"]:
        th = np.deg2rad(float(eff["gravity_tilt"]["degrees"]))
        az = np.deg2rad(float(eff["gravity_tilt"]["azimuth_deg"]))
        g = 9.81 * np.array([np.sin(th) * np.cos(az), np.sin(th) * np.sin(az), -np.cos(th)])
    return g


def _slip_paths(measured_fn, eff: dict[str, Any], t: np.ndarray, rng: np.random.Generator, jitter_phase: np.ndarray) -> np.ndarray:
    """True corner path given the measured one: grip lag, a slow drop, and optional jitter."""
    gs = eff["grip_slip"]
    p = measured_fn(t - float(gs["lag"]))
    drop = float(gs["drop"])
    s = np.clip(t / 1.0, 0.0, 1.0)
    p[:, :, 2] -= drop * (s * s * (3 - 2 * s))[:, None]
    jit = float(gs["jitter"])
    if jit > 0:
        p += jit * np.sin(2 * np.pi * 7.0 * t[:, None, None] + jitter_phase[None, :, :])
    return p


# --------------------------------------------------------------------------------------- swatch
def _yield_attr(eff: dict[str, Any]) -> str:
    bp = eff["bending_plasticity"]
    if not bp["on"]:
        return ""
    y = float(bp["yield_strain"])
    if not (np.isfinite(y) and y > 0):
        raise ClothRealityError(f"effects['bending_plasticity']['yield_strain'] must be > 0, got {bp['yield_strain']!r}")
    return f' yield="0 {y}"'


def _swatch_xml(f: dict[str, float], n: int, size: float, top: np.ndarray, dt: float, gravity: np.ndarray,
                yield_attr: str = "") -> str:
    young, thick = _shell_parameters(f)
    sp = size / (n - 1)
    mass = f["areal_density"] * size * size
    cx, cy, cz = top[0], top[1], top[2] - size / 2
    return f"""
<mujoco model="swatch">
  <option timestep="{dt}" integrator="discrete" solver="Newton" tolerance="1e-10"
          gravity="{gravity[0]} {gravity[1]} {gravity[2]}"/>
  <size memory="64M"/>
  <worldbody>
    <flexcomp name="cloth" type="grid" dim="2" count="{n} {n} 1" spacing="{sp} {sp} {sp}"
              pos="{cx} {cy} {cz}" euler="90 0 0" mass="{mass}" radius="0.001">
      <contact contype="0" conaffinity="0" selfcollide="none"/>
      <edge equality="false"/>
      <elasticity young="{young}" poisson="{f['poisson']}" thickness="{thick}"
                  damping="{f['damping']}" elastic2d="both"{yield_attr}/>
    </flexcomp>
  </worldbody>
</mujoco>"""


def _make_grips(m: mujoco.MjModel, d: mujoco.MjData, bodies: list[int]) -> None:
    """Turn gripped vertex bodies into heavy, gravity-compensated grips.

    MuJoCo's discrete integrator solves all flex dofs implicitly within a step; a light gripped
    vertex would follow the cloth inside the step and the overwrite afterwards would leave the
    cloth hanging ~100 % over-stretched at the grip. A 1 kg grip barely moves within a step, and
    the prescribed state is re-imposed before every step (measured: the static hang then matches
    MuJoCo's own pin to 0.01 % strain).
    """
    for b in bodies:
        m.body_mass[b] = 1.0
        m.body_inertia[b] = [1e-5, 1e-5, 1e-5]
        m.body_gravcomp[b] = 1.0
    mujoco.mj_setConst(m, d)


class _Kinematic:
    """Prescribes world positions/velocities of bodies moved by three slide joints."""

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, bodies: list[int]) -> None:
        self.qadr, self.vadr, self.axes, self.p0 = [], [], [], []
        for b in bodies:
            j0, nj = int(m.body_jntadr[b]), int(m.body_jntnum[b])
            if nj != 3 or any(m.jnt_type[j] != mujoco.mjtJoint.mjJNT_SLIDE for j in range(j0, j0 + 3)):
                raise ClothRealityError(f"body {b} is not a 3-slide-joint flex vertex body")
            self.qadr.append([int(m.jnt_qposadr[j]) for j in range(j0, j0 + 3)])
            self.vadr.append([int(m.jnt_dofadr[j]) for j in range(j0, j0 + 3)])
            self.axes.append(np.array([d.xaxis[j] for j in range(j0, j0 + 3)]))
            self.p0.append(d.xpos[b] - self.axes[-1].T @ np.array([d.qpos[a] for a in self.qadr[-1]]))

    def set(self, d: mujoco.MjData, pos: np.ndarray, vel: np.ndarray) -> None:
        for i in range(len(self.qadr)):
            q = self.axes[i] @ (pos[i] - self.p0[i])
            u = self.axes[i] @ vel[i]
            d.qpos[self.qadr[i]] = q
            d.qvel[self.vadr[i]] = u


def _grid_edges(x0: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split the flex edges into weft (horizontal, along x) and warp (vertical, along z)."""
    d = x0[edges[:, 1]] - x0[edges[:, 0]]
    horiz = (np.abs(d[:, 0]) > 1e-9) & (np.abs(d[:, 2]) < 1e-9)
    vert = (np.abs(d[:, 2]) > 1e-9) & (np.abs(d[:, 0]) < 1e-9)
    return edges[horiz], edges[vert]


def _border_halves(coord: np.ndarray) -> np.ndarray:
    """(E,) strip-width factors of grid edges from the coordinate across them: 1/2 on the swatch's two
    border lines, 1 inside (n lines at spacing h carry strips of h, the two borders h/2 each)."""
    lo, hi = coord.min(), coord.max()
    tol = 1e-6 * max(hi - lo, 1e-9)
    return np.where((np.abs(coord - lo) < tol) | (np.abs(coord - hi) < tol), 0.5, 1.0)


def _edge_forces(x: np.ndarray, edges: np.ndarray, rest: np.ndarray, k_lin, k_cub) -> np.ndarray:
    """Explicit edge springs, tension ``k_lin eps + k_cub eps^3`` (N; eps = engineering strain;
    ``k_lin``, ``k_cub``: scalars or (E,) per edge)."""
    d = x[edges[:, 1]] - x[edges[:, 0]]
    ln = np.linalg.norm(d, axis=1)
    eps = ln / rest - 1.0
    tension = k_lin * eps + k_cub * eps**3
    fv = (tension / np.maximum(ln, 1e-12))[:, None] * d  # pulls the ends together when stretched
    out = np.zeros_like(x)
    np.add.at(out, edges[:, 0], fv)
    np.add.at(out, edges[:, 1], -fv)
    return out


def _mujoco_unstable(d: mujoco.MjData) -> str | None:
    """MuJoCo resets the state silently-ish when accelerations blow up: treat that as divergence."""
    for w in (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQPOS):
        if d.warning[w].number > 0:
            return f"MuJoCo reported {w.name} (unstable simulation, state was reset)"
    return None


def _diverged(x: np.ndarray, ref: np.ndarray, scale: float) -> str | None:
    if not np.all(np.isfinite(x)):
        return "non-finite vertex positions"
    if np.max(np.linalg.norm(x - ref, axis=1)) > 10 * scale:
        return f"a vertex moved more than {10 * scale:.2f} m from the grip (exploded)"
    return None


def simulate_swatch(
    fabric: dict[str, Any],
    motion: dict[str, Any],
    effects: dict[str, Any] | None,
    rng: np.random.Generator,
    n_frames: int = 50,
    fps: float = 30.0,
    resolution: int = 15,
    size: float = 0.3,
    dt: float = 0.002,
    settle: float = 1.0,
    settle_bath: float = 0.0,
) -> ClothRealityRun:
    """Simulate a square swatch hanging from two kinematically moved top corners.

    The swatch starts flat and hanging, settles at rest for ``settle`` seconds with the corners
    held at the motion's start, then the motion plays and ``n_frames`` frames are recorded at
    ``fps`` (frame 0 at t = 0).

    Args:
        fabric: a fabric dict (see :data:`FABRICS`).
        motion: a motion dict (see :data:`MOTIONS`); its ``width`` should equal ``size``.
        effects: effects dict (see :data:`DEFAULT_EFFECTS`), None = all off.
        rng: random generator (gust phases, grip jitter); the result is reproducible for a seed.
        n_frames: number of output frames.
        fps: output frame rate, Hz.
        resolution: vertices per side (``resolution**2`` vertices).
        size: side of the square swatch, m.
        dt: MuJoCo time step, s (reduced automatically when explicit edge springs need it).
        settle: rest time before frame 0, s.
        settle_bath: viscous damping rate of the settle, 1/s (velocities scaled by
            ``exp(-settle_bath dt)`` every settle step; 0: off, the swatch starts the motion
            still swinging from its flat start).

    Returns:
        :class:`ClothRealityRun` (``ok=False`` with a message if the simulation diverged).
    """
    f = _check_fabric(fabric)
    mot = _check_motion(motion)
    eff = resolve_effects(effects)
    if not (isinstance(n_frames, (int, np.integer)) and n_frames >= 1):
        raise ClothRealityError(f"n_frames must be a positive integer, got {n_frames!r}")
    if not (isinstance(resolution, (int, np.integer)) and resolution >= 3):
        raise ClothRealityError(f"resolution must be an integer >= 3, got {resolution!r}")
    if not (fps > 0 and dt > 0 and size > 0 and settle >= 0):
        raise ClothRealityError(f"fps, dt, size must be > 0 and settle >= 0, got {fps}, {dt}, {size}, {settle}")
    if not (np.isfinite(settle_bath) and settle_bath >= 0):
        raise ClothRealityError(f"settle_bath must be a finite damping rate >= 0 (1/s), got {settle_bath!r}")
    gust_phases = rng.uniform(0, 2 * np.pi, 3)
    jitter_phase = rng.uniform(0, 2 * np.pi, (2, 3))

    times = np.arange(n_frames) / fps
    measured = corner_paths(mot, times)
    mocap_noise = rng.normal(0.0, 1.0, measured.shape)

    def true_path(t: np.ndarray) -> np.ndarray:
        if eff["grip_slip"]["on"]:
            return _slip_paths(lambda s: corner_paths(mot, s), eff, t, rng, jitter_phase)
        return corner_paths(mot, t)

    top = corner_paths(mot, np.array([0.0]))[0].mean(axis=0)
    gravity = _gravity(eff)

    # explicit edge springs (anisotropy / strain stiffening) need a stable step
    k_warp = float(eff["anisotropy"]["warp"]) if eff["anisotropy"]["on"] else 0.0
    k_weft = float(eff["anisotropy"]["weft"]) if eff["anisotropy"]["on"] else 0.0
    k_cub = 0.0
    if eff["strain_stiffening"]["on"]:
        k_cub = float(eff["strain_stiffening"]["c3"]) * float(eff["strain_stiffening"]["stiffness"] or f["stretch"])
    if min(k_warp, k_weft, k_cub) < 0:
        raise ClothRealityError("anisotropy warp/weft and strain_stiffening c3/stiffness must be >= 0")
    mass_v = f["areal_density"] * size * size / resolution**2
    h = size / (resolution - 1)
    # Tangent stiffness of an extra edge spring (N/m of displacement ~ membrane N/m on a square
    # grid), the cubic part evaluated at 10 % strain. An explicit spring on a vertex of mass m is
    # stable for dt < 2 / omega = sqrt(m / k) (two-sided neighbours); use 0.7 of that.
    k_eff = max(k_warp, k_weft) + 3 * 0.01 * k_cub
    dt_used = float(dt)
    if k_eff > 0:
        dt_used = min(dt_used, 0.7 * np.sqrt(mass_v / k_eff))
    substeps = max(1, int(np.ceil((1.0 / fps) / dt_used - 1e-9)))
    dt_used = (1.0 / fps) / substeps
    n_settle = int(round(settle / dt_used))

    xml = _swatch_xml(f, resolution, size, top, dt_used, gravity, _yield_attr(eff))
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    x0 = d.flexvert_xpos.copy()
    faces = m.flex_elem.reshape(-1, 3).astype(np.int64)
    vbody = m.flex_vertbodyid.astype(np.int64)
    c0 = corner_paths(mot, np.array([0.0]))[0]
    ic = [int(np.argmin(np.linalg.norm(x0 - c0[k], axis=1))) for k in range(2)]
    if max(np.linalg.norm(x0[ic[k]] - c0[k]) for k in range(2)) > 1e-6 + 0.01 * size:
        raise ClothRealityError(f"motion['width'] ({mot['width']}) must match the swatch size ({size})")
    _make_grips(m, d, [int(vbody[i]) for i in ic])
    kin = _Kinematic(m, d, [int(vbody[i]) for i in ic])
    vel_of = _VertexVelocity(m, d, vbody)
    weft, warp = _grid_edges(x0, m.flex_edge.astype(np.int64))
    rest_weft = np.linalg.norm(x0[weft[:, 1]] - x0[weft[:, 0]], axis=1)
    rest_warp = np.linalg.norm(x0[warp[:, 1]] - x0[warp[:, 0]], axis=1)
    strip_warp = _border_halves(x0[warp[:, 0], 0])  # warp edges run along z: their strips lie across x
    strip_weft = _border_halves(x0[weft[:, 0], 2])
    air_on = bool(eff["air_drag"]["on"])  # wind needs it (resolve_effects)
    rho = float(eff["air_drag"]["density"])
    free = np.ones(len(x0), bool)
    free[ic] = False
    fbody = vbody[free]

    def corner_state(t: float) -> tuple[np.ndarray, np.ndarray]:
        e = 1e-4
        p = true_path(np.array([t - e, t, t + e]))
        return p[1], (p[2] - p[0]) / (2 * e)

    def apply_forces(t: float) -> None:
        if not (air_on or k_eff > 0):
            return
        x = d.flexvert_xpos
        force = np.zeros_like(x)
        if air_on:
            force += air_forces(x, vel_of(d), faces, _wind_at(eff, t, gust_phases), rho,
                                f["drag"], f["lift"], f["friction"])
        # membrane stiffness (N/m) -> tension per edge: each grid edge carries a strip of width h, the
        # edges along the swatch's border h/2 (so the strips add up to the swatch's width)
        if k_warp > 0 or k_cub > 0:
            force += _edge_forces(x, warp, rest_warp, k_warp * h * strip_warp, k_cub * h * strip_warp)
        if k_weft > 0 or k_cub > 0:
            force += _edge_forces(x, weft, rest_weft, k_weft * h * strip_weft, k_cub * h * strip_weft)
        d.xfrc_applied[fbody, :3] = force[free]

    out, true_corners, failure, wall = _drive(
        m, d, kin, corner_state, apply_forces if (air_on or k_eff > 0) else None,
        n_settle, n_frames, fps, substeps, dt_used, size, settle_bath,
    )
    n_done = len(out)
    if eff["grip_slip"]["on"] or eff["mocap_noise"]["on"]:
        # what motion capture reports: the commanded path (slip) plus sensor noise
        sigma = float(eff["mocap_noise"]["sigma"]) if eff["mocap_noise"]["on"] else 0.0
        if not (np.isfinite(sigma) and sigma >= 0):
            raise ClothRealityError(f"effects['mocap_noise']['sigma'] must be >= 0 m, got {sigma!r}")
        measured = measured + sigma * mocap_noise
    young, thick = _shell_parameters(f)
    truth = {
        "engine": f"mujoco {mujoco.__version__} flexcomp dim=2, integrator=discrete",
        "fabric": dict(fabric),
        "shell": {"young_pa": young, "thickness_m": thick, "mass_kg": f["areal_density"] * size * size},
        "motion": {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v) for k, v in mot.items()},
        "effects": eff,
        "corner_paths_true": true_corners,
        "corner_vertex_ids": ic,
        "rest_vertices": x0,
        "resolution": int(resolution),
        "size_m": float(size),
        "dt_s": dt_used,
        "substeps_per_frame": substeps,
        "settle_s": n_settle * dt_used,
        "wall_time_s": wall,
        "gravity": gravity.tolist(),
    }
    return ClothRealityRun(
        vertices=out, faces=faces, times=times[:n_done], corner_paths_measured=measured[:n_done],
        truth=truth, ok=failure is None, failure=failure,
    )


def _drive(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    kin: "_Kinematic",
    grip_state,
    apply_forces,
    n_settle: int,
    n_frames: int,
    fps: float,
    substeps: int,
    dt: float,
    scale: float,
    settle_bath: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, str | None, float]:
    """Settle at rest (velocities damped at ``settle_bath`` 1/s), then step with prescribed grips and record ``flexvert_xpos`` per frame.

    Returns:
        ``(vertices (T', N, 3), grips (T', G, 3), failure or None, wall seconds)`` with ``T'``
        the frames completed before a divergence (all ``n_frames`` when it did not diverge).
    """
    wall0 = time.perf_counter()
    failure = None
    out = np.empty((n_frames, m.nflexvert, 3))
    p_rest, _ = grip_state(0.0)
    grips = np.empty((n_frames,) + p_rest.shape)

    def step(p: np.ndarray, v: np.ndarray, t: float) -> None:
        kin.set(d, p, v)
        if apply_forces is not None:
            mujoco.mj_kinematics(m, d)
            mujoco.mj_flex(m, d)
            apply_forces(t)
        mujoco.mj_step(m, d)

    zero = np.zeros_like(p_rest)
    keep = float(np.exp(-settle_bath * dt))
    for _ in range(n_settle):  # settle at rest (t < 0: grips held still)
        step(p_rest, zero, 0.0)
        if settle_bath > 0:
            d.qvel[:] *= keep
    n_done = 0
    for frame in range(n_frames):
        if frame > 0:
            for k in range(substeps):
                t = (frame - 1) / fps + k * dt
                step(*grip_state(t), t)
        t = frame / fps
        pc, vc = grip_state(t)
        kin.set(d, pc, vc)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_flex(m, d)
        out[frame] = d.flexvert_xpos
        grips[frame] = pc
        reason = _diverged(out[frame], pc.mean(axis=0), scale) or _mujoco_unstable(d)
        if reason:
            failure = f"{reason} at t = {t:.3f} s (frame {frame})"
            break
        n_done = frame + 1
    return out[:n_done].copy(), grips[:n_done].copy(), failure, time.perf_counter() - wall0


class _VertexVelocity:
    """World velocities of flex vertex bodies that move on three slide joints."""

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, vbody: np.ndarray) -> None:
        j0 = m.body_jntadr[vbody]
        self.dof = np.stack([m.jnt_dofadr[j0 + k] for k in range(3)], axis=1)  # (N, 3)
        self.axes = np.stack([d.xaxis[j0 + k] for k in range(3)], axis=1)  # (N, 3 joints, 3)

    def __call__(self, d: mujoco.MjData) -> np.ndarray:
        return np.einsum("nk,nkc->nc", d.qvel[self.dof], self.axes)


# --------------------------------------------------------------------------------------- skirt
#: Skipping body (kinematic, known like motion capture). Units: m, Hz, rad. The waist bobs twice
#: per step (``bob * |sin(2 pi f t)|``, f = ``step_frequency``: a hop on each half of the step),
#: sways sideways (x), rolls (about y) and yaws (about z) once per stride (two steps), and the legs
#: (capsules from the hips) swing forward/back (about x) in opposition.
SKIRT_MOTIONS: dict[str, dict[str, Any]] = {
    "skip": {"waist": [0.0, 0.0, 1.0], "step_frequency": 2.2, "bob": 0.05, "sway": 0.03,
             "roll": 0.12, "yaw": 0.2, "leg_swing": 0.55, "hip_width": 0.18, "hip_drop": 0.08,
             "leg_length": 0.85, "leg_radius": 0.065, "ramp": 0.25},
}
_SKIRT_MOTION_KEYS = set(SKIRT_MOTIONS["skip"])

#: Skirt shape: a truncated cone hanging from the waist. Units: m.
SKIRT_SHAPE: dict[str, float] = {"waist_radius": 0.15, "hem_radius": 0.30, "length": 0.45}


def skirt_motion(name: str = "skip") -> dict[str, Any]:
    """A copy of a named skipping-body motion (see :data:`SKIRT_MOTIONS`)."""
    if name not in SKIRT_MOTIONS:
        raise ClothRealityError(f"skirt motion must be one of {sorted(SKIRT_MOTIONS)}, got {name!r}")
    return copy.deepcopy(SKIRT_MOTIONS[name])


def _check_skirt_motion(motion: dict[str, Any]) -> dict[str, Any]:
    if not isinstance(motion, dict):
        raise ClothRealityError(f"skirt motion must be a dict, got {type(motion).__name__}")
    unknown = set(motion) - _SKIRT_MOTION_KEYS - {"name"}
    missing = _SKIRT_MOTION_KEYS - set(motion)
    if unknown or missing:
        raise ClothRealityError(f"skirt motion keys: unknown {sorted(unknown)}, missing {sorted(missing)}")
    m = dict(motion)
    w = np.asarray(m["waist"], dtype=float)
    if w.shape != (3,) or not np.all(np.isfinite(w)):
        raise ClothRealityError(f"skirt motion['waist'] must be 3 finite numbers (m), got {m['waist']!r}")
    m["waist"] = w
    for k in ("leg_length", "leg_radius", "hip_width"):
        if not m[k] > 0:
            raise ClothRealityError(f"skirt motion['{k}'] must be > 0 m, got {m[k]!r}")
    return m


def _rot(roll: float, yaw: float) -> np.ndarray:
    cr, sr, cy, sy = np.cos(roll), np.sin(roll), np.cos(yaw), np.sin(yaw)
    ry = np.array([[cr, 0, sr], [0, 1, 0], [-sr, 0, cr]])  # roll about y
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry


def skirt_frames(motion: dict[str, Any], times: np.ndarray) -> dict[str, np.ndarray]:
    """Poses of the skipping body at the given times.

    Args:
        motion: a skirt motion dict (see :data:`SKIRT_MOTIONS`).
        times: ``(T,)`` seconds.

    Returns:
        ``{"waist_pos": (T, 3) m, "waist_rot": (T, 3, 3) world-from-waist rotation,
        "legs": (T, 2, 2, 3) hip and ankle points of the left/right leg capsules, m}``.
    """
    m = _check_skirt_motion(motion)
    t = np.asarray(times, dtype=float).reshape(-1)
    if m["ramp"] > 0:
        s = np.clip(t / m["ramp"], 0.0, 1.0)
        env = s * s * s * (10 - 15 * s + 6 * s * s)
    else:
        env = (t >= 0).astype(float)
    ph = np.pi * m["step_frequency"] * t
    pos = np.repeat(m["waist"][None, :], len(t), axis=0)
    pos[:, 0] += env * m["sway"] * np.sin(ph)
    pos[:, 2] += env * m["bob"] * np.abs(np.sin(2 * ph))
    rot = np.stack([_rot(e * m["roll"] * np.sin(p), e * m["yaw"] * np.sin(p + 0.5)) for e, p in zip(env, ph)])
    swing = env * m["leg_swing"] * np.sin(ph)
    legs = np.empty((len(t), 2, 2, 3))
    for k, (side, sgn) in enumerate(((-1.0, 1.0), (1.0, -1.0))):
        hip_local = np.array([side * 0.5 * m["hip_width"], 0.0, -m["hip_drop"]])
        a = sgn * swing  # leg angle about the waist x axis, forward (+y) when positive
        foot_local = hip_local[None, :] + m["leg_length"] * np.stack(
            [np.zeros_like(a), np.sin(a), -np.cos(a)], axis=1)
        legs[:, k, 0] = pos + np.einsum("tij,j->ti", rot, hip_local)
        legs[:, k, 1] = pos + np.einsum("tij,tj->ti", rot, foot_local)
    return {"waist_pos": pos, "waist_rot": rot, "legs": legs}


def _skirt_mesh(shape: dict[str, float], rings: int, around: int) -> tuple[np.ndarray, np.ndarray]:
    """Truncated-cone points in the waist frame (top ring at z = 0) and triangles."""
    r0, r1, L = shape["waist_radius"], shape["hem_radius"], shape["length"]
    drop = np.sqrt(max(L * L - (r1 - r0) ** 2, 1e-6))
    pts = []
    for i in range(rings):
        f = i / (rings - 1)
        r, z = r0 + (r1 - r0) * f, -drop * f
        for j in range(around):
            a = 2 * np.pi * j / around
            pts.append([r * np.cos(a), r * np.sin(a), z])
    tris = []
    for i in range(rings - 1):
        for j in range(around):
            a, b = i * around + j, i * around + (j + 1) % around
            c, e = a + around, b + around
            tris += [[a, c, b], [b, c, e]] if (i + j) % 2 == 0 else [[a, c, e], [a, e, b]]
    return np.asarray(pts, float), np.asarray(tris, np.int64)


def _capsule_depth(x: np.ndarray, a: np.ndarray, b: np.ndarray, r: float) -> np.ndarray:
    """Penetration depth (m, > 0 inside) of points ``x`` (N, 3) into capsule ``a``-``b``."""
    ab = b - a
    u = np.clip(((x - a) @ ab) / max(ab @ ab, 1e-12), 0.0, 1.0)
    return r - np.linalg.norm(x - (a + u[:, None] * ab), axis=1)


def simulate_skirt(
    fabric: dict[str, Any],
    motion: dict[str, Any],
    effects: dict[str, Any] | None,
    rng: np.random.Generator,
    n_frames: int = 50,
    fps: float = 30.0,
    rings: int = 9,
    around: int = 28,
    shape: dict[str, float] | None = None,
    dt: float = 0.002,
    settle: float = 1.0,
) -> ClothRealityRun:
    """A truncated-cone skirt of the given fabric on a skipping kinematic body.

    The skirt's top ring is held by the waist (heavy kinematic vertices following the waist's
    pose); the legs are capsule colliders on mocap bodies. Effects as in :func:`simulate_swatch`
    except ``grip_slip`` (the waistband does not slip) and the edge-spring effects (the skirt
    mesh has no warp/weft grid): those raise an error when switched on.

    Args:
        fabric: fabric dict (see :data:`FABRICS`).
        motion: skipping-body dict (see :data:`SKIRT_MOTIONS`).
        effects: effects dict or None (all off).
        rng: random generator (gust phases).
        n_frames, fps: output frames and rate (Hz).
        rings, around: mesh resolution (rings from waist to hem, vertices around).
        shape: ``{"waist_radius", "hem_radius", "length"}`` in m; default :data:`SKIRT_SHAPE`.
        dt: MuJoCo time step, s (rounded down to divide the frame interval).
        settle: rest time before frame 0, s.

    Returns:
        :class:`ClothRealityRun`; ``corner_paths_measured`` is ``(T, 0, 3)`` and ``colliders``
        holds the leg capsules per frame (the known body motion) and the waist pose.
    """
    f = _check_fabric(fabric)
    mot = _check_skirt_motion(motion)
    eff = resolve_effects(effects)
    for name in ("grip_slip", "anisotropy", "strain_stiffening", "mocap_noise"):
        # mocap_noise: the skirt's known body motion is handed to the model exactly (not noised)
        if eff[name]["on"]:
            raise ClothRealityError(f"effect {name!r} is not available for the skirt")
    shp = dict(SKIRT_SHAPE if shape is None else shape)
    if set(shp) != set(SKIRT_SHAPE) or not all(float(v) > 0 for v in shp.values()):
        raise ClothRealityError(f"shape must give positive {sorted(SKIRT_SHAPE)}, got {shape!r}")
    if not (isinstance(rings, (int, np.integer)) and rings >= 3 and isinstance(around, (int, np.integer)) and around >= 8):
        raise ClothRealityError(f"rings must be >= 3 and around >= 8, got {rings}, {around}")
    if not (isinstance(n_frames, (int, np.integer)) and n_frames >= 1 and fps > 0 and dt > 0 and settle >= 0):
        raise ClothRealityError("n_frames >= 1, fps > 0, dt > 0 and settle >= 0 are required")
    gust_phases = rng.uniform(0, 2 * np.pi, 3)
    times = np.arange(n_frames) / fps
    pts_local, tris = _skirt_mesh(shp, rings, around)
    fr0 = skirt_frames(mot, np.array([0.0]))
    pts0 = fr0["waist_pos"][0] + pts_local @ fr0["waist_rot"][0].T
    r0, r1, L = shp["waist_radius"], shp["hem_radius"], shp["length"]
    area = np.pi * (r0 + r1) * L
    young, thick = _shell_parameters(f)
    substeps = max(1, int(np.ceil((1.0 / fps) / dt - 1e-9)))
    dt_used = (1.0 / fps) / substeps
    n_settle = int(round(settle / dt_used))
    g = _gravity(eff)
    legs0 = fr0["legs"][0]
    rad = float(mot["leg_radius"])
    leg_xml = "".join(
        f'<body name="leg{k}" mocap="true" pos="0 0 0"><geom name="leg{k}" type="capsule" '
        f'fromto="{" ".join(map(str, legs0[k, 0]))} {" ".join(map(str, legs0[k, 1]))}" size="{rad}" '
        f'contype="1" conaffinity="1" rgba=".8 .6 .5 1"/></body>'
        for k in range(2)
    )
    xml = f"""
<mujoco model="skirt">
  <option timestep="{dt_used}" integrator="discrete" solver="Newton" tolerance="1e-10"
          gravity="{g[0]} {g[1]} {g[2]}"/>
  <size memory="128M"/>
  <worldbody>
    {leg_xml}
    <flexcomp name="skirt" type="direct" dim="2" point="{" ".join(map(str, pts0.ravel()))}"
              element="{" ".join(map(str, tris.ravel()))}" mass="{f['areal_density'] * area}" radius="0.012">
      <contact contype="1" conaffinity="1" selfcollide="none" condim="3" friction="0.4"
               solref="0.004 1" margin="0.002"/>
      <edge equality="false"/>
      <elasticity young="{young}" poisson="{f['poisson']}" thickness="{thick}"
                  damping="{f['damping']}" elastic2d="both"{_yield_attr(eff)}/>
    </flexcomp>
  </worldbody>
</mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    x0 = d.flexvert_xpos.copy()
    faces = m.flex_elem.reshape(-1, 3).astype(np.int64)
    vbody = m.flex_vertbodyid.astype(np.int64)
    top = np.arange(around)
    _make_grips(m, d, [int(vbody[i]) for i in top])
    kin = _Kinematic(m, d, [int(vbody[i]) for i in top])
    vel_of = _VertexVelocity(m, d, vbody)
    free = np.ones(len(x0), bool)
    free[top] = False
    fbody = vbody[free]
    air_on = bool(eff["air_drag"]["on"])  # wind needs it (resolve_effects)
    rho = float(eff["air_drag"]["density"])
    leg_mocap = [int(m.body_mocapid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"leg{k}")]) for k in range(2)]
    # mocap leg bodies: geoms are placed in world coordinates at t = 0; move the body by the
    # rigid transform of each leg relative to its t = 0 pose.
    leg_axis0 = [legs0[k, 1] - legs0[k, 0] for k in range(2)]

    def waist_pts(t: float) -> np.ndarray:
        fr = skirt_frames(mot, np.array([t]))
        return fr["waist_pos"][0] + pts_local[top] @ fr["waist_rot"][0].T, fr["legs"][0]

    def grip_state(t: float) -> tuple[np.ndarray, np.ndarray]:
        e = 1e-4
        pm, lm = waist_pts(t - e)
        pc, legs = waist_pts(t)
        pp, lp = waist_pts(t + e)
        for k in range(2):  # legs follow kinematically (mocap: position + orientation)
            q = _quat_between(leg_axis0[k], legs[k, 1] - legs[k, 0])
            rot = np.empty(9)
            mujoco.mju_quat2Mat(rot, q)
            d.mocap_quat[leg_mocap[k]] = q
            d.mocap_pos[leg_mocap[k]] = legs[k, 0] - rot.reshape(3, 3) @ legs0[k, 0]
        return pc, (pp - pm) / (2 * e)

    def apply_forces(t: float) -> None:
        x = d.flexvert_xpos
        force = air_forces(x, vel_of(d), faces, _wind_at(eff, t, gust_phases), rho,
                           f["drag"], f["lift"], f["friction"])
        d.xfrc_applied[fbody, :3] = force[free]

    out, _, failure, wall = _drive(
        m, d, kin, grip_state, apply_forces if air_on else None,
        n_settle, n_frames, fps, substeps, dt_used, L + r1,
    )
    n_done = len(out)
    body = skirt_frames(mot, times[:n_done])
    depth = np.array([max(_capsule_depth(out[i], body["legs"][i, k, 0], body["legs"][i, k, 1], rad).max()
                          for k in range(2)) for i in range(n_done)]) if n_done else np.zeros(0)
    truth = {
        "engine": f"mujoco {mujoco.__version__} flexcomp dim=2 (direct), integrator=discrete",
        "fabric": dict(fabric),
        "shell": {"young_pa": young, "thickness_m": thick, "mass_kg": f["areal_density"] * area},
        "shape": shp,
        "motion": {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v) for k, v in mot.items()},
        "effects": eff,
        "waist_vertex_ids": top.tolist(),
        "rest_vertices": x0,
        "max_leg_penetration_m": depth,
        "rings": int(rings),
        "around": int(around),
        "dt_s": dt_used,
        "substeps_per_frame": substeps,
        "settle_s": n_settle * dt_used,
        "wall_time_s": wall,
        "gravity": g.tolist(),
    }
    return ClothRealityRun(
        vertices=out, faces=faces, times=times[:n_done], corner_paths_measured=np.zeros((n_done, 0, 3)),
        truth=truth, ok=failure is None, failure=failure,
        colliders={"capsules": body["legs"], "radii": np.full(2, rad),
                   "waist_ring": body["waist_pos"][:, None, :] + np.einsum("tij,nj->tni", body["waist_rot"], pts_local[top]),
                   "waist_pos": body["waist_pos"], "waist_rot": body["waist_rot"]},
    )


def _quat_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) rotating direction ``a`` onto direction ``b``."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    c = np.cross(a, b)
    w = 1.0 + float(a @ b)
    if w < 1e-9:  # opposite: rotate pi about any axis perpendicular to a
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        q = np.concatenate([[0.0], axis / np.linalg.norm(axis)])
    else:
        q = np.concatenate([[w], c])
    return q / np.linalg.norm(q)
