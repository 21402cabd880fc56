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


def _numba_cache_dir() -> None:
    """One numba cache folder per version of the package's source.

    numba's on-disk cache checks only the file that defines each jitted function: a kernel that
    calls a jitted function of another file keeps the old callee's machine code after that file
    changed (seen 5 Dec 2026: a fix in ``cloth/collision.py`` did not reach the cached RK45 loop
    of ``cloth/integrate.py``). So the cache lives in ``<repo>/.numba_cache/<hash of every .py
    file of the package>``, unless ``NUMBA_CACHE_DIR`` is set; folders of other versions unused for
    two days are removed. Must run before numba is imported (it is: this is the package's first
    module)."""
    import hashlib
    import os
    import shutil
    import time
    from pathlib import Path

    global SOURCE_DIGEST
    root = Path(__file__).resolve().parent
    h = hashlib.sha1()
    for f in sorted(root.rglob("*.py")):
        h.update(f.relative_to(root).as_posix().encode())
        h.update(f.read_bytes())
    SOURCE_DIGEST = h.hexdigest()
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    base = root.parent / ".numba_cache"
    here = base / h.hexdigest()[:16]
    os.environ["NUMBA_CACHE_DIR"] = str(here)
    try:
        here.mkdir(parents=True, exist_ok=True)
        os.utime(here)
        for old in base.iterdir():
            if old != here and old.is_dir() and time.time() - old.stat().st_mtime > 2 * 86400:
                shutil.rmtree(old, ignore_errors=True)
    except OSError:  # a read-only checkout: numba falls back to its own choice of folder
        pass


#: SHA-1 of every .py file of the package (the code version: checkpoints of intermediate work that
#: code changes invalidate carry it in their keys)
SOURCE_DIGEST = ""
_numba_cache_dir()
