"""Reality for rigid bodies: a T-object thrown through the air, simulated by MuJoCo, filmed by pyrender.

MuJoCo is an engine independent of the estimator's own Newton-Euler integrator. The world has
z up and gravity (0, 0, -9.81); the camera looks roughly along world +y with a random tilt (pitch)
and roll that the estimator does not know (it works in the camera frame and estimates gravity's
direction there). Effects, each off by default and scaled from config (:class:`RigidEffects`):

* ``drag`` / ``angular_drag`` / ``magnus`` / ``wind``: MuJoCo's ellipsoid fluid model (air density
  1.2 kg/m^3, viscosity 1.8e-5 Pa s) on each box, so drag also twists the body; ``drag`` scales the
  blunt and slender drag and the Kutta lift coefficients, ``angular_drag`` the rotational drag,
  ``magnus`` the Magnus lift coefficient (MuJoCo defaults 0.5, 0.25, 1.0, 1.5, 1.0 at scale 1);
  ``wind`` (world m/s) acts through them;
* ``com_offset``: the true centre of mass sits this far (body axes, metres) from where
  ``meta.yaml`` says;
* ``lens_k1``: radial distortion the calibration does not know;
* ``exposure``: motion blur, the frame is the mean of renders across the exposure (seconds);
* ``rolling_shutter``: row ``r`` is exposed ``r / H * rolling_shutter`` seconds after row 0
  (rendered as 48 horizontal slabs, each at its middle row's time);
* ``time_jitter``: std (seconds) of the true capture times around the nominal times written to
  the footage.

The clip starts with ``n_background`` background-only frames (the object is still out of view)
as a real recording would. The truth (initial state in the camera frame at the first throw
frame, gravity angles, effect settings, true capture times) is returned separately and must be
written beside the footage, never inside it.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field

import mujoco
import numpy as np

from vidsim.reality.imaging import sensor, textured_wall
from vidsim.rigid.body import BoxBody, RigidBodyError, t_object
from vidsim.rigid.dynamics import gravity_angles, quat_to_rot, rot_to_quat
from vidsim.video.camera import PinholeCamera, intrinsics

#: renders averaged over a blurred frame's exposure, evenly spaced over it, both ends included
BLUR_SAMPLES = 7

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

AIR_DENSITY = 1.2
AIR_VISCOSITY = 1.8e-5
MJ_TIMESTEP = 5e-4
G = 9.81


@dataclass
class RigidEffects:
    """Reality effects, all off by default (see module docstring for units)."""

    drag: float = 0.0
    angular_drag: float = 0.0
    magnus: float = 0.0
    wind: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    com_offset: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    lens_k1: float = 0.0
    exposure: float = 0.0
    rolling_shutter: float = 0.0
    time_jitter: float = 0.0

    def validate(self) -> None:
        """Raise :class:`RigidBodyError` naming the field when a setting is not physical."""
        for name in ("drag", "angular_drag", "magnus", "exposure", "rolling_shutter", "time_jitter"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise RigidBodyError(f"effects: '{name}' must be finite and >= 0, got {v}")
        for name in ("wind", "com_offset"):
            v = np.asarray(getattr(self, name), float)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise RigidBodyError(f"effects: '{name}' must be 3 finite numbers, got {getattr(self, name)}")
        if not (np.isfinite(self.lens_k1) and abs(self.lens_k1) < 1.0):
            raise RigidBodyError(f"effects: 'lens_k1' must be in (-1, 1), got {self.lens_k1}")
        if np.any(np.asarray(self.wind, float) != 0) and not self.air_on:
            # the wind acts only through MuJoCo's air model, which the coefficients switch on
            raise RigidBodyError(f"effects: 'wind' {list(self.wind)} acts through the air, but air_drag, angular_drag "
                                 f"and magnus are all 0 (the air is off): switch one of them on, or set wind to 0")

    @property
    def air_on(self) -> bool:
        """Whether MuJoCo's ellipsoid air model is on (any of drag, angular drag, Magnus above 0).
        The model then also applies its added-mass (virtual inertia) forces, which no coefficient
        scales: air at 1.2 kg/m^3 moves the throw by about 1 cm over 40 frames through them alone.
        So going from 0 to a tiny coefficient is not continuous; every air case carries the added
        mass, and the suite's "none" cases, in vacuum, do not."""
        return self.drag > 0 or self.angular_drag > 0 or self.magnus > 0

    @classmethod
    def from_schema(cls, dynamics: dict | None = None, imaging: dict | None = None) -> "RigidEffects":
        """From the project's ``effects`` config group (``dynamics`` and ``imaging`` sections)."""
        d = dict(dynamics or {})
        i = dict(imaging or {})
        known_d = {"air_drag", "angular_drag", "magnus", "wind", "com_offset", "gravity_tilt_deg"}
        known_i = {"lens_k1", "exposure_s", "rolling_shutter_s", "time_jitter_s", "time_offset_s"}
        for sec, given, known in (("dynamics", d, known_d), ("imaging", i, known_i)):
            unknown = sorted(set(given) - known)
            if unknown:
                raise RigidBodyError(f"effects.{sec}: unknown field(s) {unknown} (known: {sorted(known)})")
        for sec, given, name in (("dynamics", d, "gravity_tilt_deg"), ("imaging", i, "time_offset_s")):
            if float(given.get(name, 0.0) or 0.0) != 0.0:
                # accepted by the shared schema (the demo scene uses time_offset_s), not made by this reality:
                # footage filmed without it would silently be a case without the effect
                raise RigidBodyError(f"effects.{sec}.{name} = {given[name]}: the rigid reality does not make this "
                                     f"effect (the thrown body's gravity direction and clock are estimated/fitted "
                                     f"anyway); set it to 0")
        return cls(drag=float(d.get("air_drag", 0.0)), angular_drag=float(d.get("angular_drag", 0.0)),
                   magnus=float(d.get("magnus", 0.0)), wind=list(d.get("wind", [0.0, 0.0, 0.0])),
                   com_offset=list(d.get("com_offset", [0.0, 0.0, 0.0])), lens_k1=float(i.get("lens_k1", 0.0)),
                   exposure=float(i.get("exposure_s", 0.0)), rolling_shutter=float(i.get("rolling_shutter_s", 0.0)),
                   time_jitter=float(i.get("time_jitter_s", 0.0)))


