# Helpers of the rigid rules (workflow/rules/rigid.smk): the case table and its input/params functions.
import shlex

RIGID = config.get("rigid", {}) or {}
RIGID_CASES = RIGID.get("cases", {}) or {}


def rigid_case_overrides(wildcards):
    """Hydra overrides of one case: its seed, then its own overrides (each token shell-quoted)."""
    case = RIGID_CASES[wildcards.case]
    own = shlex.split(str(case.get("overrides", "") or ""))
    return " ".join(shlex.quote(t) for t in [f"rigid.seed={int(case['seed'])}", *own])


def rigid_footage_dir(wildcards):
    """The footage folder of a case."""
    return f"{RESULTS}/footage/rigid_{wildcards.case}"
