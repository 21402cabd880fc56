"""Shared plumbing of the cloth stages: footage folder -> :class:`~vidsim.clothfit.objective.Trial`,
config -> objective, parameter tables. File reading goes through :mod:`vidsim.io.footage` only.
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import fields as dc_fields
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from omegaconf import DictConfig, OmegaConf

from vidsim.cloth import ESTIMATED_NAMES, ClothParams
from vidsim.clothfit.features import FeatureSettings, extract_features
from vidsim.clothfit.objective import ClothObjective, ModelSettings, Trial, space_from_config
from vidsim.clothfit.rig import RigError, SkirtBody
from vidsim.errors import VidsimError
from vidsim.io.footage import load_yaml, read_footage, read_meta
from vidsim.log.progress import Progress
from vidsim.render.projector import Projector

__all__ = ["ClothStageError", "feature_settings", "load_trial", "make_objective", "params_dict", "fixed_params",
           "object_kind", "params_from_dict", "read_selected", "fabric_sets", "fabric_matrix", "matrix_figure", "matrix_csv",
           "irradiance_to_uint8", "LoggedScores", "CellScore"]

#: what a cloth footage folder's meta.yaml must give (known inputs), for every object and per
#: object kind (``object: {kind: swatch | skirt}``; a folder without ``object`` is a swatch)
REQUIRED_META = ("scene", "background_frames", "areal_density", "projector_pattern")
REQUIRED_META_KIND = {"swatch": ("corner_paths", "size_m"), "skirt": ("body",)}


class ClothStageError(VidsimError):
    """A cloth stage's input is missing or inconsistent (names the file and field)."""


def feature_settings(cfg: DictConfig) -> FeatureSettings:
    """:class:`FeatureSettings` from ``cloth.features``."""
    return FeatureSettings(**OmegaConf.to_container(cfg.cloth.features, resolve=True))


def _meta_number(d: dict, key: str, where: str, unit: str, positive: bool = False, default: float | None = None
                 ) -> float:
    """A finite number from a meta.yaml mapping (> 0 with ``positive``); the error names the file and field."""
    if key not in d and default is not None:
        return float(default)
    try:
        v = float(d[key])
    except (TypeError, ValueError, KeyError):
        raise ClothStageError(f"{where}: field '{key}' = {d.get(key)!r} is not a number ({unit})") from None
    if not np.isfinite(v) or (positive and v <= 0):
        raise ClothStageError(f"{where}: field '{key}' = {v} must be {'> 0' if positive else 'finite'} ({unit})")
    return v


