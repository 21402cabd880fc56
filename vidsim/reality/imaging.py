"""What a real camera does to a perfect render: blur, sensor noise, compression (lens distortion is
applied by the renderer from the camera's ``dist``).

Pure functions of an image and a random generator, used by every reality generator so that
footage has the imperfections of a real recording.
"""

from __future__ import annotations

import cv2
import numpy as np



def sensor(
    img: np.ndarray,
    rng: np.random.Generator,
    noise_sigma: float = 2.0,
    jpeg_quality: int = 92,
    blur_sigma_px: float = 0.0,
) -> np.ndarray:
    """Optical blur, Gaussian sensor noise (digital numbers) and JPEG compression of an RGB uint8 image."""
    out = img.astype(np.float32)
    if blur_sigma_px > 0:
        out = cv2.GaussianBlur(out, (0, 0), blur_sigma_px)
    if noise_sigma > 0:
        out = out + rng.normal(0.0, noise_sigma, size=out.shape).astype(np.float32)
    out8 = np.clip(np.rint(out), 0, 255).astype(np.uint8)
    if jpeg_quality > 0:
        ok, buf = cv2.imencode(".jpg", cv2.cvtColor(out8, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
        if ok:
            out8 = cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return out8


def textured_wall(width: int, height: int, rng: np.random.Generator) -> np.ndarray:
    """A static, richly textured background image (H, W, 3) uint8: bricks of random tone plus grain."""
    img = np.zeros((height, width, 3), np.float32)
    bh, bw = max(height // 12, 4), max(width // 8, 8)
    for r in range(0, height, bh):
        off = (r // bh % 2) * bw // 2
        for c in range(-bw, width, bw):
            tone = rng.uniform(110, 200)
            tint = rng.uniform(0.85, 1.1, size=3)
            img[r : r + bh, max(c + off, 0) : max(c + off + bw, 0)] = tone * tint
    img[::bh, :] = 70
    grain = cv2.GaussianBlur(rng.normal(0, 12, (height, width)).astype(np.float32), (0, 0), 1.2)
    img += grain[..., None]
    return np.clip(img, 0, 255).astype(np.uint8)
