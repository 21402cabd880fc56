"""Shared pieces of the gap stages: figures, Rerun logging and atomic outputs of a diagnosis (rigid or cloth)."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np

from vidsim.gap.rigid_diagnose import RigidDiagnosis
from vidsim.report.figures import save_figure
from vidsim.io.atomic import replace_dir

FLOOR_LABEL = "noise floor (free pose per frame)"


def write_diagnosis(d: Any, out: Path, inputs: dict, masks: np.ndarray, stage: str, title: str, rerun: bool,
                    floor_label: str = FLOOR_LABEL) -> None:
    """``diagnosis.json`` (with ``inputs``), ``diagnosis.png`` and ``diagnosis.rrd`` of a rigid or
    cloth diagnosis, written into a temporary folder renamed to ``out`` at the end (all or nothing);
    a one-line verdict on stderr."""
    from vidsim.io.atomic import write_json
    from vidsim.log import make_logger

    out = Path(out)
    tmp = out.with_name(f".{out.name}.part")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    res = d.to_dict()
    res["inputs"] = inputs
    write_json(tmp / "diagnosis.json", res)
    plot_diagnosis(d, tmp / "diagnosis.png", title=title, floor_label=floor_label)
    with make_logger(tmp / "diagnosis.rrd", f"vidsim.{stage}", rerun) as lg:
        log_diagnosis(lg, d, masks)
    chaos = _chaos_px(d)
    print(f"{stage} {title}: {verdict_text(d)} (held-out gap {d.gap_per_frame[d.test].mean():.1f} px, "
          f"floor {d.floor_test.mean():.1f} px" + (f", the model's own chaos {chaos:.1f} px" if chaos is not None else "")
          + f", {d.seconds:.0f} s)", file=sys.stderr)
    replace_dir(tmp, out)


def _chaos_px(d: Any) -> float | None:
    """The held-out mean of a cloth diagnosis's ``where.model_chaos`` (None: not measured)."""
    mc = getattr(d, "where", {}).get("model_chaos") or {}
    return mc.get("heldout_px")


def _chaos_per_frame(d: Any) -> np.ndarray | None:
    mc = getattr(d, "where", {}).get("model_chaos") or {}
    return None if mc.get("per_frame_px") is None else np.asarray(mc["per_frame_px"], float)


def verdict_text(d: Any) -> str:
    """The verdict, and for each named effect the supported candidates the held-out frames could
    not tell from it (``as_good_on_heldout`` of its refit), e.g. "explained by time_offset (grips);
    undecided: time_offset as good as rolling_shutter on the held-out frames"."""
    keys = d.named_refit_keys() if hasattr(d, "named_refit_keys") else ["+".join(d.named[: i + 1]) for i in range(len(d.named))]
    alike = [f"{n} as good as {', '.join(r['as_good_on_heldout'])}" for n, k in zip(d.named, keys)
             for r in [d.refits.get(k, {})] if r.get("as_good_on_heldout")]
    return d.verdict + (f"; undecided: {'; '.join(alike)} on the held-out frames" if alike else "")


