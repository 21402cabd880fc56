"""The one way a stage becomes a command: a Hydra app with validation and one-line errors.

Each ``vidsim/cli/<stage>.py`` defines ``run(cfg)`` and ends with ``main = stage_app("<stage>",
run)``; ``python -m vidsim.cli.<stage> key=value ...`` then composes ``conf/config.yaml`` with
the overrides (``-m`` sweeps), validates it, and runs the stage. Bad input (any
:class:`~vidsim.errors.VidsimError`, a missing file) ends the process with exit code 2 and one
line on stderr that names the file, field or value -- never a bare traceback.
"""

from __future__ import annotations

import logging
import os
import sys
from typing import Callable

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import hydra  # noqa: E402
from omegaconf import DictConfig  # noqa: E402

from vidsim.config import CONF_DIR, validate  # noqa: E402
from vidsim.errors import VidsimError  # noqa: E402

log = logging.getLogger("vidsim")


def check_paths(cfg: DictConfig) -> None:
    """Every stage writes inside ``paths.results``: an output path that escapes it is an error."""
    from pathlib import Path

    from vidsim.errors import ConfigError

    results = Path(cfg.paths.results).resolve()
    out = Path(cfg.paths.out).resolve()
    if out == results:
        # stages replace their output folder as a whole (a staging folder moved over it): the
        # results folder itself would lose every other stage's outputs
        raise ConfigError(f"paths.out = {cfg.paths.out!r} is the results folder itself (paths.results); give a "
                          "folder inside it, e.g. paths.out=${paths.results}/mine")
    if results not in out.parents:
        raise ConfigError(f"paths.out = {cfg.paths.out!r} escapes the results folder {str(results)!r} (paths.results)")
    # a file where the output folder (or one of its parents) must go: refused now, not after the work
    for p in (out, *out.parents):
        if p.exists() and not p.is_dir():
            raise ConfigError(f"paths.out = {cfg.paths.out!r}: {str(p)!r} is an existing file, not a folder")


_FAILED_POINTS: list[str] = []  # sweep points of this process that failed (multirun)
_SWEEP_DIRS: set[str] = set()  # the sweep folder(s) of this process's points (multirun)


def _in_multirun() -> bool:
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    return HydraConfig.initialized() and HydraConfig.get().mode == RunMode.MULTIRUN


def _fail(name: str, e: Exception) -> None:
    """One line on stderr; exit 2 -- except inside a sweep, where the point is marked failed (its
    line, and a row of ``failed.csv`` in the sweep folder) and the sweep goes on to the next point;
    the sweep then ends with exit code 2."""
    print(f"vidsim {name}: error: {e}", file=sys.stderr)
    if not _in_multirun():
        sys.exit(2)
    from pathlib import Path

    from hydra.core.hydra_config import HydraConfig

    from vidsim.io.atomic import write_text

    hc = HydraConfig.get()
    point = hc.job.override_dirname or str(hc.job.num)
    first = not _FAILED_POINTS  # this process's first failed point: an older sweep's file is replaced
    _FAILED_POINTS.append(point)
    msg = str(e).replace('"', "'")
    row = f'"{point}","{msg}"\n'
    csv = Path(hc.sweep.dir) / "failed.csv"
    old = csv.read_text() if csv.exists() and not first else "point,error\n"
    write_text(csv, old + row)
    job_dir = Path(hc.runtime.output_dir)
    if job_dir.is_dir() and not any(job_dir.iterdir()):
        job_dir.rmdir()  # nothing of the failed point is left behind


