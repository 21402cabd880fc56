"""Shaded rendering with pyrender (EGL offscreen, Mesa llvmpipe on the CPU; no display).

Used for footage (reality) and wherever real shading, textures or a textured background are
needed. :class:`Renderer` keeps one ``pyrender.OffscreenRenderer`` alive between calls.

Conventions (same as :mod:`vidsim.video.camera` and :mod:`vidsim.render.raster`):

* The OpenCV camera (``x_c = R X + t``, +z forward, y down) is converted to pyrender's
  OpenGL camera (y up, looking along -z) by the pose ``[R^T diag(1, -1, -1) | C]``; the
  projection matrix is built from ``K`` directly (skew included) with znear / zfar.
* Pixel ``(i, j)`` is sampled at the continuous pixel coordinate ``(u, v) = (j, i)``
  (OpenCV: ``(0, 0)`` = centre of the top-left pixel). OpenGL samples window coordinates
  ``(j + 0.5, i + 0.5)``, so the principal point handed to OpenGL is shifted by half a pixel.
* ``depth`` and ``mask`` come from a pass without multisampling, so each pixel is sampled
  exactly at its centre and agrees with the fast rasteriser. ``color`` comes from a 4x
  multisampled pass (anti-aliased edges, as a real sensor integrates over the pixel).
* Lens distortion (``cam.dist`` non-zero): the scene is rendered with the ideal pinhole
  camera on a canvas large enough to cover every distorted pixel, and warped with
  ``cv2.remap`` (bilinear for colour, nearest for depth and mask) so that output pixel ``p``
  shows what the ideal camera saw at ``undistort(p)``, i.e. what a real distorting lens
  records. Depth stays camera z of the seen point.
* With a :class:`~vidsim.render.projector.Projector`, colour is ``albedo * I`` (plus the
  contribution of any explicit ``lights``), where ``albedo`` is the unlit base colour
  (colour, vertex colours or texture, as stored, no gamma) and ``I`` the linear stripe
  irradiance of :func:`~vidsim.render.projector.shade_stripes` with normals and the shadow
  map rendered by pyrender. Without a projector, colour is pyrender's PBR shading of the
  ``lights`` (pyrender applies a 1/2.2 display gamma there).
"""

from __future__ import annotations

import enum
import os
from dataclasses import dataclass, field
from typing import Sequence

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

if not hasattr(np, "infty"):  # pyrender 0.1.45 uses the alias removed in NumPy 2
    np.infty = np.inf

import pyrender  # noqa: E402

from vidsim.render.projector import Projector, shade_stripes, undistort_pixels  # noqa: E402
from vidsim.video.camera import PinholeCamera  # noqa: E402

__all__ = [
    "SceneError",
    "MeshItem",
    "DirectionalLight",
    "PointLight",
    "RenderFlags",
    "RenderOutput",
    "Renderer",
    "opencv_to_opengl_pose",
    "textured_plane",
]


class SceneError(ValueError):
    """A scene description (mesh, light, background, camera) is not valid."""


class RenderFlags(enum.IntFlag):
    """Options of :meth:`Renderer.render`."""

    NONE = 0
    SHADOWS = 1          #: pyrender shadow maps for the explicit lights
    GEOMETRY_ONLY = 2    #: skip the colour pass (``color`` is None): depth and mask only


