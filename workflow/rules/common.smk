# Helpers shared by all rules (input functions live only here).
from pathlib import Path

RESULTS = config.get("results", "results")
SHARED = Path(config.get("shared_data", "../shared/data"))
HYDRA_EXTRA = config.get("hydra_overrides", "")


def stage_overrides(stage):
    """Hydra overrides for one stage: the global ones, then `overrides: {<stage>: "..."}` from the config.

    They are a rule parameter, so changing a stage's overrides reruns that stage and what
    depends on it (rerun trigger `params`), and nothing else.
    """
    own = config.get("overrides", {}).get(stage, "") or ""
    return f"{HYDRA_EXTRA} {own}".strip()


def stage_enabled(name):
    return bool(config.get("stages", {}).get(name, False))


def get_final_outputs(wildcards):
    """Everything `rule all` asks for, by the stages switched on in the config."""
    out = []
    if stage_enabled("calibration_chessboard"):
        out += [f"{RESULTS}/calibration/chessboard/calibration.yaml"]
    if stage_enabled("demo"):
        for s in config["demo"]["scenes"]:
            out += [f"{RESULTS}/calibration/{s}/calibration.yaml", f"{RESULTS}/footage/{s}/meta.yaml",
                    f"{RESULTS}/footage/{s}/contact_sheet.png"]
    return out


def get_out_dir(wildcards, output):
    """The folder of a rule's first output: where its Hydra stage writes (paths.out)."""
    return str(Path(output[0]).parent)


CONDA_ENV = "../../env.yml"