def load_trial(folder: str | Path, cfg: DictConfig, name: str | None = None, with_frames: bool = False
               ) -> Trial | tuple[Trial, np.ndarray]:
    """Read a cloth footage folder and extract its features (silhouettes from the footage itself).

    Args:
        folder: footage folder written by ``reality_cloth`` (frames, times, calibration, meta).
        cfg: the stage config (``cloth.features``, ``cloth.model.frame_stride/max_frames``).
        name: trial label (default: the folder name).
        with_frames: also return the trial's (T, H, W, 3) uint8 footage frames (for logging).

    Returns:
        The (strided) trial with the *calibrated* camera and projector of the folder
        (and its frames with ``with_frames``).
    """
    kind = object_kind(folder)
    fp = read_footage(folder, required_meta=REQUIRED_META + REQUIRED_META_KIND[kind])
    meta = fp.meta
    if meta["scene"] != "cloth":
        raise ClothStageError(f"{folder}/meta.yaml: scene = {meta['scene']!r}, expected 'cloth'")
    if "projector" not in fp.cameras:
        raise ClothStageError(f"{folder}/calibration.yaml: field 'projector' is missing (the cloth scene is lit by stripes)")
    bg = np.asarray(meta["background_frames"], int)
    cloth_idx = np.setdiff1d(np.arange(fp.frames.shape[0]), bg)
    body = None
    if kind == "skirt":
        try:
            body = SkirtBody.from_meta(meta["body"], f"{folder}/meta.yaml")
        except RigError as e:
            raise ClothStageError(str(e)) from None
        if body.n_frames != cloth_idx.size:
            raise ClothStageError(f"{folder}/meta.yaml: body has {body.n_frames} frames, expected {cloth_idx.size}")
        cp = np.zeros((cloth_idx.size, 0, 3))
    else:
        try:
            cp = np.asarray(meta["corner_paths"], float)
        except (TypeError, ValueError):
            raise ClothStageError(f"{folder}/meta.yaml: field 'corner_paths' must be numbers (metres), "
                                  f"({cloth_idx.size}, 2, 3)") from None
        if cp.shape != (cloth_idx.size, 2, 3):
            raise ClothStageError(f"{folder}/meta.yaml: corner_paths has shape {cp.shape}, expected ({cloth_idx.size}, 2, 3)")
        if not np.all(np.isfinite(cp)):
            raise ClothStageError(f"{folder}/meta.yaml: field 'corner_paths' has non-finite values (metres expected)")
    where = f"{folder}/meta.yaml"
    density = _meta_number(meta, "areal_density", where, "kg/m^2", positive=True)
    size = (_meta_number(meta, "size_m", where, "m", positive=True) if kind == "swatch"
            else _meta_number(meta, "size_m", where, "m", default=0.0))
    pat = meta["projector_pattern"]
    if not isinstance(pat, dict) or "period_px" not in pat:
        raise ClothStageError(f"{where}: field 'projector_pattern' must be a mapping with 'period_px'")
    period = _meta_number(pat, "period_px", f"{where}: projector_pattern", "px", positive=True)
    if period <= 1:
        raise ClothStageError(f"{where}: projector_pattern field 'period_px' = {period} must be > 1 px (a stripe period)")
    proj = Projector(fp.cameras["projector"], period_px=period,
                     power=_meta_number(pat, "power", f"{where}: projector_pattern", "-", default=1.0),
                     ambient=_meta_number(pat, "ambient", f"{where}: projector_pattern", "-", default=0.1))
    fs = feature_settings(cfg)
    feats = extract_features(fp.frames, bg, fs)
    tr = Trial(name or Path(folder).name, feats, fp.times[cloth_idx], cp, fp.camera, proj, size, density, body)
    stride, most = int(cfg.cloth.model.frame_stride), int(cfg.cloth.model.max_frames)
    if not with_frames:
        return tr.strided(stride, most)
    idx = np.arange(0, cloth_idx.size, max(1, stride))
    if most > 0:
        idx = idx[:most]
    return tr.strided(stride, most), fp.frames[cloth_idx[idx]]


def object_kind(folder: str | Path) -> str:
    """``swatch`` or ``skirt``: the ``object.kind`` of a cloth footage folder's meta.yaml."""
    if not (Path(folder) / "meta.yaml").is_file():
        return "swatch"  # read_footage names what is missing
    meta = read_meta(Path(folder) / "meta.yaml", required=("scene",))
    obj = meta.get("object") or {}
    kind = obj.get("kind", "swatch") if isinstance(obj, dict) else None
    if kind not in REQUIRED_META_KIND:
        raise ClothStageError(f"{folder}/meta.yaml: object.kind = {kind!r}, expected one of {sorted(REQUIRED_META_KIND)}")
    return kind


def fixed_params(cfg: DictConfig) -> dict[str, float]:
    """``cloth.fit.fixed`` as floats."""
    return {k: float(v) for k, v in OmegaConf.to_container(cfg.cloth.fit.fixed, resolve=True).items()}


