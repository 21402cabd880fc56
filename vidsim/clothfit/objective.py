"""The cloth objective: simulate, render stripes, angle maps, metric (seed eqs. 12-16).

For parameters ``theta`` the estimator's simulator (:func:`vidsim.cloth.simulate`, "fast"
velocity-Verlet at its stable step) moves a swatch whose top corners follow the *measured*
paths of ``meta.yaml`` (or a skirt whose waistband follows the measured body, with the legs as
colliders: :mod:`vidsim.clothfit.rig`); every frame is rendered by the fast rasteriser with the *calibrated*
camera and projector (:func:`vidsim.render.projector.render_stripes_batch`, shadows on); the
simulated silhouette is where the rasteriser hit the cloth; angle maps come from the same
filter bank as the footage's; and the error is :func:`vidsim.video.anglemap.cloth_metric`
(fold term masked by the footage's gradient mask + ``alpha`` x silhouette mismatch, mean per
frame). A joint objective over several trials sums the per-trial errors (E1 + E2).

A simulation that diverges gives :data:`vidsim.optim.FAILED_SCORE` (finite, huge) with the
failure text in ``info``: never an exception inside an optimiser, never NaN.
"""

from __future__ import annotations

from collections.abc import Mapping

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from vidsim.cloth import ESTIMATED_NAMES, ClothParams, mid_range_params, simulate
from vidsim.cloth.simulate import DAMPING_MODES, ClothStepError
from vidsim.clothfit.features import ClothFeatures, FeatureSettings, angle_features
from vidsim.clothfit.film import swatch_driver, swatch_model_mesh
from vidsim.clothfit.rig import SkirtBody, skirt_fold_starts, skirt_model_rig
from vidsim.errors import VidsimError
from vidsim.optim import FAILED_SCORE
from vidsim.optim.space import Space
from vidsim.render.projector import Projector, render_stripes_batch
from vidsim.video.anglemap import cloth_metric
from vidsim.video.camera import PinholeCamera

__all__ = ["ObjectiveError", "Trial", "ModelSettings", "EvalResult", "ClothObjective", "space_from_config"]


class ObjectiveError(VidsimError):
    """Inconsistent objective inputs (names the field)."""


@dataclass
class Trial:
    """One filmed trial as the estimator sees it.

    Attributes:
        name: label (e.g. ``linen/exp1``).
        features: footage features of the cloth frames.
        times: (T,) frame times, seconds.
        corner_paths: (T, 2, 3) measured corner positions, metres ((T, 0, 3) for a skirt).
        camera: calibrated camera.
        projector: calibrated projector with the known stripe pattern.
        size: swatch side, metres (measured; unused for a skirt).
        density: areal density, kg/m^2 (measured).
        skirt: the measured body motion and cut of a skirt trial (None: a swatch trial).
        drive_times, drive_paths, drive_skirt: the measured motion that drives the model, at the
            footage's full rate (None: ``times``, ``corner_paths`` and ``skirt`` themselves).
            :meth:`strided` compares every k-th frame but keeps driving the model by every measured
            sample: until 4 Dec 2026 the model's grips followed a spline through every k-th sample
            only (on the exp1 motion 2.6 mm off the measured path at stride 2, 18 mm at stride 4).
    """

    name: str
    features: ClothFeatures
    times: np.ndarray
    corner_paths: np.ndarray
    camera: PinholeCamera
    projector: Projector
    size: float
    density: float
    skirt: SkirtBody | None = None
    drive_times: np.ndarray | None = None
    drive_paths: np.ndarray | None = None
    drive_skirt: SkirtBody | None = None

    def __post_init__(self) -> None:
        T = self.features.n_frames
        self.times = np.asarray(self.times, float)
        self.corner_paths = np.asarray(self.corner_paths, float)
        if self.drive_times is None:
            self.drive_times, self.drive_paths, self.drive_skirt = self.times, self.corner_paths, self.skirt
        else:
            self.drive_times = np.asarray(self.drive_times, float)
            self.drive_paths = np.asarray(self.drive_paths, float)
            D = self.drive_times.size
            if (self.drive_times.ndim != 1 or self.drive_paths.shape != (D,) + self.corner_paths.shape[1:]
                    or (self.skirt is None) != (self.drive_skirt is None)
                    or (self.drive_skirt is not None and self.drive_skirt.n_frames != D)
                    or D < 2 or self.drive_times[0] > self.times[0] or self.drive_times[-1] < self.times[-1]):
                raise ObjectiveError(f"trial {self.name}: the driving motion ({D} samples, paths "
                                     f"{self.drive_paths.shape}) must cover the compared frames' times "
                                     f"[{self.times[0]}, {self.times[-1]}] s with the trial's corners/body")
        n_grip = 0 if self.skirt is not None else 2
        if self.times.shape != (T,) or self.corner_paths.shape != (T, n_grip, 3):
            raise ObjectiveError(f"trial {self.name}: {T} feature frames but times {self.times.shape} and corner "
                                 f"paths {self.corner_paths.shape} (expected ({T}, {n_grip}, 3))")
        if self.skirt is not None and self.skirt.n_frames != T:
            raise ObjectiveError(f"trial {self.name}: {T} feature frames but the skirt body has {self.skirt.n_frames}")
        if self.features.sil.shape[1:] != (self.camera.height, self.camera.width):
            raise ObjectiveError(f"trial {self.name}: frames {self.features.sil.shape[1:]} differ from the calibrated "
                                 f"camera ({self.camera.height}, {self.camera.width})")

    def strided(self, stride: int, max_frames: int = 0) -> "Trial":
        """Every ``stride``-th frame (and at most ``max_frames``, 0 = all)."""
        idx = np.arange(0, self.features.n_frames, max(1, int(stride)))
        if max_frames > 0:
            idx = idx[:max_frames]
        return Trial(self.name, self.features.subset(idx), self.times[idx], self.corner_paths[idx], self.camera,
                     self.projector, self.size, self.density,
                     None if self.skirt is None else self.skirt.subset(idx),
                     self.drive_times, self.drive_paths, self.drive_skirt)


