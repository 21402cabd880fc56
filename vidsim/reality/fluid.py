"""Synthetic fluid footage with known velocity: a waterfall, a stream with a boat, a flame.

Reality side of the fluid pipeline: a stable-fluids solver (:mod:`vidsim.fluid.stable`; Stam's
approximate projection, so nearly but not exactly incompressible, least so next to obstacles and
walls) with obstacles advects a foam-like noise texture and dye; the
frames are rendered with a static background and camera noise, and the true per-frame
velocity (pixels per frame, the field that moved the texture from frame t to t+1) is kept
apart as truth. Estimators must read only ``frames``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.ndimage import gaussian_filter

from vidsim.fluid.stable import advect_scalar, advect_velocity, project

SCENES = ("waterfall", "stream_boat", "flame")


class FluidSceneError(ValueError):
    """Unknown scene or invalid scene parameter."""


@dataclass
class FluidFootage:
    """Rendered fluid footage plus its truth.

    Attributes:
        frames: ``(T, H, W, 3)`` uint8 RGB.
        velocity: ``(T-1, H, W, 2)`` float32 true flow (px/frame) from frame t to t+1 (truth).
        solid: ``(H, W)`` bool obstacle cells (rocks, boat), zero velocity.
        dye: ``(T, H, W)`` float32 fluid fraction in [0, 1] (truth; 1 = water/fire visible).
        ok: False when the solver produced a non-finite value (the footage is then unusable).
        meta: scene name, seed, size and the solver settings.
    """

    frames: np.ndarray
    velocity: np.ndarray
    solid: np.ndarray
    dye: np.ndarray
    ok: bool = True
    meta: dict[str, Any] = field(default_factory=dict)


def _disk(h: int, w: int, cx: float, cy: float, rx: float, ry: float) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w]
    return ((xx - cx) / rx) ** 2 + ((yy - cy) / ry) ** 2 <= 1.0


def _smooth_noise(rng: np.random.Generator, shape: tuple[int, ...], sigma: float) -> np.ndarray:
    n = gaussian_filter(rng.standard_normal(shape), sigma)
    return n / (n.std() + 1e-12)


def make_scene(
    name: str, size: int = 128, n_frames: int = 120, seed: int = 0, warmup: int | None = None,
    noise_sigma: float = 1.5, jacobi_iters: int = 60,
) -> FluidFootage:
    """Simulate and render one scene.

    Args:
        name: ``"waterfall"`` (a sheet falling over rocks), ``"stream_boat"`` (a stream flowing
            left to right past a boat) or ``"flame"`` (a buoyant plume rising from a burner).
        size: grid and image side in pixels (square).
        n_frames: recorded frames T (>= 2).
        seed: seed of the turbulence, texture and camera noise.
        warmup: solver frames run before recording, so that the flow is developed
            (default: 160 for the waterfall, 80 otherwise).
        noise_sigma: camera noise standard deviation in grey levels.
        jacobi_iters: pressure iterations per frame.

    Returns:
        :class:`FluidFootage`; ``ok`` is False (and no exception is raised) if the solver diverged.
    """
    if name not in SCENES:
        raise FluidSceneError(f"scene={name!r}, expected one of {SCENES}")
    if size < 32:
        raise FluidSceneError(f"size={size}, expected >= 32")
    if n_frames < 2:
        raise FluidSceneError(f"n_frames={n_frames}, expected >= 2")
    if warmup is None:
        warmup = 160 if name == "waterfall" else 80
    if warmup < 0:
        raise FluidSceneError(f"warmup={warmup}, expected >= 0")
    rng = np.random.default_rng(seed)
    h = w = size
    s = size / 128.0
    solid = np.zeros((h, w), bool)
    open_ = np.zeros((h, w), bool)
    inflow = np.zeros((h, w), bool)
    u_in = np.zeros(2)
    gravity = np.zeros(2)
    vmax = 3.0 * s
    cool = 1.0
    if name == "waterfall":
        open_[-1, :] = True
        inflow[0:3, int(0.38 * w):int(0.62 * w)] = True
        u_in[:] = (0.0, 1.2 * s)
        gravity[:] = (0.0, 0.03 * s)
        for cx, cy, r in ((0.40, 0.70, 0.07), (0.62, 0.78, 0.06), (0.50, 0.90, 0.05)):
            solid |= _disk(h, w, cx * w, cy * h, r * w, r * h)
        bg_col, fg_lo, fg_hi = np.array([70, 62, 55.0]), np.array([40, 90, 140.0]), np.array([235, 240, 245.0])
    elif name == "stream_boat":
        open_[:, -1] = True
        inflow[2:-2, 0:2] = True
        u_in[:] = (1.4 * s, 0.0)
        solid[0, :] = solid[-1, :] = True
        solid |= _disk(h, w, 0.38 * w, 0.5 * h, 0.13 * w, 0.055 * h)
        bg_col, fg_lo, fg_hi = np.array([110, 80, 50.0]), np.array([20, 60, 85.0]), np.array([200, 225, 230.0])
    else:  # flame
        open_[0, :] = True
        inflow[-3:, int(0.44 * w):int(0.56 * w)] = True
        u_in[:] = (0.0, -1.0 * s)
        gravity[:] = (0.0, -0.05 * s)  # buoyancy: hot gas accelerates upward
        cool = 0.985
        bg_col, fg_lo, fg_hi = np.array([15, 12, 20.0]), np.array([180, 40, 5.0]), np.array([255, 230, 120.0])
    boat_col = np.array([120, 60, 30.0])

    u = np.zeros((h, w, 2))
    u[inflow] = u_in
    dye = np.zeros((h, w))
    if name == "stream_boat":
        dye[:] = 1.0
    foam = _smooth_noise(rng, (h, w), 2.0 * s)
    background = bg_col + 25.0 * _smooth_noise(rng, (h, w), 3.0 * s)[..., None]
    total = warmup + n_frames
    frames = np.empty((n_frames, h, w, 3), np.uint8)
    vel = np.empty((n_frames - 1, h, w, 2), np.float32)
    dyes = np.empty((n_frames, h, w), np.float32)
    ok = True
    for k in range(total):
        u = advect_velocity(u)
        u += gravity * dye[..., None]
        u += (0.02 * s) * np.stack([_smooth_noise(rng, (h, w), 4.0 * s) for _ in range(2)], -1) * (dye[..., None] > 0.05)
        u[inflow] = u_in
        project(u, solid, open_, jacobi_iters)
        u[inflow] = u_in
        sp = np.linalg.norm(u, axis=-1, keepdims=True)
        u *= np.minimum(1.0, vmax / np.maximum(sp, 1e-12))
        if not np.isfinite(u).all():
            ok = False
            break
        t = k - warmup
        if t >= 0:
            dyes[t] = dye
            a = np.clip(dye, 0, 1)[..., None]
            tone = (0.5 + 0.5 * np.tanh(1.2 * foam))[..., None]
            if name == "flame":
                tone = tone * np.clip(dye, 0, 1)[..., None]
            col = fg_lo + (fg_hi - fg_lo) * tone
            img = background * (1 - a) + col * a
            img[solid] = boat_col if name == "stream_boat" else bg_col * 0.6 + 10 * _rock_shade(solid)[solid, None]
            img = img + noise_sigma * rng.standard_normal(img.shape)
            frames[t] = np.clip(img + 0.5, 0, 255).astype(np.uint8)
            if t < n_frames - 1:
                vel[t] = u
            else:
                break
        dye = advect_scalar(dye, u, True) * cool
        foam = advect_scalar(foam, u, True)
        # fresh foam enters with the inflow: new random texture each frame
        fresh = _smooth_noise(rng, (h, w), 1.5 * s)
        foam[inflow] = fresh[inflow]
        dye[inflow] = 1.0
        dye[solid] = 0.0 if name != "stream_boat" else 1.0
    meta = {"scene": name, "size": size, "n_frames": n_frames, "seed": seed, "warmup": warmup,
            "noise_sigma": noise_sigma, "jacobi_iters": jacobi_iters, "units": "px, px/frame"}
    return FluidFootage(frames, vel, solid, dyes, ok, meta)


def _rock_shade(solid: np.ndarray) -> np.ndarray:
    yy, xx = np.mgrid[0:solid.shape[0], 0:solid.shape[1]]
    return np.sin(0.7 * xx) * np.cos(0.5 * yy)
