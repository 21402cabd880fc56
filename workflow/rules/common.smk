# Helpers shared by all rules (input functions live only here).
import hashlib
import sys
from pathlib import Path

RESULTS = config.get("results", "results")
SHARED = Path(config.get("shared_data", "../shared/data"))
HYDRA_EXTRA = config.get("hydra_overrides", "")


def stage_overrides(*stages):
    """Hydra overrides for one rule: the global ones, then `overrides: {<stage>: "..."}` from the
    config for each of ``stages`` in order (a rule that shares another stage's settings, e.g.
    `fit_cloth_cmaes`, passes that stage first and its own name last, so its own entry wins).

    They are a rule parameter, so changing a stage's overrides reruns that stage and what
    depends on it (rerun trigger `params`), and nothing else.
    """
    ov = config.get("overrides", {}) or {}
    own = " ".join(e for e in (ov.get(s, "") or "" for s in stages) if e)
    return f"paths.results={RESULTS} {HYDRA_EXTRA} {own}".strip()


STAGE_BASE = f"paths.results={RESULTS} {HYDRA_EXTRA}".strip()

# The Hydra configs under conf/ shape every stage's results but are read by the stages at run
# time, not declared as inputs: each rule carries a digest of the conf files its family composes
# as a parameter (`conf=CONF_<FAMILY>`), so editing one (a gap case, a cloth default) reruns that
# family's jobs through the params trigger (file contents, so a fresh clone's file times trigger
# nothing). `conf/log` is left out (it switches recordings and progress, not results).
CONF_DIR = Path(workflow.basedir) / "conf"


def conf_digest(*groups):
    """sha256 (16 hex digits) of conf/config.yaml and every YAML file of the named groups."""
    h = hashlib.sha256()
    files = [CONF_DIR / "config.yaml"] + sorted(f for g in groups for f in (CONF_DIR / g).glob("*.yaml"))
    for f in files:
        h.update(f.relative_to(CONF_DIR).as_posix().encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


_IMAGING = ("camera", "projector", "reality", "effects", "render", "calibrate")
CONF_CALIBRATION = conf_digest("calibrate", "camera", "projector")
CONF_DEMO = conf_digest(*_IMAGING)
CONF_RIGID = conf_digest("rigid", *_IMAGING)
CONF_CLOTH = conf_digest("cloth", *_IMAGING)
CONF_FLUID = conf_digest("fluid")
CONF_POSTERIOR = conf_digest("posterior", "rigid", "cloth", *_IMAGING)
CONF_GAP = conf_digest("gap", "rigid", "cloth", *_IMAGING)


def stage_own(*stages):
    """Only the stages' own `overrides:` entries (see :func:`stage_overrides`), for rules that put a
    family's settings between the global ones (`STAGE_BASE`) and the stage's own, so that the
    stage's entry wins over the family string (Hydra keeps the last value of a key)."""
    ov = config.get("overrides", {}) or {}
    return " ".join(e for e in (ov.get(s, "") or "" for s in stages) if e)


def stage_enabled(name):
    return bool(config.get("stages", {}).get(name, False))


_SHARED_MISSING = set()


def shared_available(sub):
    """True when the real recording ``<shared_data>/<sub>`` exists; otherwise the stages that need it
    are left out of the targets, with one warning naming the missing folder (the rest still runs)."""
    if (SHARED / sub).exists():
        return True
    if sub not in _SHARED_MISSING:
        _SHARED_MISSING.add(sub)
        print(f"vidsim: real data {SHARED / sub} is absent: its stages are skipped (set shared_data=...)",
              file=sys.stderr)
    return False


# Each workflow/rules/<family>.smk registers its final outputs here at parse time, under the
# switch of `stages:` in the Snakemake config: TARGETS[<family>] = [paths...].
TARGETS = {}


def get_final_outputs(wildcards):
    """The final targets: what the stage families switched on have registered."""
    return [p for paths in TARGETS.values() for p in paths]


def get_out_dir(wildcards, output):
    """The folder of a rule's first output: where its Hydra stage writes (paths.out)."""
    return str(Path(output[0]).parent)


# Each stage names env.yml as its conda environment, for the record only (the README's set-up uses a
# venv), and Snakemake's `--sdm conda` mode is not supported (env.yml says so).
CONDA_ENV = "../../env.yml"


def paramspace_overrides(space):
    """A params function: the Hydra overrides (``key=value ...``) of a Paramspace point.

    Table columns name Hydra keys with "__" for "." (column names become wildcard names, which
    must be identifiers): ``calibrate__n_views`` -> ``calibrate.n_views``.
    """

    def overrides(wildcards):
        return " ".join(f"{k.replace('__', '.')}={v}" for k, v in space.instance(wildcards).items())

    return overrides


def sweep_point_dirs(wildcards, input):
    """The folders of a sweep's points (the parents of the collected summaries)."""
    return " ".join(str(Path(p).parent) for p in input.points)