@dataclass
class RigidRealityConfig:
    """Scene settings of a synthetic throw.

    Attributes:
        n_frames: frames of the throw; n_background: background-only frames before it.
        fps: nominal frame rate, Hz.
        width, height: image size, pixels; focal: focal length, pixels.
        distance: camera to the middle of the trajectory, metres.
        max_tilt_deg, max_roll_deg: camera pitch and roll relative to gravity, uniform in +-.
        spin: range of the initial spin magnitude, rad/s.
        noise_sigma: sensor noise, digital numbers; jpeg_quality: 0 disables compression.
    """

    n_frames: int = 40
    n_background: int = 30
    fps: float = 30.0
    width: int = 640
    height: int = 480
    focal: float = 640.0
    distance: float = 3.2
    max_tilt_deg: float = 8.0
    max_roll_deg: float = 8.0
    spin: tuple[float, float] = (4.0, 10.0)
    noise_sigma: float = 2.0
    jpeg_quality: int = 90

    def validate(self) -> None:
        """Raise :class:`RigidBodyError` naming the field when a setting is not usable."""
        for name in ("n_frames", "fps", "width", "height", "focal", "distance"):
            if not getattr(self, name) > 0:
                raise RigidBodyError(f"reality: '{name}' must be positive, got {getattr(self, name)}")
        if self.n_background < 0:
            raise RigidBodyError(f"reality: 'n_background' must be >= 0, got {self.n_background}")

    @classmethod
    def from_schema(cls, d: dict) -> "RigidRealityConfig":
        """From the ``rigid.reality`` config section (:class:`vidsim.config.rigid.RigidSceneConfig`)."""
        d = dict(d)
        spin = (float(d.pop("spin_min", 4.0)), float(d.pop("spin_max", 10.0)))
        known = {f for f in cls.__dataclass_fields__ if f != "spin"}
        unknown = sorted(set(d) - known)
        if unknown:
            raise RigidBodyError(f"reality: unknown field(s) {unknown} (known: {sorted(known)})")
        return cls(**d, spin=spin)