@dataclass
class MeshItem:
    """One triangle mesh of a scene.

    Attributes:
        vertices: (N, 3) world positions, metres.
        faces: (M, 3) integer vertex indices.
        color: RGB base colour in [0, 1] (used when no vertex colours and no texture).
        vertex_colors: optional (N, 3) RGB in [0, 1].
        uv: optional (N, 2) texture coordinates, (0, 0) = top-left of ``texture``, u right, v down.
        texture: optional (h, w, 3) uint8 RGB image (needs ``uv``).
        name: label (for logs and errors).
        in_mask: whether the item belongs to the foreground ``mask`` (False for walls, floors).
        smooth: interpolate vertex normals (True) or shade each face flat (False).
    """

    vertices: np.ndarray
    faces: np.ndarray
    color: tuple[float, float, float] = (0.7, 0.7, 0.7)
    vertex_colors: np.ndarray | None = None
    uv: np.ndarray | None = None
    texture: np.ndarray | None = None
    name: str = "mesh"
    in_mask: bool = True
    smooth: bool = False

    def __post_init__(self) -> None:
        w = f"MeshItem '{self.name}'"
        V = np.asarray(self.vertices, dtype=np.float64)
        if V.ndim != 2 or V.shape[1] != 3 or not np.all(np.isfinite(V)):
            raise SceneError(f"{w}: field 'vertices' must be a finite (N, 3) array, got shape {V.shape}")
        Fc = np.asarray(self.faces)
        if Fc.ndim != 2 or Fc.shape[1] != 3 or (Fc.size and not np.issubdtype(Fc.dtype, np.integer)):
            raise SceneError(f"{w}: field 'faces' must be an integer (M, 3) array, got {Fc.shape} {Fc.dtype}")
        if Fc.size and (Fc.min() < 0 or Fc.max() >= len(V)):
            raise SceneError(f"{w}: field 'faces' indexes outside [0, {len(V)})")
        c = np.asarray(self.color, dtype=float).ravel()
        if c.size != 3 or np.any(c < 0) or np.any(c > 1):
            raise SceneError(f"{w}: field 'color' must be RGB in [0, 1], got {self.color!r}")
        if self.vertex_colors is not None:
            vc = np.asarray(self.vertex_colors, dtype=float)
            if vc.shape != (len(V), 3):
                raise SceneError(f"{w}: field 'vertex_colors' must have shape {(len(V), 3)}, got {vc.shape}")
            self.vertex_colors = vc
        if (self.texture is None) != (self.uv is None):
            raise SceneError(f"{w}: fields 'texture' and 'uv' must be given together")
        if self.texture is not None:
            tex = np.asarray(self.texture)
            if tex.ndim != 3 or tex.shape[2] != 3 or tex.dtype != np.uint8:
                raise SceneError(f"{w}: field 'texture' must be an (h, w, 3) uint8 image, got {tex.shape} {tex.dtype}")
            uv = np.asarray(self.uv, dtype=float)
            if uv.shape != (len(V), 2):
                raise SceneError(f"{w}: field 'uv' must have shape {(len(V), 2)}, got {uv.shape}")
            self.texture, self.uv = tex, uv
        self.vertices, self.faces, self.color = V, Fc.astype(np.int64), tuple(float(x) for x in c)


@dataclass
class DirectionalLight:
    """Light from infinitely far away travelling along ``direction`` (world), pyrender intensity (lux)."""

    direction: Sequence[float]
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 3.0


@dataclass
class PointLight:
    """Isotropic point light at ``position`` (world metres), pyrender intensity (candela)."""

    position: Sequence[float]
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 5.0


@dataclass
class RenderOutput:
    """Result of :meth:`Renderer.render`.

    Attributes:
        color: (H, W, 3) uint8 RGB, or None with ``RenderFlags.GEOMETRY_ONLY``.
        depth: (H, W) float32 camera-z in metres, ``inf`` where nothing was hit.
        mask: (H, W) bool, True where the nearest surface belongs to an ``in_mask`` item.
        irradiance: (H, W) float32 stripe irradiance when a projector was given, else None.
    """

    color: np.ndarray | None
    depth: np.ndarray
    mask: np.ndarray
    irradiance: np.ndarray | None = None


# --------------------------------------------------------------------------- camera helpers
def opencv_to_opengl_pose(cam: PinholeCamera) -> np.ndarray:
    """(4, 4) camera-to-world pose in pyrender's OpenGL convention (y up, looking along -z)."""
    pose = np.eye(4)
    pose[:3, :3] = cam.R.T @ np.diag([1.0, -1.0, -1.0])
    pose[:3, 3] = cam.center
    return pose


