"""Synthetic throws for the posterior benchmarks and tests, rendered once and cached (not timed).

``throw_data(seed, drag, cache)`` films a throw with :func:`vidsim.reality.rigid.make_throw`
(pyrender, sensor noise, JPEG), segments it with the project's segmenter and stores the silhouettes,
times, camera, meta and truth in ``cache/throw_<seed>_drag<drag>.npz`` so repeated benchmark runs
time only the estimation. The truth is only used for the initial guess protocol and the scoring.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from vidsim.io.atomic import restore_nonfinite, to_json, write_npz


def throw_data(seed: int, drag: float = 0.0, cache: str | os.PathLike = "/tmp/vidsim_posterior_throws") -> dict:
    """Masks (N, H, W) bool, times (N,), camera dict, meta, truth of one synthetic throw.

    Args:
        seed: throw seed (truth, texture, noise).
        drag: multiplier of physical air drag and angular drag in the reality (0: no effects).
        cache: folder of the cached throws.
    """
    import vidsim

    path = Path(cache) / f"throw_{seed}_drag{drag:g}_{vidsim.SOURCE_DIGEST[:12]}.npz"  # other code films anew
    if path.is_file():
        z = np.load(path, allow_pickle=False)
        shape = tuple(int(v) for v in z["shape"])
        masks = np.unpackbits(z["bits"])[: int(np.prod(shape))].reshape(shape).astype(bool)
        info = restore_nonfinite(json.loads(str(z["info"])))
        return {"masks": masks, "times": z["times"], **info}
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from vidsim.reality.rigid import RigidEffects, make_throw
    from vidsim.video.segment import segment

    eff = RigidEffects(drag=drag, angular_drag=drag) if drag > 0 else None
    th = make_throw(seed, effects=eff)
    masks = segment(th.frames)
    truth = {k: v for k, v in th.truth.items() if k not in ("capture_times",)}
    info = {"camera": th.camera.to_dict(), "meta": th.meta, "truth": truth}
    write_npz(path, bits=np.packbits(masks.ravel()), shape=np.array(masks.shape), times=th.times,
              info=np.array(to_json(info, "string")))  # strict JSON; a non-finite truth value read back exactly
    return {"masks": masks, "times": th.times, **info}


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", required=True)
    ap.add_argument("--drag", type=float, default=0.0)
    a = ap.parse_args()
    for s in a.seeds:
        throw_data(s, a.drag)
        print("throw", s, "drag", a.drag, flush=True)
