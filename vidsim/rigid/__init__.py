"""vidsim.rigid: rigid bodies from video (seed section 3).

Modules: ``body`` (box-union bodies, the T-object), ``dynamics`` (Newton-Euler RK4 with
variational-equation sensitivities), ``silhouette`` (smoothed silhouette mismatch and its
image-space pose gradient), ``fit`` (hybrid-gradient multi-start estimation), ``evaluate``
(scoring against a synthetic truth), ``ballistic`` (real ball free flight), ``outputs``
(overlays, paths, the ``fit.yaml`` and ``masks.npz`` formats) and ``stage`` (stage-level drivers).
The command-line stages are ``vidsim.cli.{reality_rigid,segment,fit_rigid,score_rigid,
rigid_summary,rigid_ball}``.
"""
