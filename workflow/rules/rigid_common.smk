# Helpers of the rigid rules (workflow/rules/rigid.smk): the case table and its input/params functions.
import shlex

RIGID = config.get("rigid", {}) or {}
RIGID_CASES = RIGID.get("cases", {}) or {}
# a case is a synthetic throw ({seed: ...}: reality films it, score_rigid scores it against its truth)
# or your own recording ({footage: <folder>}: segmented, fitted and diagnosed, never scored)
for _name, _case in RIGID_CASES.items():
    if not isinstance(_case, dict) or ("seed" in _case) == ("footage" in _case):
        raise ValueError(f"rigid.cases.{_name}: give either seed (a synthetic throw) or footage (a folder of your "
                         f"own recording), got {_case!r}")
RIGID_OWN = [c for c, v in RIGID_CASES.items() if "footage" in v]
RIGID_SYNTHETIC = [c for c in RIGID_CASES if c not in RIGID_OWN]


def rigid_case_overrides(wildcards):
    """Hydra overrides of one case: its seed (synthetic cases), then its own overrides (each token
    shell-quoted)."""
    case = RIGID_CASES[wildcards.case]
    own = shlex.split(str(case.get("overrides", "") or ""))
    seed = [f"rigid.seed={int(case['seed'])}"] if "seed" in case else []
    return " ".join(shlex.quote(t) for t in [*seed, *own])


def rigid_footage_dir(wildcards):
    """The footage folder of a case: reality's, or the recording a case names with ``footage``."""
    own = RIGID_CASES.get(wildcards.case, {}).get("footage")
    return str(own) if own else f"{RESULTS}/footage/rigid_{wildcards.case}"


def rigid_meta(wildcards):
    """The case's meta.yaml (an input: for your own recording, a file that must exist)."""
    return f"{rigid_footage_dir(wildcards)}/meta.yaml"