def multirate_setting(value: object) -> int | str:
    """``cloth.model.multirate`` as :func:`vidsim.cloth.simulate` takes it: "auto" or a whole number >= 1."""
    text = str(value).strip()
    if text == "auto":
        return "auto"
    try:
        r = int(text)
    except ValueError:
        r = 0
    if r < 1 or str(r) != text:
        raise ObjectiveError(f"cloth.model.multirate must be 'auto' or a whole number >= 1, got {value!r}")
    return r


@dataclass(frozen=True)
class ModelSettings:
    """The estimator's simulator settings (see :class:`vidsim.config.cloth.ClothModelConfig`).

    ``resolution``: swatch vertices per side; ``skirt_rings``/``skirt_around``: the skirt model's
    rings and vertices per ring; ``skirt_rest_bend``: its bending rest state
    (:data:`vidsim.clothfit.rig.SKIRT_REST_BEND`); ``skirt_fold_members`` > 0 with
    ``skirt_fold_amplitude`` > 0 [m]: a skirt trial's error is the mean over that many fold-seeded
    starts (:func:`vidsim.clothfit.rig.skirt_fold_starts`, seed ``skirt_fold_seed``); 0: one start
    in the exact cone. Defaults as ``cloth.skirt`` (:class:`vidsim.config.cloth.ClothSkirtConfig`).
    ``multirate``: the "fast" scheme's bending kicks once per that many steps ("1", the default:
    plain velocity Verlet; "auto": from the ratio of stable steps), :func:`vidsim.cloth.simulate`'s
    ``multirate``.
    ``damping``: "explicit", "split" or "auto", :func:`vidsim.cloth.simulate`'s ``damping``.
    ``chaos_members`` > 0: a swatch trial's error is the mean over that many copies of the
    parameters, each of the nine scaled by fixed draws of exp(N(0, ``chaos_sigma``)) (the same
    draws for every evaluation, so the averaged objective is a deterministic function); 0: the
    parameters as given. An experiment against the chaotic loss (docs/cloth_study.md, "Session 36").
    """

    resolution: int = 20
    settle_s: float = 0.5
    settle_bath: float = 0.0
    integrator: str = "fast"
    multirate: str = "1"
    damping: str = "auto"
    skirt_rings: int = 8
    skirt_around: int = 24
    skirt_rest_bend: str = "cone"
    skirt_fold_members: int = 8
    skirt_fold_amplitude: float = 0.02
    skirt_fold_seed: int = 0
    chaos_members: int = 0
    chaos_sigma: float = 1e-4


CHAOS_SEED = 20261205  # the chaos members' fixed draws


def chaos_scales(members: int, sigma: float) -> list[dict[str, float] | None]:
    """Per chaos member the factor of each of the nine parameters (``[None]``: no members)."""
    if members <= 0:
        return [None]
    rng = np.random.default_rng(CHAOS_SEED)
    return [{n: float(np.exp(rng.normal(0.0, sigma))) for n in ESTIMATED_NAMES} for _ in range(members)]


