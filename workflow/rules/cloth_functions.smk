# Input/params functions of the cloth rules (workflow/rules/cloth.smk includes this file).
from pathlib import Path


def cloth_folders(paths):
    """Hydra list of the folders holding the given files: [a,b,...]."""
    folders = ",".join(str(Path(p).parent) for p in paths)
    return f"[{folders}]"


def cloth_select_inputs(wildcards, input):
    """cloth.select.* overrides: the fabric's fit.yaml files and footage folders, in trial order."""
    return f"cloth.select.fits=[{','.join(input.fits)}] cloth.select.footage={cloth_folders(input.metas)}"


def cloth_validate_inputs(wildcards, input):
    """cloth.validate.* overrides: fabrics, their params.yaml and held-out footage folders."""
    return (f"cloth.validate.fabrics=[{','.join(CLOTH_FABRICS)}] cloth.validate.params=[{','.join(input.params)}] "
            f"cloth.validate.footage={cloth_folders(input.metas)}")


def cloth_fabric_overrides(wildcards):
    """Hydra overrides of one fabric's fit/select jobs (the `cloth.per_fabric` map): only that
    fabric's fits, its selection and the validation rerun when it changes."""
    return (CLOTH.get("per_fabric", {}) or {}).get(wildcards.fabric, "") or ""


def cloth_fabric_reality_overrides(wildcards):
    """Hydra overrides of one fabric's reality (the `cloth.per_fabric_reality` map), e.g. effects;
    a twin (a name in `cloth.twins`) is filmed from the estimator's own simulator."""
    own = (CLOTH.get("per_fabric_reality", {}) or {}).get(wildcards.fabric, "") or ""
    return f"cloth.reality.kind=twin {own}".strip() if wildcards.fabric in CLOTH_TWINS else own


def cloth_skirt_inputs(wildcards, input):
    """cloth.skirt.* overrides: fabrics, their params.yaml and skirt footage folders."""
    return (f"cloth.skirt.fabrics=[{','.join(CLOTH_FABRICS)}] cloth.skirt.params=[{','.join(input.params)}] "
            f"cloth.skirt.footage={cloth_folders(input.metas)}")


def cloth_compare_inputs(wildcards, input):
    """cloth.compare.* overrides of compare_cloth (lists in the order of `cloth.compare`)."""
    lists = " ".join(f"cloth.compare.{k}=[{','.join(input[k])}]" for k in
                     ("anneal", "cmaes", "joint", "anneal_traces", "cmaes_traces", "joint_traces"))
    return f"cloth.compare.fabrics=[{','.join(CLOTH_COMPARE)}] cloth.compare.heldout={cloth_folders(input.heldout)} {lists}"


def cloth_meta_folders(wildcards, input):
    """Hydra list of the footage folders of a rule's `metas` input (the fitted trials)."""
    return cloth_folders(input.metas)


def table1_cloth_inputs(wildcards, input):
    """cloth.table1.* overrides: the fabrics of Table 1 with their selections and posterior summaries."""
    return (f"cloth.table1.fabrics=[{','.join(POSTERIOR_TABLE1_FABRICS)}] cloth.table1.params=[{','.join(input.params)}] "
            f"cloth.table1.summaries=[{','.join(input.summaries)}]")


def posterior_cloth_inputs(wildcards, input):
    """posterior.cloth.* overrides: the fabric's selection, its fits and footage folders (trial order)."""
    return (f"posterior.cloth.params={input.params} posterior.cloth.fits=[{','.join(input.fits)}] "
            f"posterior.cloth.footage={cloth_folders(input.metas)}")
