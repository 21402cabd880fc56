"""vidsim.cli: one Hydra app per pipeline stage (``python -m vidsim.cli.<stage>``).

Imported before any stage module (and so before numpy), this sets the BLAS/OpenMP thread counts to
one unless the caller set them: Snakemake runs each job with one thread, and a stage run by hand
must give the same numbers (BLAS sums in a thread-count-dependent order; seen as 2e-4 rad/s
differences in a rigid fit). Set e.g. ``OPENBLAS_NUM_THREADS=2`` to trade that for speed.
"""

import os as _os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
