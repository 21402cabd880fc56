"""Writing animations: (T, H, W, 3) uint8 RGB frames to an H.264 mp4 (PyAV) or an animated GIF."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write_animation"]


def write_animation(path: str | Path, frames: np.ndarray, fps: float) -> None:
    """Write (T, H, W, 3) uint8 RGB frames as an H.264 mp4 (PyAV) or a GIF (Pillow), atomically.

    An mp4 has even width and height (yuv420p): an odd last row or column is dropped."""
    from vidsim.io.atomic import atomic_path

    path = Path(path)
    a = np.asarray(frames)
    if a.ndim != 4 or a.shape[-1] != 3 or a.shape[0] < 1:
        raise ValueError(f"{path}: frames must be (T, H, W, 3) RGB with T >= 1, got shape {a.shape}")
    if a.dtype != np.uint8:  # e.g. floats in [0, 1] would silently become a black video
        raise ValueError(f"{path}: frames must be uint8, got {a.dtype}")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"{path}: fps must be a finite rate > 0, got {fps!r}")
    frames = a
    if path.suffix == ".gif":
        from PIL import Image

        ims = [Image.fromarray(f) for f in frames]
        with atomic_path(path) as tmp:
            ims[0].save(tmp, format="GIF", save_all=True, append_images=ims[1:], duration=int(1000 / fps), loop=0)
        return
    import av
    from fractions import Fraction

    h, w = frames.shape[1] // 2 * 2, frames.shape[2] // 2 * 2
    with atomic_path(path) as tmp:
        with av.open(str(tmp), mode="w", format="mp4") as c:
            st = c.add_stream("libx264", rate=Fraction(int(round(fps * 1000)), 1000))
            st.width, st.height, st.pix_fmt = w, h, "yuv420p"
            st.options = {"crf": "23", "preset": "veryfast", "threads": "1"}
            for f in frames:
                for pkt in st.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(f[:h, :w]), format="rgb24")):
                    c.mux(pkt)
            for pkt in st.encode():
                c.mux(pkt)