# ----------------------------------------------------------------------------- MuJoCo
def mujoco_xml(body: BoxBody, effects: RigidEffects) -> str:
    """MJCF of the free body (boxes as geoms, explicit inertial at the true centre of mass)."""
    fluid = effects.air_on  # MuJoCo's ellipsoid model, added mass included (RigidEffects.air_on)
    dens = AIR_DENSITY if fluid else 0.0
    visc = AIR_VISCOSITY if fluid else 0.0
    wind = " ".join(f"{w:.9g}" for w in effects.wind)
    # fluidcoef: blunt drag, slender drag, angular drag, Kutta lift, Magnus lift (MuJoCo defaults 0.5 0.25 1.5 1 1)
    coef = f"{0.5 * effects.drag:.9g} {0.25 * effects.drag:.9g} {1.5 * effects.angular_drag:.9g} " \
           f"{1.0 * effects.drag:.9g} {1.0 * effects.magnus:.9g}"
    geoms = []
    for c, h in zip(body.centers, body.half_sizes):
        fl = f' fluidshape="ellipsoid" fluidcoef="{coef}"' if fluid else ""
        geoms.append(f'<geom type="box" pos="{c[0]:.9g} {c[1]:.9g} {c[2]:.9g}" '
                     f'size="{h[0]:.9g} {h[1]:.9g} {h[2]:.9g}" contype="0" conaffinity="0"{fl}/>')
    I = body.inertia
    off = np.asarray(effects.com_offset, float)
    inertial = (f'<inertial pos="{off[0]:.9g} {off[1]:.9g} {off[2]:.9g}" mass="{body.mass:.9g}" '
                f'fullinertia="{I[0, 0]:.9g} {I[1, 1]:.9g} {I[2, 2]:.9g} {I[0, 1]:.9g} {I[0, 2]:.9g} {I[1, 2]:.9g}"/>')
    return f"""<mujoco model="thrown_t">
  <option timestep="{MJ_TIMESTEP}" integrator="RK4" gravity="0 0 {-G}" density="{dens}" viscosity="{visc}" wind="{wind}"/>
  <worldbody>
    <body name="T">
      <freejoint/>
      {inertial}
      {''.join(geoms)}
    </body>
  </worldbody>
</mujoco>"""