class _CVCamera(pyrender.Camera):
    """pyrender camera whose projection is the OpenCV ``K`` (skew included), sampled at pixel centres."""

    def __init__(self, K: np.ndarray, znear: float, zfar: float) -> None:
        super().__init__(znear=znear, zfar=zfar)
        self.K = np.asarray(K, float)

    def get_projection_matrix(self, width: int | None = None, height: int | None = None) -> np.ndarray:
        W, H = float(width), float(height)
        fx, s, cx = self.K[0, 0], self.K[0, 1], self.K[0, 2] + 0.5
        fy, cy = self.K[1, 1], self.K[1, 2] + 0.5
        n, f = self.znear, self.zfar
        P = np.zeros((4, 4))
        P[0, 0] = 2.0 * fx / W
        P[0, 1] = -2.0 * s / W
        P[0, 2] = 1.0 - 2.0 * cx / W
        P[1, 1] = 2.0 * fy / H
        P[1, 2] = 2.0 * cy / H - 1.0
        P[2, 2] = (f + n) / (n - f)
        P[2, 3] = 2.0 * f * n / (n - f)
        P[3, 2] = -1.0
        return P


@dataclass
class _Canvas:
    cam: PinholeCamera                  # ideal pinhole camera actually rendered
    map_x: np.ndarray | None = None     # remap to the distorted output, or None
    map_y: np.ndarray | None = None


_MAX_CANVAS_SCALE = 3.0


def _canvas(cam: PinholeCamera) -> _Canvas:
    if not np.any(cam.dist):
        return _Canvas(cam)
    u, v = np.meshgrid(np.arange(cam.width, dtype=np.float64), np.arange(cam.height, dtype=np.float64))
    try:
        und = undistort_pixels(np.stack([u.ravel(), v.ravel()], axis=1), cam, P=cam.K)
    except ValueError as e:
        raise SceneError(str(e)) from e
    lo = np.floor(und.min(axis=0)) - 2
    hi = np.ceil(und.max(axis=0)) + 2
    lo = np.minimum(lo, 0)
    hi = np.maximum(hi, [cam.width - 1, cam.height - 1])
    size = hi - lo + 1
    if size[0] > _MAX_CANVAS_SCALE * cam.width or size[1] > _MAX_CANVAS_SCALE * cam.height:
        raise SceneError(f"camera field 'dist' {cam.dist.tolist()} is too strong: the undistorted view needs a "
                         f"{int(size[0])}x{int(size[1])} canvas (> {_MAX_CANVAS_SCALE}x the image)")
    K = cam.K.copy()
    K[0, 2] -= lo[0]
    K[1, 2] -= lo[1]
    ideal = PinholeCamera(K, cam.R, cam.t, int(size[0]), int(size[1]))
    mx = (und[:, 0] - lo[0]).reshape(cam.height, cam.width).astype(np.float32)
    my = (und[:, 1] - lo[1]).reshape(cam.height, cam.width).astype(np.float32)
    return _Canvas(ideal, mx, my)


def _warp(img: np.ndarray, cv: _Canvas, nearest: bool, fill: float = 0) -> np.ndarray:
    if cv.map_x is None:
        return img
    interp = cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR
    return cv2.remap(img, cv.map_x, cv.map_y, interp, borderMode=cv2.BORDER_CONSTANT, borderValue=fill)