def make_objective(trials: list[Trial], cfg: DictConfig) -> ClothObjective:
    """The objective of ``cloth.fit``/``cloth.model`` over ``trials`` (errors summed)."""
    full = OmegaConf.to_container(cfg.cloth.fit.space, resolve=True)
    est = list(cfg.cloth.fit.estimate) or list(full)
    bad = [n for n in est if n not in full]
    if bad:
        raise ClothStageError(f"cloth.fit.estimate {bad} are not in cloth.fit.space {list(full)}")
    space = space_from_config({n: full[n] for n in est})
    m = cfg.cloth.model
    return ClothObjective(trials, space, fixed=fixed_params(cfg),
                          model=ModelSettings(resolution=int(m.resolution), settle_s=float(m.settle_s),
                                              settle_bath=float(m.settle_bath), integrator=str(m.integrator),
                                              multirate=str(m.multirate), damping=str(m.damping),
                                              chaos_members=int(m.chaos_members), chaos_sigma=float(m.chaos_sigma),
                                              skirt_rings=int(cfg.cloth.skirt.model_rings),
                                              skirt_around=int(cfg.cloth.skirt.model_around),
                                              skirt_rest_bend=str(cfg.cloth.skirt.model_rest_bend),
                                              skirt_fold_members=int(cfg.cloth.skirt.model_fold_members),
                                              skirt_fold_amplitude=float(cfg.cloth.skirt.model_fold_amplitude),
                                              skirt_fold_seed=int(cfg.cloth.skirt.model_fold_seed)),
                          features=feature_settings(cfg), alpha=float(cfg.cloth.fit.alpha))


def params_dict(p: ClothParams) -> dict[str, float]:
    """The nine estimated parameters (and the known density) of ``p`` as plain floats."""
    out = {n: float(getattr(p, n)) for n in ESTIMATED_NAMES}
    out["density"] = float(p.density)
    return out


def params_from_dict(d: dict[str, Any], where: str) -> ClothParams:
    """:class:`ClothParams` from a ``params`` mapping of a fit/params file (names the file)."""
    try:
        return ClothParams(**{k: float(v) for k, v in d.items()})
    except (TypeError, ValueError) as e:
        raise ClothStageError(f"{where}: params are not valid ({e})") from None


def read_selected(paths: list[str]) -> list[dict[str, Any]]:
    """The ``params.yaml`` documents of ``select_cloth`` (names a missing file)."""
    docs = []
    for p in paths:
        doc = load_yaml(p, ClothStageError, "params.yaml", mapping=True)
        if "params" not in doc:
            raise ClothStageError(f"{p}: field 'params' is missing")
        docs.append(doc)
    return docs


def fabric_sets(node: DictConfig, where: str) -> tuple[list[str], list[str], list[str], list[ClothParams]]:
    """``(fabrics, params files, footage folders, parameter sets)`` of a matrix stage's inputs
    (``fabrics``, ``params``, ``footage`` lists of one length under ``where``)."""
    fabrics, pfiles, footage = list(node.fabrics), list(node.params), list(node.footage)
    if not fabrics or not (len(fabrics) == len(pfiles) == len(footage)):
        raise ClothStageError(f"{where}: fabrics ({len(fabrics)}), params ({len(pfiles)}) and footage "
                              f"({len(footage)}) must be non-empty lists of one length")
    sets = [params_from_dict(d["params"], p) for d, p in zip(read_selected(pfiles), pfiles)]
    return fabrics, pfiles, footage, sets


@dataclass
class CellScore:
    """A parameter set's score on one objective as :class:`LoggedScores` logged it (the fields of
    :class:`~vidsim.clothfit.objective.EvalResult` a score needs; no images)."""

    score: float
    ok: bool
    failure: str | None
    members: list[list[float]]


def params_key(p: ClothParams) -> np.ndarray:
    """Every field of ``p`` (gravity's three components in place) as one float vector: the exact
    key of a complete parameter set in an evaluation log."""
    return np.array([float(x) for f in dc_fields(p) for x in np.ravel(getattr(p, f.name))])


