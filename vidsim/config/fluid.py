"""Hydra schema of the ``fluid`` config group (conf/fluid/*.yaml extend it).

The fluid stages (``vidsim/cli/fluid_*.py``, seed section 5): synthetic footage from a
stable-fluids reality (``reality_fluid``), real PIV recordings imported as footage
(``fluid_piv_footage``), optical flow against truth and on Middlebury (``fluid_flow``,
``fluid_middlebury``), source-sink edits rendered by texture transfer (``fluid_edit``) and the
collected metrics table (``fluid_metrics``). Units: pixels and frames (velocities px/frame),
seconds for ``fps``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional


@dataclass
class FluidRealityConfig:
    """Synthetic fluid footage (:func:`vidsim.reality.fluid.make_scene`).

    ``scene``: ``waterfall`` | ``stream_boat`` | ``flame``; ``size``: square image side (px);
    ``n_frames``: recorded frames; ``warmup``: solver frames before recording (None: the
    scene's default); ``noise_sigma``: camera noise (grey levels); ``fps``: nominal frame rate
    written to ``times.csv``.
    """

    scene: str = "waterfall"
    size: int = 128
    n_frames: int = 120
    seed: int = 0
    warmup: Optional[int] = None
    noise_sigma: float = 1.5
    jacobi_iters: int = 60
    fps: float = 30.0


@dataclass
class FluidPivConfig:
    """A real PIV recording imported as footage: ``name`` is ``karman`` (the 4 PIVlab frames of
    a cylinder wake, 1024x765) or ``jet`` (PIVlab's water jet: the A/B exposures of pair 1, in
    that order); ``downsample`` an integer area-downsampling factor; ``fps`` nominal."""

    name: str = "karman"
    downsample: int = 4
    fps: float = 30.0


@dataclass
class FluidFlowConfig:
    """Optical flow: ``method`` ``dis_fine`` | ``dis_medium`` | ``farneback``;
    ``temporal_sigma`` Gaussian smoothing of the flow along time (frames, 0 = off);
    ``baseline`` the reference method also scored (OpenCV's DIS medium preset);
    ``arrow_step`` pixels between arrows in figures and recordings."""

    method: str = "dis_fine"
    temporal_sigma: float = 1.0
    baseline: str = "dis_medium"
    arrow_step: int = 8


@dataclass
class FluidEditConfig:
    """One source-sink edit (format: ``docs/fluid_editing.md``).

    ``spec``: path of the edit YAML (relative to the working directory); ``flow``: the
    ``flow.npz`` of the footage from ``fluid_flow`` (empty: estimate it here); ``frames``: output
    frames (None: the YAML's ``render.frames``); ``iterations``: optimiser iterations (None:
    the YAML's); ``checkpoint_every``: optimiser iterations between checkpoints (resume after a
    kill); ``video_fps``: frame rate of the rendered mp4/gif; ``gif_frames``: frames in the gif.
    """

    spec: str = ""
    flow: str = ""
    frames: Optional[int] = None
    iterations: Optional[int] = None
    checkpoint_every: int = 5
    video_fps: float = 24.0
    gif_frames: int = 24


@dataclass
class FluidConfig:
    """Settings of the fluid stages.

    ``inputs``: for ``fluid_metrics``, the stage outputs (summary files) to collect.
    """

    enabled: bool = True
    reality: FluidRealityConfig = field(default_factory=FluidRealityConfig)
    piv: FluidPivConfig = field(default_factory=FluidPivConfig)
    flow: FluidFlowConfig = field(default_factory=FluidFlowConfig)
    edit: FluidEditConfig = field(default_factory=FluidEditConfig)
    inputs: list[str] = field(default_factory=list)


def check_fluid_numbers(node, prefix: str, rules: dict) -> None:
    """Refuse a non-physical or meaningless setting with one line naming it (``ConfigError``).

    ``rules``: ``{field: (kind, lower bound)}`` with kind ``"int"`` or ``"float"``; the value must
    be a finite number of that kind strictly above the bound.
    """
    import math

    from vidsim.errors import ConfigError

    for name, (kind, lo) in rules.items():
        v = getattr(node, name)
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v)) and float(v) > lo
        if ok and kind == "int":
            ok = float(v) == int(v)
        if not ok:
            what = "a whole number" if kind == "int" else "a finite number"
            raise ConfigError(f"{prefix}.{name}={v!r}: expected {what} > {lo:g}")