def plot_diagnosis(d: RigidDiagnosis, path: Path, title: str = "", floor_label: str = FLOOR_LABEL) -> None:
    """Three panels: gap per frame (held-out marked, floor, after the named effect), screen, heatmap.
    ``d`` is a rigid or a cloth diagnosis (same fields); ``floor_label`` says how its floor was measured."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(16, 4.2))
    fr = d.frames
    ax[0].plot(fr, d.gap_per_frame, "k.-", label="base model (refit on training frames)")
    ax[0].plot(fr[d.test], d.gap_per_frame[d.test], "ko", mfc="none", ms=8, label="held-out frames")
    ax[0].plot(fr[d.test], d.floor_test, "s", color="gray", ms=4, label=floor_label)
    chaos = _chaos_per_frame(d)
    if chaos is not None:
        ax[0].plot(fr, chaos, ":", color="tab:purple",
                   label=f"the model's own chaos (the fit vs copies moved by {d.where['model_chaos']['sigma']:g})")
    keys = d.named_refit_keys() if hasattr(d, "named_refit_keys") else ["+".join(d.named[: i + 1]) for i in range(len(d.named))]
    region = d.extra.get("primary_region") if hasattr(d, "extra") else None
    for name in keys[:2]:
        r = d.refits[name]
        if region is not None and r.get("region") != region:
            continue  # judged on another pass's pixels (a split cloth diagnosis): another scale
        ax[0].plot(fr, np.asarray(r["gap_per_frame_after_px"]), ".-", label=f"+ {name}")
    ax[0].set_xlabel("frame")
    ax[0].set_ylabel("mismatch, full-res pixels")
    ax[0].set_title(f"where: gap per frame -- {verdict_text(d)}", fontsize=9)
    ax[0].legend(fontsize=7)
    items = sorted(((k, v) for k, v in d.screen.items() if "rank" in v), key=lambda kv: kv[1]["rank"])
    names = [k for k, _ in items]
    vals = [max(v["fraction"], 0.0) for _, v in items]
    refitted = {key.split(":", 1)[-1] for key in d.refits}  # a split cloth diagnosis prefixes its region
    colors = ["tab:green" if k in d.named else ("tab:orange" if k in refitted else "tab:gray") for k in names]
    ax[1].barh(names[::-1], vals[::-1], color=colors[::-1])
    ax[1].set_xlabel("score-test screen: first-order share of the residual")
    ax[1].set_title("which: green named, orange refitted", fontsize=9)
    im = ax[2].imshow(d.signed_heatmap, cmap="coolwarm",
                      vmin=-np.abs(d.signed_heatmap).max() - 1e-9, vmax=np.abs(d.signed_heatmap).max() + 1e-9)
    ax[2].set_title("accumulated residual (red: model covers, blue: footage covers)", fontsize=9)
    fig.colorbar(im, ax=ax[2], fraction=0.035)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, path)


def log_diagnosis(lg: Any, d: RigidDiagnosis, masks: np.ndarray, prefix: str = "") -> None:
    """Footage silhouettes, per-frame gap curves (base, floor, after each refit) on the frame timeline."""
    after = {k: np.asarray(v["gap_per_frame_after_px"]) for k, v in d.refits.items()}
    floor = dict(zip(d.test.tolist(), d.floor_test.tolist()))
    chaos = _chaos_per_frame(d)
    for i, k in enumerate(d.frames):
        lg.set_frame(int(k))
        lg.mask(f"{prefix}footage/camera/mask", masks[k])
        lg.scalar(f"{prefix}metric/gap_base_px", float(d.gap_per_frame[i]))
        if i in floor:
            lg.scalar(f"{prefix}metric/noise_floor_px", float(floor[i]))
        if chaos is not None:
            lg.scalar(f"{prefix}metric/model_chaos_px", float(chaos[i]))
        for name, g in after.items():
            lg.scalar(f"{prefix}metric/gap_after_{name.replace(':', '_')}_px", float(g[i]))
    lg.set_frame(int(d.frames[-1]))
    lg.image(f"{prefix}gap/heatmap", _heat_rgb(d.signed_heatmap))
    lg.text(f"{prefix}gap/verdict", verdict_text(d))


def _heat_rgb(h: np.ndarray) -> np.ndarray:
    m = float(np.abs(h).max()) or 1.0
    x = np.clip(h / m, -1, 1)
    rgb = np.zeros(h.shape + (3,), np.uint8)
    rgb[..., 0] = (255 * np.clip(x, 0, 1)).astype(np.uint8)
    rgb[..., 2] = (255 * np.clip(-x, 0, 1)).astype(np.uint8)
    rgb[..., 1] = (64 * (1 - np.abs(x))).astype(np.uint8)
    return rgb


def diagnose_config(node: Any):
    """:class:`~vidsim.gap.rigid_diagnose.DiagnoseConfig` from the ``gap.diagnose`` node (validated)."""
    from omegaconf import OmegaConf

    from vidsim.gap.rigid_diagnose import DiagnoseConfig

    d = OmegaConf.to_container(node, resolve=True) if not isinstance(node, dict) else dict(node)
    cfg = DiagnoseConfig(**d)
    cfg.validate()
    return cfg