@dataclass
class EvalResult:
    """One evaluation.

    Attributes:
        score: total error (sum over trials of the mean per-frame error), or FAILED_SCORE.
        per_trial: per-trial mean per-frame error.
        e_fold, e_silh: per-trial (T,) arrays (rad^2, pixels).
        ok: all simulations completed.
        failure: failure text or None.
        timing: seconds spent in ``simulate``, ``render``, ``anglemap``, ``metric``.
        positions: per-trial (T, N, 3) simulated vertices (only when requested).
        theta_sim, sil_sim: per-trial simulated angle maps / silhouettes (only when requested).
        members: per trial, the error of each member of its ensemble (a skirt's fold-seeded starts,
            a swatch's chaos members; one entry otherwise); ``per_trial`` is their mean. The kept
            outputs (``keep``) are member 0's: with chaos members a moved copy of the parameters.
    """

    score: float
    per_trial: list[float]
    e_fold: list[np.ndarray]
    e_silh: list[np.ndarray]
    ok: bool
    failure: str | None
    timing: dict[str, float]
    positions: list[np.ndarray] = field(default_factory=list)
    theta_sim: list[np.ndarray] = field(default_factory=list)
    sil_sim: list[np.ndarray] = field(default_factory=list)
    images: list[np.ndarray] = field(default_factory=list)
    members: list[list[float]] = field(default_factory=list)


def space_from_config(space: dict) -> Space:
    """A :class:`Space` over estimated parameters from ``{name: {lo, hi, log}}``, names checked."""
    bad = [n for n in space if n not in ESTIMATED_NAMES]
    if bad:
        raise ObjectiveError(f"cloth.fit.space: unknown parameter(s) {bad}; expected names from {list(ESTIMATED_NAMES)}")
    return Space.from_config({k: dict(v) if isinstance(v, Mapping) else v for k, v in space.items()})


