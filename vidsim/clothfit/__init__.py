"""vidsim.clothfit: cloth parameters from structured-light video (seed sections 4.3-4.5).

* :mod:`vidsim.clothfit.film` -- reality side: film cloth vertices with pyrender, a striped
  projector (shadows, 1/d^2 falloff), sensor noise, blur, optional motion blur, unknown lens
  distortion and projector misalignment; and the twin reality (the estimator's own simulator at
  a finer mesh with known parameters).
* :mod:`vidsim.clothfit.features` -- silhouettes (background model, never truth) and angle maps
  with gradient masks of a footage clip.
* :mod:`vidsim.clothfit.objective` -- the objective: simulate the swatch driven by the measured
  corner paths, render stripes with the calibrated camera and projector, angle maps, metric
  (seed eqs. 12-16); one or several trials (joint fit).
* :mod:`vidsim.clothfit.study` -- coarse grid + annealing / CMA-ES with on-disk evaluation
  caches, cross-trial selection (Table 1), error matrices (Figure 8), profiles.
"""