def simulate_mujoco(body: BoxBody, effects: RigidEffects, x0: np.ndarray, q0: np.ndarray, v0: np.ndarray,
                    w0_world: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Poses of the body frame (the stated centre of mass) at the requested times, world frame.

    Args:
        body: the body; effects: reality effects.
        x0: (3,) initial body-frame origin, world metres; q0: (4,) orientation (w, x, y, z).
        v0: (3,) initial velocity of the body-frame origin, m/s; w0_world: (3,) spin, world rad/s.
        times: (T,) seconds after the initial state, any order (>= 0).

    Returns:
        positions (T, 3) and quaternions (T, 4) at ``times``.
    """
    times = np.asarray(times, float)
    if np.any(times < 0) or not np.all(np.isfinite(times)):
        raise RigidBodyError("simulate_mujoco: times must be finite and >= 0")
    model = mujoco.MjModel.from_xml_string(mujoco_xml(body, effects))
    data = mujoco.MjData(model)
    R0 = quat_to_rot(np.asarray(q0, float))
    data.qpos[:3] = x0
    data.qpos[3:7] = np.asarray(q0, float) / np.linalg.norm(q0)
    # free joint: qvel[:3] is the velocity of the body-frame origin, qvel[3:] the spin in body axes
    data.qvel[:3] = v0
    data.qvel[3:6] = R0.T @ np.asarray(w0_world, float)
    # the initial state is that of the body-frame origin (the stated centre of mass, as meta.yaml
    # defines it); with a centre-of-mass offset MuJoCo's true centre moves on a parabola instead
    mujoco.mj_forward(model, data)
    order = np.argsort(times)
    pos = np.zeros((len(times), 3))
    quat = np.zeros((len(times), 4))
    t = 0.0
    for idx in order:
        target = times[idx]
        while target - t > 1e-12:
            h = min(MJ_TIMESTEP, target - t)
            model.opt.timestep = h
            mujoco.mj_step(model, data)
            t += h
        model.opt.timestep = MJ_TIMESTEP
        pos[idx] = data.qpos[:3]
        quat[idx] = data.qpos[3:7]
    return pos, quat


# ----------------------------------------------------------------------------- throw
@dataclass
class Throw:
    """A generated throw.

    Attributes:
        frames: (N, H, W, 3) uint8 footage; times: (N,) nominal frame times written to the footage.
        camera: the calibration (ideal lens, world frame = camera frame).
        meta: known inputs (object, frame rate).
        truth: initial state in the camera frame at ``truth['t0']``, gravity angles, effects,
            true capture times (never shown to the estimator).
        masks: (N, H, W) bool ground-truth silhouettes (for scoring segmentation).
        true_camera: the camera that really filmed (world z up, with the lens effect): truth only.
    """

    frames: np.ndarray
    times: np.ndarray
    camera: PinholeCamera
    meta: dict
    truth: dict
    masks: np.ndarray
    true_camera: PinholeCamera | None = None


def sample_truth(rng: np.random.Generator, cfg: RigidRealityConfig) -> dict:
    """Random camera attitude and initial state (world frame, z up) of a throw spanning the view."""
    tilt = np.radians(rng.uniform(-cfg.max_tilt_deg, cfg.max_tilt_deg))
    roll = np.radians(rng.uniform(-cfg.max_roll_deg, cfg.max_roll_deg))
    R0 = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # world x right, z up, y forward
    ct, st, cr, sr = np.cos(tilt), np.sin(tilt), np.cos(roll), np.sin(roll)
    Rx = np.array([[1, 0, 0], [0, ct, -st], [0, st, ct]])
    Rz = np.array([[cr, -sr, 0], [sr, cr, 0], [0, 0, 1]])
    Rc = Rz @ Rx @ R0
    C = np.array([0.0, 0.0, 1.2])
    T = (cfg.n_frames - 1) / cfg.fps
    mid = C + cfg.distance * Rc[2]  # on the optical axis
    vz = G * T / 2.0
    vx = rng.uniform(-0.8, 0.8)
    vy = rng.uniform(-0.3, 0.3)
    rise = G * (T / 2) ** 2 / 2
    start = mid + np.array([-vx * T / 2, -vy * T / 2, -rise / 2])
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    q = q if q[0] >= 0 else -q
    w = rng.normal(size=3)
    w *= rng.uniform(*cfg.spin) / np.linalg.norm(w)
    return {"R_cam": Rc, "C_cam": C, "x0": start, "q0": q, "v0": np.array([vx, vy, vz]), "w0": w}


def _world_to_camera_state(s: dict) -> dict:
    Rc, C = s["R_cam"], s["C_cam"]
    X = Rc @ (s["x0"] - C)
    Rb = Rc @ quat_to_rot(s["q0"])
    g_cam = Rc @ np.array([0.0, 0.0, -G])
    tilt, roll = gravity_angles(g_cam)
    return {"position": X.tolist(), "quaternion": rot_to_quat(Rb).tolist(), "velocity": (Rc @ s["v0"]).tolist(),
            "omega_world": (Rc @ s["w0"]).tolist(), "tilt": tilt, "roll": roll, "gravity": g_cam.tolist()}


def make_throw(seed: int, cfg: RigidRealityConfig | None = None, effects: RigidEffects | None = None,
               render: bool = True) -> Throw:
    """Simulate and film one throw.

    Args:
        seed: seeds the truth, the background texture and the sensor noise.
        cfg: scene settings; effects: reality effects (default: none).
        render: False skips pyrender (frames are zeros) and draws only the masks with the fast
            rasteriser, for quick tests of the estimator on exact silhouettes (refused with an exposure
            or a rolling shutter, which only rendering makes). The returned truth masks are the
            instantaneous silhouettes at each capture time (row 0's for a rolling shutter, the
            exposure's centre for a blur), so a segmentation IoU scored against them on blurred or
            skewed footage includes the effect's own smear.

    Returns:
        :class:`Throw`.
    """
    cfg = cfg or RigidRealityConfig()
    effects = effects or RigidEffects()
    cfg.validate()
    effects.validate()
    if not render and (effects.exposure > 0 or effects.rolling_shutter > 0):
        # without pyrender only the instantaneous masks are drawn: the effect would silently be missing
        raise RigidBodyError(f"effects: exposure {effects.exposure} s and rolling_shutter {effects.rolling_shutter} s "
                             f"are made only by rendering (render=True); the mask-only path would drop them")
    rng = np.random.default_rng(seed)
    body, _ = t_object()
    s = sample_truth(rng, cfg)
    Rc, C = s["R_cam"], s["C_cam"]
    K = intrinsics(cfg.focal, None, (cfg.width - 1) / 2, (cfg.height - 1) / 2)
    calib = PinholeCamera(K, np.eye(3), np.zeros(3), cfg.width, cfg.height)  # world = camera frame
    lens = PinholeCamera(K, Rc, -Rc @ C, cfg.width, cfg.height, [effects.lens_k1, 0, 0, 0, 0])
    n_bg, n = cfg.n_background, cfg.n_frames
    nominal = np.arange(n_bg + n) / cfg.fps
    t_throw0 = n_bg / cfg.fps
    actual = nominal + (rng.normal(0, effects.time_jitter, nominal.shape) if effects.time_jitter > 0 else 0.0)
    # sub-samples: exposure (blur) x rolling-shutter slabs
    n_exp = 1 if effects.exposure <= 0 else BLUR_SAMPLES
    # 48 slabs of 10 rows at 480 px: close to a per-row read-out (12 slabs, used until session 18,
    # left a staircase that a model with a finer read-out cannot match: docs/gap.md)
    n_rs = 1 if effects.rolling_shutter <= 0 else 48
    exp_off = (np.linspace(-0.5, 0.5, n_exp) * effects.exposure) if n_exp > 1 else np.zeros(1)
    rs_off = (np.arange(n_rs) + 0.5) / n_rs * effects.rolling_shutter if n_rs > 1 else np.zeros(1)
    sub = actual[n_bg:, None, None] + exp_off[None, :, None] + rs_off[None, None, :] - t_throw0
    # before release the object is out of view (not rendered); the throw starts at the first throw frame
    pos, quat = simulate_mujoco(body, effects, s["x0"], s["q0"], s["v0"], s["w0"], np.maximum(sub.ravel(), 0.0))
    pos = pos.reshape(sub.shape + (3,))
    quat = quat.reshape(sub.shape + (4,))
    pos_c, quat_c = simulate_mujoco(body, effects, s["x0"], s["q0"], s["v0"], s["w0"],
                                    np.maximum(actual[n_bg:] - t_throw0, 0.0))
    Vb, F = body.mesh()
    H, W = cfg.height, cfg.width
    frames = np.zeros((n_bg + n, H, W, 3), np.uint8)
    masks = np.zeros((n_bg + n, H, W), bool)
    if render:
        from vidsim.render.scene import DirectionalLight, MeshItem, Renderer, textured_plane

        wall_tex = textured_wall(1024, 768, rng)
        fwd = Rc[2].copy()
        fwd[2] = 0.0
        fwd /= np.linalg.norm(fwd)
        wall = textured_plane(C + (cfg.distance + 2.5) * fwd, -fwd, [0, 0, 1], (12.0, 9.0), wall_tex)
        lights = [DirectionalLight(direction=[0.3, 0.6, -0.75], intensity=3.0),
                  DirectionalLight(direction=[-0.5, 0.7, 0.2], intensity=1.2)]
        with Renderer(W, H) as r:
            bg = r.render([wall], lens, lights=lights).color
            noise_rng = np.random.default_rng(seed + 7919)
            for k in range(n_bg):
                frames[k] = sensor(bg, noise_rng, cfg.noise_sigma, cfg.jpeg_quality)
            for k in range(n):
                acc = np.zeros((H, W, 3), np.float64)
                for e in range(n_exp):
                    slabs = []
                    for j in range(n_rs):
                        Vw = Vb @ quat_to_rot(quat[k, e, j]).T + pos[k, e, j]
                        item = MeshItem(Vw, F, color=(0.85, 0.35, 0.1), name="T")
                        slabs.append(r.render([wall, item], lens, lights=lights).color)
                    img = slabs[0].copy()
                    for j in range(1, n_rs):
                        r0 = int(round(j * H / n_rs))
                        img[r0:] = slabs[j][r0:]
                    acc += img
                frame = np.clip(np.rint(acc / n_exp), 0, 255).astype(np.uint8)
                frames[n_bg + k] = sensor(frame, noise_rng, cfg.noise_sigma, cfg.jpeg_quality)
                Vw = Vb @ quat_to_rot(quat_c[k]).T + pos_c[k]
                masks[n_bg + k] = r.render([wall, MeshItem(Vw, F, name="T")], lens, lights=lights).mask
    else:
        from vidsim.render.raster import silhouette_batch

        Vs = np.stack([Vb @ quat_to_rot(q).T + p for p, q in zip(pos_c, quat_c)])
        masks[n_bg:] = silhouette_batch(Vs, F, lens)
    cam_state = _world_to_camera_state(s)
    truth = {
        "t0": float(t_throw0),
        **cam_state,
        "camera_tilt_deg": float(np.degrees(np.arcsin(np.clip(Rc[2, 2], -1, 1)))),
        "effects": asdict(effects),
        "capture_times": actual.tolist(),
        "seed": int(seed),
        "note": "initial state of the body-frame origin (the stated centre of mass) in the camera frame at t0",
    }
    meta = {"object": body.to_meta(), "fps": cfg.fps,
            "gravity_magnitude": G, "kind": "rigid"}
    return Throw(frames, nominal, calib, meta, truth, masks, lens)