class LoggedScores:
    """Complete parameter sets scored on one objective (:meth:`ClothObjective.evaluate_params`),
    each simulation's score, success and per-start errors logged as it finishes.

    The checkpoint of the stages that score given parameter sets (``score_cloth_twin``,
    ``skirt_cloth``): an :class:`~vidsim.optim.cache.EvalCache` keyed by the set's exact values
    (:func:`params_key`) whose context is the objective's fingerprint (footage, model, features,
    metric, simulator and source digest), as the fits' logs are. A killed stage, run again,
    replays every set already scored without simulating, so its output is the uninterrupted run's
    bit for bit; a log written for another objective is moved aside, not replayed.

    Args:
        obj: the objective.
        path: the JSONL log (None: in memory only, nothing kept across runs).
    """

    def __init__(self, obj: ClothObjective, path: str | Path | None = None) -> None:
        from vidsim.optim.cache import EvalCache

        self.obj = obj
        self.space = obj.space
        self.cache = EvalCache(lambda x: None, path, context=obj.fingerprint() if path is not None else None)

    def evaluate_params(self, params: ClothParams, keep: bool = False):
        """:meth:`ClothObjective.evaluate_params` through the log: a :class:`CellScore`, or with
        ``keep`` the simulation's full :class:`~vidsim.clothfit.objective.EvalResult` (images and
        positions are not logged, so a kept set is simulated again even when it was logged: the
        same score, deterministic)."""
        from vidsim.optim.cache import point_key

        x = params_key(params)
        key = point_key(x)
        if keep and key in self.cache.store:
            return self.obj.evaluate_params(params, keep=True)
        full = []

        def run(_x: np.ndarray) -> tuple[float, dict]:
            r = self.obj.evaluate_params(params, keep=keep)
            full.append(r)
            return float(r.score), {"ok": bool(r.ok), "failure": r.failure,
                                    "members": [[float(e) for e in m] for m in r.members]}

        f, info = self.cache.evaluate(x, run)
        if keep and full:
            return full[0]
        return CellScore(f, bool(info.get("ok", False)), info.get("failure"), info.get("members", []))

    def close(self) -> None:
        self.cache.close()


def fabric_matrix(footage: list[str], param_sets: list[ClothParams], cfg: DictConfig, names: list[str],
                  what: str, keep_diagonal: bool = False, members: list | None = None,
                  checkpoint: str | Path | None = None) -> tuple[np.ndarray, list]:
    """Error of every parameter set (rows) on every footage folder (columns), seed Figure 8.

    Each set is simulated as it is (its own density: "fleece simulated against satin footage").

    Args:
        members: if given, a list that receives per cell ``members[i][j]`` the errors of the
            objective's ensemble starts (a skirt's fold-seeded starts; one entry for a swatch).
        checkpoint: a folder for the cells' logs (:class:`LoggedScores`, one per footage column,
            ``column<j>.jsonl``): a killed run resumes at the first cell not logged (the kept
            diagonal cells, whose images are returned, are simulated again). None: no log.

    Returns:
        ``(E, diagonal)``: the (sets, footage) matrix and, with ``keep_diagonal``, per footage
        ``(trial, frames, EvalResult with images)`` of its own fabric's set (else an empty list).
    """
    E = np.zeros((len(param_sets), len(footage)))
    if members is not None:
        members[:] = [[[] for _ in footage] for _ in param_sets]
    diag = []
    prog = Progress(E.size, f"{what} matrix", enabled=cfg.log.progress)
    for j, f in enumerate(footage):
        if keep_diagonal:
            tr, frames = load_trial(f, cfg, with_frames=True)
        else:
            tr, frames = load_trial(f, cfg), None
        obj = LoggedScores(make_objective([tr], cfg), None if checkpoint is None else Path(checkpoint) / f"column{j}.jsonl")
        try:
            for i, p in enumerate(param_sets):
                r = obj.evaluate_params(p, keep=keep_diagonal and i == j)
                E[i, j] = r.score
                if members is not None:
                    members[i][j] = list(r.members[0]) if r.ok and r.members else []
                if keep_diagonal and i == j:
                    diag.append((tr, frames, r))
                prog.update(note=f"{names[i]} parameters on {names[j]} footage")
        finally:
            obj.close()
    return E, diag


