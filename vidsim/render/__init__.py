"""Rendering: a fast numba rasteriser, pyrender shaded scenes, and striped structured light.

* :mod:`vidsim.render.raster` -- z-buffer triangle rasteriser for optimisation inner loops
  (silhouettes, depth, face ids, barycentrics; batched over frames).
* :mod:`vidsim.render.scene` -- pyrender (EGL offscreen) renderer for footage: colours,
  textures, textured backgrounds, lights, lens distortion by remapping.
* :mod:`vidsim.render.projector` -- a projector casting horizontal stripes and the
  irradiance it produces (1/d^2 falloff, Lambert cosine, shadow map, ambient), shared by
  both renderers.

All three follow the OpenCV camera of :mod:`vidsim.video.camera` and sample pixels at
their centres, so a mask from the fast path and one from pyrender agree.
"""

from vidsim.render.projector import (
    Projector,
    ProjectorError,
    camera_rays,
    render_stripes,
    render_stripes_batch,
    shade_stripes,
)
from vidsim.render.raster import (
    RasterError,
    RasterResult,
    face_normals,
    rasterize,
    rasterize_batch,
    silhouette,
    silhouette_batch,
)

__all__ = [
    "Projector",
    "ProjectorError",
    "camera_rays",
    "render_stripes",
    "render_stripes_batch",
    "shade_stripes",
    "RasterError",
    "RasterResult",
    "face_normals",
    "rasterize",
    "rasterize_batch",
    "silhouette",
    "silhouette_batch",
    # lazily imported from vidsim.render.scene (pyrender / OpenGL is heavy):
    "Renderer",
    "RenderOutput",
    "RenderFlags",
    "MeshItem",
    "DirectionalLight",
    "PointLight",
    "SceneError",
    "textured_plane",
]

_SCENE_NAMES = {"Renderer", "RenderOutput", "RenderFlags", "MeshItem", "DirectionalLight", "PointLight",
                "SceneError", "textured_plane"}


def __getattr__(name: str):
    """Import the pyrender-backed names on first use, so the fast path never loads OpenGL."""
    if name in _SCENE_NAMES:
        from vidsim.render import scene

        return getattr(scene, name)
    raise AttributeError(f"module 'vidsim.render' has no attribute {name!r}")