def stage_app(name: str, run: Callable[[DictConfig], None]) -> Callable[[], None]:
    """Wrap ``run(cfg)`` as a Hydra main function for stage ``name``."""

    @hydra.main(version_base="1.3", config_path=CONF_DIR, config_name="config")
    def _main(cfg: DictConfig) -> None:
        # Reproducible numbers: OpenCV's parallel loops sum in a thread-dependent order (seen as
        # 1e-11 differences between identical calibrations); stages run its code single-threaded
        # (VIDSIM_OPENCV_THREADS overrides, at the price of bit-exact reruns).
        import cv2

        cv2.setNumThreads(int(os.environ.get("VIDSIM_OPENCV_THREADS", "1")))
        from omegaconf.errors import MissingMandatoryValue

        if _in_multirun():
            from hydra.core.hydra_config import HydraConfig

            _SWEEP_DIRS.add(str(HydraConfig.get().sweep.dir))

        try:
            validate(cfg)
            check_paths(cfg)
            level = str(cfg.log.level).upper()
            if level not in ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"):
                from vidsim.errors import ConfigError

                raise ConfigError(f"log.level = {cfg.log.level!r}: expected DEBUG, INFO, WARNING, ERROR or CRITICAL")
            log.setLevel(level)  # the project's logger ("vidsim" and its children)
            run(cfg)
        except (VidsimError, FileNotFoundError) as e:
            _fail(name, e)
        except MissingMandatoryValue as e:  # e.g. no paths.out: name the key, no traceback
            _fail(name, f"{e.full_key or 'a setting'} is required and was not given (missing value '???')")
        except ValueError as e:
            # the project's own validation errors (CameraError, CalibrationError, ...) are
            # ValueError subclasses defined in vidsim modules: one line, no traceback (in a sweep
            # the point is marked failed and the sweep goes on, as for any VidsimError)
            if not type(e).__module__.startswith("vidsim"):
                raise
            _fail(name, e)

    def _entry() -> None:
        args = sys.argv[1:]
        if any(a in ("--help", "-h") for a in args):
            try:
                _stage_help(name, run)
                sys.stdout.flush()
            except BrokenPipeError:  # `--help | head`: the reader left, which is not an error
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return
        if not any(a.startswith("hydra.job.name=") for a in args):
            # names the sweep folder (${paths.results}/sweeps/<stage>) and Hydra's logs
            sys.argv.append(f"hydra.job.name={name}")
        if any(a in ("-m", "--multirun") for a in args) and not any(a.startswith("paths.out=") for a in args):
            # a sweep: each point writes its outputs to its own folder, named by its overrides
            sys.argv.append(f"paths.out=${{paths.results}}/sweeps/{name}/${{hydra:job.override_dirname}}")
        _precheck_overrides(name, sys.argv[1:])
        _main()
        if not _FAILED_POINTS:
            from pathlib import Path

            for d in _SWEEP_DIRS:  # failed.csv belongs to the last sweep: a clean one leaves none
                (Path(d) / "failed.csv").unlink(missing_ok=True)
        if _FAILED_POINTS:
            print(f"vidsim {name}: {len(_FAILED_POINTS)} sweep point(s) failed (the others ran): "
                  f"{', '.join(_FAILED_POINTS)}", file=sys.stderr)
            sys.exit(2)

    _entry.__name__ = name
    return _entry


def _stage_help(name: str, run: Callable) -> None:
    """``--help``: what the stage does (its module's docstring) and how to see its settings, instead of
    Hydra's generic text followed by an 800-line dump of the whole config tree."""
    import inspect

    mod = sys.modules.get(getattr(run, "__module__", ""), None)
    doc = inspect.getdoc(mod) if mod is not None else None
    print(doc or f"Stage {name}.")
    print(f"""
Usage: python -m vidsim.cli.{name} paths.out=<folder inside paths.results> [key=value ...]
       python -m vidsim.cli.{name} -m key=a,b ...   (a sweep: one folder per point under results/sweeps/{name}/)

Every stage needs paths.out (its output folder, inside paths.results = results/ by default); stages that
read footage or earlier results name those paths above. Settings are Hydra config keys (conf/):
  python -m vidsim.cli.{name} --cfg job [key=value ...]   print the composed settings this run would use
  python -m vidsim.cli.{name} --hydra-help                Hydra's own options
Bad input stops with exit code 2 and one line naming the file, field or value.""")