def matrix_figure(E: np.ndarray, names: list[str], xlabel: str, path: str | Path, note: str = "") -> int:
    """Heatmap of an error matrix (each column over its minimum); returns the diagonal's column wins."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from vidsim.report.figures import save_figure

    n = len(names)
    wins = sum(diagonal_wins(E))
    fig, ax = plt.subplots(figsize=(1.3 * n + 2, 1.1 * n + 1.5))
    R = E / E.min(axis=0, keepdims=True)
    im = ax.imshow(R, cmap="viridis_r")
    for i in range(n):
        for j in range(n):
            ax.text(j, i, f"{E[i, j]:.3g}", ha="center", va="center", fontsize=8,
                    color="w" if R[i, j] > 0.5 * (R.max() + 1) else "k", weight="bold" if i == j else None)
    ax.set_xticks(range(n), names)
    ax.set_yticks(range(n), names)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("selected parameters of")
    ax.set_title(f"error / column minimum; diagonal wins {wins}/{n}" + (f"\n{note}" if note else ""), fontsize=9)
    fig.colorbar(im, ax=ax, shrink=0.8)
    save_figure(fig, path)
    return wins


def matrix_csv(E: np.ndarray, names: list[str]) -> str:
    """CSV text of an error matrix (rows: parameters, columns: footage)."""
    return "params\\footage," + ",".join(names) + "\n" + "".join(
        f"{names[i]}," + ",".join(f"{E[i, j]:.5g}" for j in range(E.shape[1])) + "\n" for i in range(E.shape[0]))


def irradiance_to_uint8(img: np.ndarray) -> np.ndarray:
    """A simulated (H, W) irradiance image scaled to 0-255 by its own maximum (for viewing)."""
    im = np.nan_to_num(np.asarray(img, float), nan=0.0)
    return np.clip(np.rint(255 * im / max(float(im.max()), 1e-9)), 0, 255).astype(np.uint8)


def diagonal_wins(E: np.ndarray) -> list[int]:
    """Per column 1 when the diagonal (the footage's own parameters) has the least error, else 0. A
    column whose own cell failed to simulate (``FAILED_SCORE``) is lost: ``argmin`` of an all-failed
    column would otherwise hand the win to row 0."""
    from vidsim.optim import FAILED_SCORE

    n = min(E.shape)
    return [int(E[j, j] < FAILED_SCORE and int(np.argmin(E[:, j])) == j) for j in range(n)]


def chaos_copies(node, where: str) -> tuple[int, float]:
    """``(chaos_draws, chaos_sigma)`` of a stage's config ``node`` (``where``: its key, e.g.
    ``cloth.validate``), checked: 0 copies or at least 2 (a paired test needs two), and a log-scale
    spread in (0, 1] as the objective's ``cloth.model.chaos_sigma``."""
    draws, sigma = node.chaos_draws, node.chaos_sigma
    if isinstance(draws, bool) or int(draws) != draws or draws < 0 or draws == 1:
        raise ClothStageError(f"{where}.chaos_draws = {draws}: expected 0 (no copies) or a whole number >= 2 "
                              "(a paired test needs two copies)")
    if not (np.isfinite(sigma) and 0 < sigma <= 1):
        raise ClothStageError(f"{where}.chaos_sigma = {sigma}: expected a log-scale spread in (0, 1] "
                              "(1e-4 moves the parameters by 0.01 %)")
    return int(draws), float(sigma)