class ClothObjective:
    """Error of parameters against one or more trials.

    Args:
        trials: the trials (their errors are summed).
        space: the estimated parameters and their box (unit-cube mapping).
        fixed: values of parameters not in ``space`` (default mid-range), SI.
        model: simulator settings.
        features: the angle-map settings used for the footage.
        alpha: silhouette weight of the metric (rad^2 per pixel).
    """

    def __init__(self, trials: list[Trial], space: Space, fixed: dict[str, float] | None = None,
                 model: ModelSettings = ModelSettings(), features: FeatureSettings = FeatureSettings(),
                 alpha: float = 0.1) -> None:
        if not trials:
            raise ObjectiveError("objective needs at least one trial")
        if model.integrator not in ("fast", "rk45"):
            raise ObjectiveError(f"cloth.model.integrator must be 'fast' or 'rk45', got {model.integrator!r}")
        self._multirate = multirate_setting(model.multirate)
        if model.damping not in DAMPING_MODES or (model.damping == "split" and model.integrator != "fast"):
            raise ObjectiveError(f"cloth.model.damping must be one of {DAMPING_MODES} ('split' with the fast "
                                 f"integrator only), got {model.damping!r} with integrator {model.integrator!r}")
        if int(model.skirt_fold_members) != model.skirt_fold_members or model.skirt_fold_members < 0:
            raise ObjectiveError(f"cloth.skirt.model_fold_members must be an integer >= 0, got {model.skirt_fold_members!r}")
        if not (np.isfinite(model.skirt_fold_amplitude) and model.skirt_fold_amplitude >= 0):
            raise ObjectiveError(f"cloth.skirt.model_fold_amplitude must be a finite length >= 0 m, "
                                 f"got {model.skirt_fold_amplitude!r}")
        if int(model.skirt_fold_seed) != model.skirt_fold_seed or model.skirt_fold_seed < 0:
            raise ObjectiveError(f"cloth.skirt.model_fold_seed must be an integer >= 0, got {model.skirt_fold_seed!r}")
        if int(model.chaos_members) != model.chaos_members or model.chaos_members < 0:
            raise ObjectiveError(f"cloth.model.chaos_members must be an integer >= 0, got {model.chaos_members!r}")
        if not (np.isfinite(model.chaos_sigma) and 0 <= model.chaos_sigma <= 1):
            raise ObjectiveError(f"cloth.model.chaos_sigma must be in [0, 1] (a log-scale spread; 1e-4 moves the "
                                 f"parameters by 0.01 %), got {model.chaos_sigma!r}")
        self._chaos = chaos_scales(int(model.chaos_members), float(model.chaos_sigma))
        self.trials = trials
        self.space = space
        self.model = model
        self.features = features
        self.alpha = float(alpha)
        if not (np.isfinite(self.alpha) and self.alpha >= 0):
            raise ObjectiveError(f"cloth.fit.alpha (silhouette weight) must be finite and >= 0, got {alpha}")
        unknown = set(fixed or {}) - set(ESTIMATED_NAMES)
        if unknown:
            raise ObjectiveError(f"cloth.fit.fixed: unknown parameter(s) {sorted(unknown)}")
        both = sorted(set(fixed or {}) & set(space.names))
        if both:
            raise ObjectiveError(f"cloth.fit.fixed sets {both}, which are also estimated (cloth.fit.estimate / "
                                 f"cloth.fit.space): the fixed value would be ignored; drop them from one of the two")
        self.fixed = dict(fixed or {})
        self._check_box(trials[0].density)
        self._rigs = []
        for tr in trials:
            starts: list = [None]
            if tr.skirt is not None:
                mesh, drv, t0, col = skirt_model_rig(tr.drive_skirt, tr.drive_times, model.skirt_rings,
                                                     model.skirt_around, model.settle_s, model.skirt_rest_bend)
                if model.skirt_fold_members > 0 and model.skirt_fold_amplitude > 0:
                    starts = skirt_fold_starts(mesh, tr.skirt, model.skirt_fold_members, model.skirt_fold_amplitude,
                                               model.skirt_fold_seed)
            else:
                mesh = swatch_model_mesh(tr.corner_paths[0], model.resolution, tr.size)
                drv, t0 = swatch_driver(mesh, tr.drive_times, tr.drive_paths, model.settle_s)
                col = None
            self._rigs.append((mesh, drv, t0, col, starts))
        self.n_evals = 0

    def fingerprint(self) -> str:
        """What decides a score, hashed (:func:`vidsim.optim.cache.fingerprint`): every trial's
        footage features, times, corner paths, camera, projector, size, density and skirt (not its
        label), the parameter space, the fixed values, the model and feature settings, alpha, the
        simulator's kernel version and the package's source digest (``vidsim.SOURCE_DIGEST``: the
        renderer, the angle maps and the metric decide a score too, and a change to any of them
        must not replay scores of the old code). The fits' evaluation logs carry it, so a rerun
        after any of these changed does not replay the old scores."""
        from dataclasses import fields as dc_fields

        import vidsim
        from vidsim.cloth.integrate import KERNEL_VERSION
        from vidsim.optim.cache import fingerprint

        trials = [{f.name: getattr(tr, f.name) for f in dc_fields(tr) if f.name != "name"} for tr in self.trials]
        return fingerprint("ClothObjective", trials, self.space, self.fixed, self.model, self.features, self.alpha,
                           KERNEL_VERSION, vidsim.SOURCE_DIGEST)

    @property
    def meshes(self) -> list:
        """The model mesh of each trial (:class:`~vidsim.cloth.ClothMesh`)."""
        return [r[0] for r in self._rigs]

    @property
    def starts(self) -> list[list]:
        """Per trial its start positions (``[None]``: the mesh's rest state; skirts: the fold seeds)."""
        return [r[4] for r in self._rigs]

    def _check_box(self, density: float) -> None:
        """Refuse a box whose ends are not physical (e.g. a negative drag), before any evaluation:
        mid-fit, the first point beyond it would stop the run, and a resumed run at the same point."""
        mid = self.space.from_unit(np.full(self.space.dim, 0.5))
        try:
            self.params(mid, density)
        except ValueError as e:
            raise ObjectiveError(f"cloth.fit.fixed: {e}") from None
        for j, ax in enumerate(self.space.axes):
            for end, val in (("lo", ax.lo), ("hi", ax.hi)):
                th = mid.copy()
                th[j] = val
                try:
                    self.params(th, density)
                except ValueError as e:
                    raise ObjectiveError(f"cloth.fit.space.{ax.name}.{end} = {val}: {e}") from None

    # ------------------------------------------------------------------ parameters
    def params(self, theta: np.ndarray, density: float) -> ClothParams:
        """Full :class:`ClothParams` from the estimated vector ``theta`` (space order, SI)."""
        base = mid_range_params(density=density)
        kw = {**self.fixed, **self.space.as_dict(theta)}
        return base.replace(**kw)

    def theta_of(self, params: ClothParams) -> np.ndarray:
        """The estimated vector of full parameters (space order)."""
        return np.array([getattr(params, n) for n in self.space.names], float)

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, theta: np.ndarray, keep: bool = False) -> EvalResult:
        """Evaluate physical parameters ``theta`` (space order, SI units; each trial's own density).

        Args:
            theta: (n,) estimated parameters.
            keep: also return positions, simulated angle maps, silhouettes and images.
        """
        return self._evaluate([self.params(theta, tr.density) for tr in self.trials], keep)

    def evaluate_params(self, params: ClothParams, keep: bool = False) -> EvalResult:
        """Evaluate one complete parameter set (all nine and its density) on every trial.

        This is how another fabric's parameters are tried on this footage (validation matrices):
        the set is simulated as it is, its own density included.
        """
        return self._evaluate([params] * len(self.trials), keep)

    def _evaluate(self, plist: list[ClothParams], keep: bool) -> EvalResult:
        timing = {"simulate": 0.0, "render": 0.0, "anglemap": 0.0, "metric": 0.0}
        per, ef, es = [], [], []
        out = EvalResult(FAILED_SCORE, per, ef, es, True, None, timing)
        self.n_evals += 1
        for tr, (mesh, drv, t0, col, starts), p in zip(self.trials, self._rigs, plist):
            # a skirt's fold-seeded ensemble: the trial's errors are the members' means (member 0 is kept)
            # a swatch's chaos members (cloth.model.chaos_members): the same, one copy per parameter scaling
            m_e, m_fold, m_silh = [], [], []
            chaos = self._chaos if tr.skirt is None else [None]
            members = [(x0, sc) for x0 in starts for sc in chaos]
            for k, (x0, sc) in enumerate(members):
                member = (f" (fold-seeded start {k})" if x0 is not None else
                          f" (chaos member {k})" if sc is not None else "")
                pk = p if sc is None else dataclasses.replace(p, **{n: getattr(p, n) * sc[n] for n in ESTIMATED_NAMES})
                t = time.perf_counter()
                try:
                    res = simulate(mesh, pk, drv, tr.times, integrator=self.model.integrator, t0=t0, colliders=col,
                                   settle_bath=self.model.settle_bath, x0=x0, multirate=self._multirate,
                                   damping=self.model.damping)
                except (ArithmeticError, ClothStepError) as e:  # a numerical fault, or a step these
                    # parameters cannot take with the settle bath: a failed run of this set
                    timing["simulate"] += time.perf_counter() - t
                    out.ok, out.failure = False, f"{tr.name}{member}: simulator raised {type(e).__name__}: {e}"
                    return out
                timing["simulate"] += time.perf_counter() - t
                if not res.ok:
                    out.ok, out.failure = False, f"{tr.name}{member}: {res.failure}"
                    return out
                t = time.perf_counter()
                img, depth = render_stripes_batch(res.positions, mesh.triangles, tr.camera, tr.projector, shadows=True)
                sil = np.isfinite(depth)
                timing["render"] += time.perf_counter() - t
                t = time.perf_counter()
                th, _ = angle_features(img, sil, self.features)
                timing["anglemap"] += time.perf_counter() - t
                t = time.perf_counter()
                f = tr.features
                e, e_fold, e_silh = cloth_metric(f.theta, f.mask, f.sil, th, sil, alpha=self.alpha)
                timing["metric"] += time.perf_counter() - t
                m_e.append(e)
                m_fold.append(e_fold)
                m_silh.append(e_silh)
                if keep and k == 0:
                    out.positions.append(res.positions)
                    out.theta_sim.append(th)
                    out.sil_sim.append(sil)
                    out.images.append(img)
            per.append(float(np.mean(m_e)))
            out.members.append([float(x) for x in m_e])
            ef.append(np.mean(m_fold, axis=0))
            es.append(np.mean(m_silh, axis=0))
        out.score = float(sum(per))
        if not np.isfinite(out.score):
            bad = [tr.name for tr, e in zip(self.trials, per) if not np.isfinite(e)]
            out.ok, out.failure, out.score = False, f"{', '.join(bad) or 'sum over the trials'}: non-finite metric", FAILED_SCORE
        return out

    def __call__(self, u: np.ndarray) -> tuple[float, dict]:
        """Objective on the unit cube for the optimisers: ``(score, info)``."""
        theta = self.space.from_unit(u)
        r = self.evaluate(theta)
        info = {"theta": [float(x) for x in theta], "per_trial": r.per_trial,
                "timing": {k: round(v, 4) for k, v in r.timing.items()}}
        if not r.ok:
            info["failure"] = r.failure
        return r.score, info
