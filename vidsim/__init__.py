"""vidsim: physically based animation from video.

Sub-packages (one concept each):

- ``vidsim.video``: camera model, calibration, segmentation, angle maps (image -> features).
- ``vidsim.render``: pyrender (EGL) renderer and the fast numba rasteriser for inner loops.
- ``vidsim.io``: footage folder format, atomic writes, validated readers (all file I/O lives here).
- ``vidsim.log``: Rerun recordings behind a small logger interface.
- ``vidsim.reality``: independent "real world" generators (MuJoCo + pyrender + camera imperfections).
- ``vidsim.rigid``: Newton-Euler free flight, state sensitivities, silhouette fitting.
- ``vidsim.cloth``: Baraff-Witkin cloth with nonlinear air drag.
- ``vidsim.fluid``: velocity from video, source-sink editing, texture transfer.
- ``vidsim.optim``: optimisers sharing ``objective(theta) -> float`` plus bounds; posteriors.
- ``vidsim.gap``: sim-to-real gap diagnosis.
- ``vidsim.config``: Hydra structured-config schemas.
- ``vidsim.cli``: thin Hydra entry points, one per stage.
"""

__version__ = "0.1.0"