def paired_margins(E: np.ndarray, members: list, z: float | None = None) -> dict:
    """How firmly each column's verdict (does the diagonal win?) is decided by an ensemble of starts.

    The starts are the same for every row (a skirt's fold-seeded starts depend on the skirt model and
    seed, not on the parameters; a swatch's moved copies are the objective's fixed draws), so the
    differences ``d_k = e_diag,k - e_other,k`` are paired. A win is *decided* when the diagonal is
    significantly better than *every* other row (each row's mean ``d`` beyond ``z`` standard errors
    below zero: an intersection of one-sided tests, so no correction for their number); a loss when
    *some* other row is significantly better than the diagonal (mean ``d`` beyond the cut above zero,
    the cut Bonferroni-corrected for the number of rows tested, since any one of them would do). With
    fewer than two starts the column is undecided. A row that failed to simulate (``FAILED_SCORE``)
    cannot match the footage: it is left out of the tests (beaten); a column whose own set failed is
    lost. ``z``: the cut-off of both tests; None (default) Student's t with n - 1 degrees of freedom
    at 2.5 % one-sided (2.36 at 8 starts; a fixed 2 gave a 9 % false call rate there), divided by
    the number of rows for a loss. Before 5 Dec 2026 a win was tested against the runner-up alone, and
    until 6 Dec 2026 (session 44) a loss against the row of least mean error alone, so a row that beat
    the diagonal at every start could leave the column undecided, and picking the rival after the
    fact on the same starts called 6 % of equal columns lost (reviews).

    Returns:
        ``{column index: {"verdict": "won" | "lost" | "undecided", "decided": bool, "rival": the row a
        loss is decided against, else the best other row (least error), "margin": mean d against it
        (negative: the diagonal is better), "se": its standard error, "members": n, "cut": the win's
        cut-off, "cut_lost": the loss's, "failed": rows that failed to simulate (the own row
        included, when it did)}}``.
    """
    from scipy.stats import t as student_t

    from vidsim.optim import FAILED_SCORE

    out = {}
    n_rows = E.shape[0]
    for j in range(E.shape[1]):
        others = [i for i in range(n_rows) if i != j]
        if not others or j >= n_rows:
            continue
        failed = [i for i in range(n_rows) if not (np.isfinite(E[i, j]) and E[i, j] < FAILED_SCORE)]
        alive = [i for i in others if i not in failed]
        rival = min(alive, key=lambda i: E[i, j]) if alive else others[0]
        if j in failed:  # its own set could not be simulated on its own footage: lost
            out[j] = {"verdict": "lost", "decided": True, "rival": int(rival), "margin": float("nan"),
                      "se": float("nan"), "members": 0, "cut": float("nan"), "cut_lost": float("nan"),
                      "failed": failed}
            continue
        a = np.asarray(members[j][j], float)
        rows = {i: np.asarray(members[i][j], float) for i in alive}
        n = int(min([a.size] + [b.size for b in rows.values()]))
        ok = n >= 2 and all(b.size == a.size for b in rows.values()) and np.all(np.isfinite(a)) and all(
            np.all(np.isfinite(b)) for b in rows.values())
        k = max(1, len(rows))
        if z is not None:
            cut = cut_lost = float(z)
        elif n >= 2:
            cut = float(student_t.ppf(0.975, n - 1))
            cut_lost = float(student_t.ppf(1 - 0.025 / k, n - 1))
        else:
            cut = cut_lost = float("nan")
        verdict = "undecided"
        if ok and not rows:  # every other set failed: the own set is the only one that matches
            margin, se, verdict = float("nan"), float("nan"), "won"
        elif ok:
            stats = {}
            for i, b in rows.items():
                d = a - b
                stats[i] = (float(d.mean()), float(d.std(ddof=1) / np.sqrt(n)))
            beaten_by = [i for i, (m, e) in stats.items() if m - cut_lost * e > 0]
            if beaten_by:
                rival = max(beaten_by, key=lambda i: stats[i][0])
                verdict = "lost"
            elif all(m + cut * e < 0 for m, e in stats.values()):
                verdict = "won"
            margin, se = stats[rival]
        else:
            margin = float(E[j, j] - E[rival, j]) if alive else float("nan")
            se = float("nan")
        out[j] = {"verdict": verdict, "decided": verdict != "undecided", "rival": int(rival), "margin": margin,
                  "se": se, "members": n, "cut": cut, "cut_lost": cut_lost, "failed": failed}
    return out
