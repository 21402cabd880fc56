# Input/params functions of the cloth rules (workflow/rules/cloth.smk includes this file).
from pathlib import Path


def cloth_folders(paths):
    """Hydra list of the folders holding the given files: [a,b,...]."""
    return "[" + ",".join(str(Path(p).parent) for p in paths) + "]"


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
    """Hydra overrides of one fabric's reality (the `cloth.per_fabric_reality` map), e.g. effects."""
    return (CLOTH.get("per_fabric_reality", {}) or {}).get(wildcards.fabric, "") or ""
