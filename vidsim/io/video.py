"""Writing animations: (T, H, W, 3) uint8 RGB frames to an H.264 mp4 (PyAV) or an animated GIF."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write_animation"]


def write_animation(path: str | Path, frames: np.ndarray, fps: float) -> None:
    """Write (T, H, W, 3) uint8 RGB frames as an H.264 mp4 (PyAV) or a GIF (Pillow), atomically."""
    from vidsim.io.atomic import atomic_path

    path = Path(path)
    frames = np.asarray(frames, np.uint8)
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