def _precheck_overrides(name: str, args: list[str]) -> None:
    """Compose the config once before Hydra does, to turn a bad override (unknown key, wrong
    type, a ``+`` key a schema node does not have) into one line instead of Hydra's multi-line
    report or a silently ignored key. In a sweep the same checks run on the overrides that are not
    sweeps (Hydra flags, starting with '-', and swept values, with a ',' or a sweep function,
    are left to Hydra, except a plain comma list ``k=a,b``, of which every value is checked with the
    other overrides before any point runs: an unknown swept key, a wrong type or a ``+`` key a
    schema node lacks stops the sweep with one line, instead of Hydra's multi-line report after
    the points before it ran, or a silently ignored key)."""
    # Hydra's flags, and the value of those that take one (--cfg job, -p <package>, ...), are not overrides
    with_value = {"--cfg", "-c", "--package", "-p", "--config-path", "-cp", "--config-name", "-cn",
                  "--config-dir", "-cd", "--info", "-i", "--experimental-rerun"}
    kept, skip = [], False
    for a in args:
        if skip:
            skip = False
            if "=" not in a:
                continue
        if a in with_value:
            skip = True
            continue
        kept.append(a)
    args = kept
    variants = [args]
    if any(a.startswith("-") for a in args):
        fixed = [a for a in args if not a.startswith("-") and not _is_sweep(a)]
        variants = [fixed]
        for a in args:
            if a.startswith("-") or not _is_sweep(a):
                continue
            values = _plain_sweep_values(a)
            if values is None:
                continue  # range(), choice(), ...: left to Hydra
            key = a.split("=", 1)[0]
            variants += [fixed + [f"{key}={v}"] for v in values]
    from hydra import compose, initialize_config_dir
    from hydra.errors import HydraException

    for overrides in variants:
        try:
            with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
                cfg = compose("config", overrides=overrides)
        except HydraException as e:
            lines = str(e).strip().splitlines()
            first = lines[0]
            avail = next((i for i, ln in enumerate(lines) if ln.strip().startswith("Available options")), None)
            if avail is not None:  # an unknown group option: keep Hydra's list of the group's options, on the line
                opts = []
                for ln in lines[avail + 1:]:  # the indented option names; the config search path follows
                    if not ln.startswith((" ", "\t")) or not ln.strip():
                        break
                    opts.append(ln.strip())
                first += f" ({lines[avail].strip().rstrip(':')}: {', '.join(opts)})"
            cause = e.__cause__
            why = str(cause).strip().splitlines()[0] if cause is not None and str(cause).strip() else ""
            print(f"vidsim {name}: error: {first}{' ' + why if why and why not in first else ''}", file=sys.stderr)
            sys.exit(2)
        bad = unknown_added_key(cfg, overrides)
        if bad:
            print(f"vidsim {name}: error: {bad}", file=sys.stderr)
            sys.exit(2)


def _plain_sweep_values(arg: str) -> list[str] | None:
    """The values of a plain comma-list sweep ``k=a,b,[1,2]`` (commas inside brackets or quotes kept),
    or None for a sweep function (``range(...)``, ``choice(...)``, ...)."""
    value = arg.split("=", 1)[1]
    if value.split("(", 1)[0] in ("range", "choice", "interval", "glob", "tag", "sort", "shuffle"):
        return None
    out, cur, depth, quote = [], "", 0, ""
    for ch in value:
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "[{(":
            depth += 1
        elif ch in "]})":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append(cur)
            cur = ""
            continue
        cur += ch
    out.append(cur)
    return out


def _is_sweep(arg: str) -> bool:
    """A Hydra sweep override (``k=a,b``, ``k=range(...)``, ``k=choice(...)``, ...)."""
    if "=" not in arg:
        return False
    value = arg.split("=", 1)[1]
    depth = 0
    for ch in value:  # a ',' outside brackets and quotes is a sweep list; inside [..] a list value
        if ch in "[{(":
            depth += 1
        elif ch in "]})":
            depth -= 1
        elif ch == "," and depth == 0:
            return True
    return value.split("(", 1)[0] in ("range", "choice", "interval", "glob", "tag", "sort", "shuffle")


def unknown_added_key(cfg: DictConfig, args: list[str]) -> str | None:
    """A key added with ``+``/``++`` under a schema node (a dataclass: ``rigid.fit``, ...) that has
    no such field: Hydra adds it and the stage would silently ignore it (a typo such as
    ``+rigid.fit.max_iter=5``). Keys under free-form mappings (``cloth.fit.fixed``,
    ``gap.cloth.diagnose``, ...) are what ``+`` is for and pass. Returns the message, or None."""
    import dataclasses

    from omegaconf import OmegaConf

    for a in args:
        if not a.startswith("+") or "=" not in a:
            continue
        key = a.lstrip("+").split("=", 1)[0]
        if "/" in key or "." not in key or key.startswith("hydra."):
            continue  # a config group (+group=option) or Hydra's own settings
        parts = key.split(".")
        node = cfg
        for i, part in enumerate(parts):
            typ = OmegaConf.get_type(node) if OmegaConf.is_config(node) else None
            if typ is not None and dataclasses.is_dataclass(typ):
                fields = [f.name for f in dataclasses.fields(typ)]
                if part not in fields:
                    where = ".".join(parts[:i]) or "the root"
                    return (f"config key {'.'.join(parts[: i + 1])} (added with '+') is unknown: {where} has "
                            f"{', '.join(fields)}")
            if not OmegaConf.is_dict(node) or part not in node:
                break
            node = node[part]
    return None
