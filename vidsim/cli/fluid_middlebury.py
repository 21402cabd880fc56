"""Stage ``fluid_middlebury``: optical-flow accuracy on the real Middlebury scenes.

``python -m vidsim.cli.fluid_middlebury paths.footage=../shared/data/middlebury_flow paths.out=results/fluid/middlebury``.
For each scene folder (``frame10.png``, ``frame11.png``, ground truth ``flow10.flo``) the flow of
the configured method (``fluid.flow.method``) and of the reference methods is scored by the
average endpoint error over pixels of known ground truth. Outputs ``epe.csv`` and
``middlebury.png`` (frame, estimated and true flow in the colour-wheel coding, error map,
colour wheel legend).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.errors import FootageError
from vidsim.fluid.flow import endpoint_error, flow_pair, parse_flo
from vidsim.fluid.viz import color_wheel, flow_to_color
from vidsim.io.atomic import write_json, write_text
from vidsim.io.footage import read_image
from vidsim.report.figures import save_figure

SCENES = ("RubberWhale", "Dimetrodon")


def run(cfg: DictConfig) -> None:
    import matplotlib.pyplot as plt

    root = Path(cfg.paths.footage)
    if not root.is_dir():
        raise FootageError(f"paths.footage={str(root)!r}: Middlebury folder is missing")
    methods = list(dict.fromkeys([cfg.fluid.flow.method, "dis_medium", "farneback"]))
    rows = ["scene,method,epe_px,time_s"]
    out = Path(cfg.paths.out)
    res: dict = {}
    fig, axes = plt.subplots(len(SCENES), 5, figsize=(16, 2.9 * len(SCENES)), squeeze=False)
    for r, sc in enumerate(SCENES):
        d = root / sc
        flo = d / "flow10.flo"
        if not flo.is_file():
            raise FootageError(f"{flo}: ground-truth flow file is missing")
        a, b = read_image(d / "frame10.png"), read_image(d / "frame11.png")
        try:
            gt = parse_flo(flo.read_bytes())
        except ValueError as e:  # the parser's message does not know the file
            raise FootageError(f"{flo}: {e}") from None
        if gt.shape[:2] != a.shape[:2]:
            raise FootageError(f"{flo}: ground truth {gt.shape[1]}x{gt.shape[0]} does not match frame10.png {a.shape[1]}x{a.shape[0]}")
        res[sc] = {}
        for m in methods:
            t0 = time.perf_counter()
            f = flow_pair(a, b, m)
            dt = time.perf_counter() - t0
            e = endpoint_error(f, gt)
            res[sc][m] = e
            rows.append(f"{sc},{m},{e:.4f},{dt:.3f}")
            if m == cfg.fluid.flow.method:
                est, err = f, np.linalg.norm(f - gt, axis=-1)
        known = np.all(np.abs(gt) < 1e9, -1)
        vmax = float(np.percentile(np.linalg.norm(gt, axis=-1)[known], 99))
        axes[r, 0].imshow(a)
        axes[r, 0].set_title(f"{sc} frame10", fontsize=8)
        axes[r, 1].imshow(flow_to_color(est, vmax))
        axes[r, 1].set_title(f"{cfg.fluid.flow.method}: EPE {res[sc][cfg.fluid.flow.method]:.3f} px", fontsize=8)
        axes[r, 2].imshow(flow_to_color(gt, vmax))
        axes[r, 2].set_title(f"ground truth (full colour = {vmax:.2f} px)", fontsize=8)
        im = axes[r, 3].imshow(np.where(known, err, np.nan), cmap="magma", vmin=0, vmax=1.0)
        axes[r, 3].set_title("endpoint error (px)", fontsize=8)
        fig.colorbar(im, ax=axes[r, 3], fraction=0.046)
        axes[r, 4].imshow(color_wheel(128))
        axes[r, 4].set_title("colour wheel (+x right, +y down)", fontsize=8)
        print(f"fluid_middlebury: {sc}: " + ", ".join(f"{m} {e:.3f} px" for m, e in res[sc].items()), flush=True)
    for ax in axes.ravel():
        ax.axis("off")
    save_figure(fig, out / "middlebury.png")
    write_text(out / "epe.csv", "\n".join(rows) + "\n")
    write_json(out / "summary.json", {"method": cfg.fluid.flow.method, "epe_px": res})  # read by fluid_metrics: last


main = stage_app("fluid_middlebury", run)

if __name__ == "__main__":
    main()
