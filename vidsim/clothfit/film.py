"""Filming cloth under structured light (reality side) and the shared swatch rig.

Reality renders every frame with pyrender (:class:`vidsim.render.scene.Renderer`) and a
:class:`~vidsim.render.projector.Projector` casting horizontal stripes: projector shadow map,
Lambert cosine, 1/d^2 falloff and ambient light; smooth vertex normals (the estimator renders
flat faces with its own rasteriser). Then optical blur and Gaussian sensor noise
(:func:`vidsim.reality.imaging.sensor`). The clip starts with ``n_background`` frames of the
empty scene (a dark studio backdrop), from which the segmentation learns the background.

Imaging effects (off by default): motion blur (the exposure, centred on the frame's time as in
the rigid reality and in the gap diagnosis's candidate, averages ``motion_blur`` renders at
positions interpolated linearly between consecutive frames, extrapolated from the nearest two at
the clip's ends; until 6 Dec 2026 the exposure ended at the frame time, so the blurred footage
also carried half the exposure as a time offset), a radial lens term ``lens_k1``
that the calibration never saw, and a projector rotated by ``projector_misalign_deg`` after
calibration.

The rig (:func:`swatch_model_mesh`, :func:`swatch_driver`) turns the *measured* corner paths of
``meta.yaml`` into the estimator's mesh and driven vertices; the twin reality
(:func:`twin_swatch`) runs the estimator's own simulator on a finer mesh with known parameters.
Units: metres, seconds; images (H, W, 3) uint8 RGB.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vidsim.cloth import ClothMesh, ClothParams, DrivenVertices, simulate, swatch
from vidsim.errors import VidsimError
from vidsim.reality.imaging import sensor
from vidsim.render.projector import Projector
from vidsim.video.camera import PinholeCamera

__all__ = [
    "ClothFilmError",
    "FilmSettings",
    "film_cloth",
    "swatch_model_mesh",
    "swatch_driver",
    "twin_swatch",
    "rotate_about_center",
]


class ClothFilmError(VidsimError):
    """Bad input to the cloth filming or rig functions (names the field and value)."""


@dataclass(frozen=True)
class FilmSettings:
    """How reality images the cloth.

    Attributes:
        n_background: empty-scene frames before the cloth frames (>= 3 for the background model).
        albedo: grey albedo of the fabric in [0, 1].
        noise_sigma: sensor noise, digital numbers (0-255).
        blur_sigma_px: optical blur, pixels.
        jpeg_quality: 0 = no compression, else JPEG quality.
        motion_blur: renders averaged per exposure (0 or 1 = none).
        exposure: exposure time as a fraction of the frame interval, in (0, 1].
    """

    n_background: int = 5
    albedo: float = 0.85
    noise_sigma: float = 2.0
    blur_sigma_px: float = 0.6
    jpeg_quality: int = 0
    motion_blur: int = 0
    exposure: float = 0.5

    def __post_init__(self) -> None:
        if int(self.n_background) < 3:
            raise ClothFilmError(f"FilmSettings.n_background must be >= 3 frames, got {self.n_background}")
        if not 0 < self.albedo <= 1:
            raise ClothFilmError(f"FilmSettings.albedo must be in (0, 1], got {self.albedo}")
        if self.noise_sigma < 0 or self.blur_sigma_px < 0:
            raise ClothFilmError("FilmSettings.noise_sigma and blur_sigma_px must be >= 0")
        if not 0 < self.exposure <= 1:
            raise ClothFilmError(f"FilmSettings.exposure must be in (0, 1], got {self.exposure}")


def rotate_about_center(cam: PinholeCamera, degrees: float, axis: np.ndarray | None = None) -> PinholeCamera:
    """The device turned by ``degrees`` about ``axis`` (camera frame, default its x axis) through
    its own centre: a projector knocked out of alignment after calibration."""
    if degrees == 0:
        return cam
    ax = np.array([1.0, 0.0, 0.0]) if axis is None else np.asarray(axis, float)
    Rd, _ = cv2.Rodrigues(np.deg2rad(degrees) * ax / np.linalg.norm(ax))
    R = Rd @ cam.R
    t = -R @ cam.center
    return PinholeCamera(cam.K, R, t, cam.width, cam.height, cam.dist)


def film_cloth(
    vertices: np.ndarray,
    faces: np.ndarray,
    camera: PinholeCamera,
    projector: Projector,
    rng: np.random.Generator,
    settings: FilmSettings = FilmSettings(),
) -> np.ndarray:
    """Film a cloth animation (reality): background frames, then one frame per vertex set.

    Args:
        vertices: (T, N, 3) world positions per frame, metres.
        faces: (M, 3) triangles.
        camera: the true camera (with any lens distortion reality has).
        projector: the true projector (pose as it really is).
        rng: generator for the sensor noise.
        settings: imaging settings.

    Returns:
        (n_background + T, H, W, 3) uint8 frames.
    """
    V = np.asarray(vertices, float)
    if V.ndim != 3 or V.shape[2] != 3 or not np.all(np.isfinite(V)):
        raise ClothFilmError(f"vertices must be finite (T, N, 3) metres, got shape {V.shape}")
    from vidsim.render.scene import MeshItem, Renderer

    colour = (settings.albedo,) * 3
    sub = max(1, int(settings.motion_blur))
    frames = []
    with Renderer(camera.width, camera.height) as r:
        empty = r.render([], camera, projector=projector).color
        for _ in range(int(settings.n_background)):
            frames.append(sensor(empty, rng, settings.noise_sigma, settings.jpeg_quality, settings.blur_sigma_px))
        for k in range(V.shape[0]):
            acc = np.zeros((camera.height, camera.width, 3), np.float32)
            for s in range(sub):
                # exposure centred on the frame time: w frame intervals away from it, -E/2 .. +E/2,
                # towards the neighbouring frame on that side (the other side's at the clip's ends)
                w = 0.0 if sub == 1 else settings.exposure * (s / (sub - 1) - 0.5)
                if V.shape[0] < 2 or w == 0.0:
                    Vk = V[k]
                elif (w < 0 and k > 0) or k == V.shape[0] - 1:
                    Vk = V[k] + w * (V[k] - V[k - 1])
                else:
                    Vk = V[k] + w * (V[k + 1] - V[k])
                img = r.render([MeshItem(Vk, faces, color=colour, smooth=True, name="cloth")], camera,
                               projector=projector).color
                acc += img.astype(np.float32)
            img = np.clip(np.rint(acc / sub), 0, 255).astype(np.uint8)
            frames.append(sensor(img, rng, settings.noise_sigma, settings.jpeg_quality, settings.blur_sigma_px))
    return np.stack(frames)


def swatch_model_mesh(corners0: np.ndarray, resolution: int, size: float) -> ClothMesh:
    """The estimator's square swatch hanging from its two gripped corners at frame 0.

    Args:
        corners0: (2, 3) left and right top-corner positions at the first frame, metres.
        resolution: vertices per side (>= 3).
        size: side length, metres (the measured fabric size).

    Returns:
        :class:`ClothMesh` with ``top_corners`` = vertices (0, resolution - 1) at ``corners0``.
    """
    c = np.asarray(corners0, float)
    if c.shape != (2, 3) or not np.all(np.isfinite(c)):
        raise ClothFilmError(f"corners0 must be (2, 3) finite metres, got {c.shape}")
    if int(resolution) < 3:
        raise ClothFilmError(f"model resolution must be >= 3 vertices per side, got {resolution}")
    au = c[1] - c[0]
    span = float(np.linalg.norm(au))
    if span < 1e-6:
        raise ClothFilmError("the two gripped corners coincide at frame 0")
    au /= span
    # down, made perpendicular to the corner line (Gram-Schmidt: d - (d . au) au with d = -z, d . au = -au_z)
    av = np.array([0.0, 0.0, -1.0]) + au[2] * au
    nv = float(np.linalg.norm(av))
    if nv < 1e-6:
        raise ClothFilmError("the two gripped corners are one above the other at frame 0: no downward direction")
    av /= nv
    return swatch(int(resolution), int(resolution), span, float(size), origin=tuple(c[0]), axis_u=tuple(au),
                  axis_v=tuple(av))


def swatch_driver(mesh: ClothMesh, times: np.ndarray, corner_paths: np.ndarray, settle_s: float
                  ) -> tuple[DrivenVertices, float]:
    """Driven top corners from the measured paths, held still for ``settle_s`` before frame 0.

    Args:
        mesh: from :func:`swatch_model_mesh`.
        times: (T,) frame times, seconds.
        corner_paths: (T, 2, 3) measured corner positions, metres.
        settle_s: rest time before ``times[0]``, seconds (> 0).

    Returns:
        ``(driver, t0)`` with ``t0 = times[0] - settle_s``.
    """
    t = np.asarray(times, float)
    cp = np.asarray(corner_paths, float)
    if cp.shape != (t.size, 2, 3):
        raise ClothFilmError(f"corner_paths must be (T, 2, 3) = {(t.size, 2, 3)}, got {cp.shape}")
    if not settle_s > 0:
        raise ClothFilmError(f"settle_s must be > 0 s, got {settle_s}")
    t0 = float(t[0] - settle_s)
    tt = np.concatenate([[t0, t[0] - 1e-3 * settle_s], t])
    pp = np.concatenate([cp[:1], cp[:1], cp])
    vel = np.gradient(pp, tt, axis=0)
    vel[:2] = 0.0
    return DrivenVertices(mesh.tags["top_corners"], tt, pp, vel), t0


def twin_swatch(params: ClothParams, corner_paths_fn, n_frames: int, fps: float, resolution: int,
                size: float = 0.3, settle_s: float = 1.0, settle_bath: float = 0.0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool, str | None]:
    """The twin reality: the estimator's simulator on a finer mesh with known parameters.

    Args:
        params: the true parameters (known to the test, never to the estimator).
        corner_paths_fn: ``f(times) -> (T, 2, 3)`` corner positions (true = measured here).
        n_frames, fps: frames and rate.
        resolution: vertices per side (finer than the estimator's).
        size: side length, metres.
        settle_s: rest before frame 0; settle_bath: its viscous damping rate, 1/s (0: off).

    Returns:
        ``(vertices (T, N, 3), faces, corner_paths (T, 2, 3), ok, failure)``.
    """
    times = np.arange(int(n_frames)) / float(fps)
    cp = np.asarray(corner_paths_fn(times), float)
    mesh = swatch_model_mesh(cp[0], resolution, size)
    drv, t0 = swatch_driver(mesh, times, cp, settle_s)
    res = simulate(mesh, params, drv, times, integrator="fast", t0=t0, settle_bath=settle_bath)
    return res.positions[: res.frames_done], mesh.triangles, cp, bool(res.ok), res.failure