# --------------------------------------------------------------------------- meshes
def _flat_geometry(item: MeshItem) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unshared vertices per face: positions (3M, 3), face normals (3M, 3), indices, source ids (3M,)."""
    ids = item.faces.reshape(-1)
    P = item.vertices[ids]
    a, b, c = P[0::3], P[1::3], P[2::3]
    n = np.cross(b - a, c - a)
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, ln, out=np.zeros_like(n), where=ln > 0)
    N = np.repeat(n, 3, axis=0)
    return P, N, np.arange(len(ids)).reshape(-1, 3), ids


def _vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])  # area weighted
    vn = np.zeros_like(V)
    for k in range(3):
        np.add.at(vn, F[:, k], n)
    ln = np.linalg.norm(vn, axis=1, keepdims=True)
    return np.divide(vn, ln, out=np.zeros_like(vn), where=ln > 0)


def _pyrender_mesh(item: MeshItem, normal_code: bool = False) -> pyrender.Mesh:
    """pyrender mesh of ``item``; with ``normal_code`` the colours encode face normals ``(n + 1) / 2``."""
    if item.smooth and not normal_code:
        P, N, I, ids = item.vertices, _vertex_normals(item.vertices, item.faces), item.faces, np.arange(len(item.vertices))
    else:
        P, N, I, ids = _flat_geometry(item)
    # pyrender culls back faces in its segmentation / depth passes whatever the material says,
    # so every triangle is emitted twice (both windings, opposite normals) with culling on:
    # exactly the copy facing the camera is drawn, with its normal towards the camera.
    I = np.vstack([I, I[:, ::-1] + len(P)])
    P, N, ids = np.vstack([P, P]), np.vstack([N, -N]), np.concatenate([ids, ids])
    kw: dict = {}
    if normal_code:
        kw["color_0"] = np.hstack([(N + 1.0) / 2.0, np.ones((len(N), 1))])
        mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=(1.0, 1.0, 1.0, 1.0), doubleSided=False)
    else:
        base = (1.0, 1.0, 1.0, 1.0)
        tex = None
        if item.texture is not None:
            uv = item.uv[ids]
            kw["texcoord_0"] = np.column_stack([uv[:, 0], 1.0 - uv[:, 1]])  # pyrender flips images: v up
            tex = pyrender.Texture(source=item.texture, source_channels="RGB")
        elif item.vertex_colors is not None:
            kw["color_0"] = np.hstack([item.vertex_colors[ids], np.ones((len(ids), 1))])
        else:
            base = (*item.color, 1.0)
        mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=base, baseColorTexture=tex, metallicFactor=0.0,
                                                 roughnessFactor=1.0, doubleSided=False)
    prim = pyrender.Primitive(positions=P.astype(np.float32), normals=N.astype(np.float32), indices=I,
                              material=mat, **kw)
    return pyrender.Mesh([prim], name=item.name)


def textured_plane(center: Sequence[float], normal: Sequence[float], up: Sequence[float], size: tuple[float, float],
                   texture: np.ndarray, name: str = "background", in_mask: bool = False) -> MeshItem:
    """A rectangle of ``size = (width, height)`` metres centred at ``center`` facing ``normal``, the
    ``texture`` (h, w, 3) uint8 mapped onto it upright (image top towards ``up``); for walls and floors."""
    c = np.asarray(center, float)
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    upv = np.asarray(up, float)
    upv = upv - n * (upv @ n)
    if np.linalg.norm(upv) < 1e-9:
        raise SceneError("textured_plane: 'up' must not be parallel to 'normal'")
    upv /= np.linalg.norm(upv)
    right = np.cross(upv, n)  # seen from the front (against n), image x runs along 'right'
    w, h = size
    V = np.array([c - right * w / 2 + upv * h / 2, c + right * w / 2 + upv * h / 2,
                  c + right * w / 2 - upv * h / 2, c - right * w / 2 - upv * h / 2])
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    return MeshItem(V, np.array([[0, 1, 2], [0, 2, 3]]), uv=uv, texture=texture, name=name, in_mask=in_mask)


# --------------------------------------------------------------------------- renderer
class Renderer:
    """pyrender offscreen renderer kept alive across frames.

    Args:
        width: default viewport width in pixels (resized automatically per camera).
        height: default viewport height in pixels.
        znear: near clipping distance, metres.
        zfar: far clipping distance, metres.
    """

    def __init__(self, width: int, height: int, znear: float = 0.01, zfar: float = 100.0) -> None:
        if int(width) <= 0 or int(height) <= 0:
            raise SceneError(f"Renderer size must be positive, got {width}x{height}")
        if not (0 < znear < zfar):
            raise SceneError(f"Renderer needs 0 < znear < zfar, got znear={znear}, zfar={zfar}")
        self.znear, self.zfar = float(znear), float(zfar)
        self._r = pyrender.OffscreenRenderer(int(width), int(height))

    def close(self) -> None:
        """Release the OpenGL context."""
        if self._r is not None:
            self._r.delete()
            self._r = None

    def __enter__(self) -> "Renderer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass

    # -------------------------------------------------------------- passes
    def _viewport(self, cam: PinholeCamera) -> None:
        if self._r is None:
            raise SceneError("Renderer was closed")
        if (self._r.viewport_width, self._r.viewport_height) != (cam.width, cam.height):
            self._r.viewport_width, self._r.viewport_height = cam.width, cam.height

    def _geometry(self, scene: pyrender.Scene, cam_node, cam: PinholeCamera, nodes, in_mask) -> tuple[np.ndarray, np.ndarray]:
        """Centre-sampled depth (inf background) and foreground mask from a segmentation pass."""
        scene.main_camera_node = cam_node
        self._viewport(cam)
        seg_map = {nd: ((255, 255, 255) if m else (0, 0, 255)) for nd, m in zip(nodes, in_mask)}
        seg, depth = self._r.render(scene, flags=pyrender.RenderFlags.SEG, seg_node_map=seg_map)
        depth = np.where(depth > 0, depth, np.inf).astype(np.float32)
        return depth, seg[..., 0] == 255

    def render(
        self,
        meshes: list[MeshItem],
        cam: PinholeCamera,
        *,
        lights: Sequence[DirectionalLight | PointLight] | None = None,
        projector: Projector | None = None,
        background: tuple[float, float, float] | np.ndarray | None = None,
        ambient: float = 0.15,
        flags: RenderFlags = RenderFlags.NONE,
    ) -> RenderOutput:
        """Render a list of meshes seen by ``cam``.

        Args:
            meshes: the scene content (use :func:`textured_plane` with ``in_mask=False`` for a wall).
            cam: the camera (its width/height set the image size; lens distortion is applied).
            lights: explicit lights. Default without projector: a headlight along the camera axis.
                Default with projector: none (only the projector and its ambient term).
            projector: a striped :class:`Projector` whose light is added (see module docstring).
            background: where nothing is hit: None (black), an RGB tuple in [0, 1], or an (H, W, 3)
                uint8 image of the output size.
            ambient: pyrender ambient light level (without projector).
            flags: :class:`RenderFlags`.

        Returns:
            :class:`RenderOutput` with colour (uint8), depth (float32 metres, inf background) and mask.

        Raises:
            SceneError: on malformed meshes, lights, background or camera.
        """
        if not isinstance(cam, PinholeCamera):
            raise SceneError(f"'cam' must be a PinholeCamera, got {type(cam).__name__}")
        for k, m in enumerate(meshes):
            if not isinstance(m, MeshItem):
                raise SceneError(f"meshes[{k}] must be a MeshItem, got {type(m).__name__}")
        if projector is not None and not isinstance(projector, Projector):
            raise SceneError(f"'projector' must be a Projector, got {type(projector).__name__}")
        bg_img = None
        bg_rgb = np.zeros(3)
        if background is not None:
            b = np.asarray(background)
            if b.ndim == 1 and b.size == 3 and np.all((b >= 0) & (b <= 1)):
                bg_rgb = b.astype(float)
            elif b.shape == (cam.height, cam.width, 3) and b.dtype == np.uint8:
                bg_img = b
            else:
                raise SceneError(f"'background' must be None, RGB in [0, 1] or a {(cam.height, cam.width, 3)} "
                                 f"uint8 image, got shape {b.shape} dtype {b.dtype}")

        cv = _canvas(cam)
        scene = pyrender.Scene(bg_color=(0.0, 0.0, 0.0, 0.0), ambient_light=(ambient,) * 3)
        nodes = [scene.add(_pyrender_mesh(m)) for m in meshes]
        in_mask = [m.in_mask for m in meshes]
        cam_node = scene.add(_CVCamera(cv.cam.K, self.znear, self.zfar), pose=opencv_to_opengl_pose(cv.cam))

        depth_c, mask_c = self._geometry(scene, cam_node, cv.cam, nodes, in_mask)
        depth = _warp(depth_c, cv, nearest=True, fill=np.inf)
        mask = _warp(mask_c.astype(np.uint8), cv, nearest=True).astype(bool)
        if flags & RenderFlags.GEOMETRY_ONLY:
            return RenderOutput(None, depth, mask)

        if lights is None:
            lights = [] if projector is not None else [DirectionalLight(direction=cam.R[2])]
        for L in lights:
            self._add_light(scene, L)
        bg = bg_img.astype(np.float32) / 255.0 if bg_img is not None else bg_rgb.astype(np.float32)[None, None, :]

        scene.main_camera_node = cam_node
        self._viewport(cv.cam)
        irr = None
        if projector is None:
            pf = pyrender.RenderFlags.RGBA
            if flags & RenderFlags.SHADOWS:
                pf |= pyrender.RenderFlags.SHADOWS_ALL
            rgba, _ = self._r.render(scene, flags=pf)
            rgba = _warp(rgba.astype(np.float32) / 255.0, cv, nearest=False)
            # multisample resolve against a (0, 0, 0, 0) clear colour = premultiplied alpha
            color = rgba[..., :3] + bg * (1.0 - rgba[..., 3:4])
        else:
            lit = None
            if lights:
                pf = pyrender.RenderFlags.RGBA | (pyrender.RenderFlags.SHADOWS_ALL if flags & RenderFlags.SHADOWS else 0)
                lit = _warp(self._r.render(scene, flags=pf)[0].astype(np.float32) / 255.0, cv, nearest=False)
            albedo = _warp(self._r.render(scene, flags=pyrender.RenderFlags.FLAT | pyrender.RenderFlags.RGBA)[0]
                           .astype(np.float32) / 255.0, cv, nearest=False)
            normals = self._normal_pass(meshes, cam_node, cv)
            # projector shadow map: geometry pass from the projector
            pc = _canvas(projector.cam)
            pnode = scene.add(_CVCamera(pc.cam.K, self.znear, self.zfar), pose=opencv_to_opengl_pose(pc.cam))
            dproj = _warp(self._geometry(scene, pnode, pc.cam, nodes, in_mask)[0], pc, nearest=True, fill=np.inf)
            irr = shade_stripes(depth, cam, projector, normals, dproj)
            alpha = albedo[..., 3:4]
            color = albedo[..., :3] * irr[..., None] + bg * (1.0 - alpha)
            if lit is not None:
                color = color + lit[..., :3]
        color = np.clip(np.rint(color * 255.0), 0, 255).astype(np.uint8)
        return RenderOutput(color, depth, mask, irr)

    def _normal_pass(self, meshes: list[MeshItem], cam_node, cv: _Canvas) -> np.ndarray:
        """(H, W, 3) world unit normals (zero on background) from colour-coded flat normals."""
        nscene = pyrender.Scene(bg_color=(0.5, 0.5, 0.5, 0.0), ambient_light=(0.0, 0.0, 0.0))
        for m in meshes:
            nscene.add(_pyrender_mesh(m, normal_code=True))
        nnode = nscene.add(_CVCamera(cv.cam.K, self.znear, self.zfar), pose=cam_node.matrix)
        nscene.main_camera_node = nnode
        self._viewport(cv.cam)
        col = self._r.render(nscene, flags=pyrender.RenderFlags.FLAT)[0].astype(np.float32) / 255.0
        n = _warp(col, cv, nearest=False) * 2.0 - 1.0
        ln = np.linalg.norm(n, axis=-1, keepdims=True)
        return np.divide(n, ln, out=np.zeros_like(n), where=ln > 0.2)

    @staticmethod
    def _add_light(scene: pyrender.Scene, L: DirectionalLight | PointLight) -> None:
        pose = np.eye(4)
        if isinstance(L, DirectionalLight):
            d = np.asarray(L.direction, float)
            if d.shape != (3,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0:
                raise SceneError(f"DirectionalLight field 'direction' must be a non-zero 3-vector, got {L.direction!r}")
            z = -d / np.linalg.norm(d)  # pyrender lights shine along their -z axis
            x = np.cross([0.0, 0.0, 1.0], z)
            if np.linalg.norm(x) < 1e-6:
                x = np.cross([0.0, 1.0, 0.0], z)
            x /= np.linalg.norm(x)
            pose[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
            scene.add(pyrender.DirectionalLight(color=L.color, intensity=float(L.intensity)), pose=pose)
        elif isinstance(L, PointLight):
            p = np.asarray(L.position, float)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise SceneError(f"PointLight field 'position' must be a finite 3-vector, got {L.position!r}")
            pose[:3, 3] = p
            scene.add(pyrender.PointLight(color=L.color, intensity=float(L.intensity)), pose=pose)
        else:
            raise SceneError(f"lights must be DirectionalLight or PointLight, got {type(L).__name__}")
