# cloth stages (wired in this file only; see workflow/rules/demo.smk for the pattern).
# calibrate_scene (scene=cloth, existing rule) -> reality_cloth per fabric x trial ->
# fit_cloth per fabric x fitted trial -> select_cloth per fabric -> validate_cloth.
# What runs: the `cloth:` section of workflow/config/{quick,full}.yaml.

CLOTH = config.get("cloth", {}) or {}
CLOTH_FABRICS = list(CLOTH.get("fabrics", ["linen", "satin"]))
CLOTH_FIT_TRIALS = list(CLOTH.get("fit_trials", ["exp1", "exp2"]))
CLOTH_HELD_OUT = CLOTH.get("held_out", "robot")
CLOTH_HYDRA = CLOTH.get("hydra", "") or ""  # fit_cloth, select_cloth, validate_cloth
CLOTH_REALITY_HYDRA = CLOTH.get("reality_hydra", "") or ""  # reality_cloth
CLOTH_CAL_HYDRA = CLOTH.get("calibration_hydra", "") or ""  # the cloth scene's calibration
CLOTH_CAL = f"{RESULTS}/calibration/cloth/calibration.yaml"

include: "cloth_functions.smk"


wildcard_constraints:
    fabric="[a-z]+",
    trial="[a-z0-9]+",


if stage_enabled("cloth"):
    TARGETS["cloth"] = [
        f"{RESULTS}/cloth/validate/matrix.png",
        f"{RESULTS}/cloth/validate/table1.csv",
    ] + [f"{RESULTS}/cloth/select/{f}/params.yaml" for f in CLOTH_FABRICS]


use rule calibrate_scene as calibrate_cloth_scene with:
    output:
        calib=CLOTH_CAL,
        summary=report(
            f"{RESULTS}/calibration/cloth/summary.csv",
            caption="../report/calibration_scene.rst",
            category="Calibration",
            subcategory="cloth",
        ),
        rrd=f"{RESULTS}/calibration/cloth/calibrate.rrd",
    params:
        out=get_out_dir,
        extra=f"{stage_overrides('calibrate_scene')} camera=cloth projector=cloth calibrate=cloth {CLOTH_CAL_HYDRA}",
    benchmark:
        f"{RESULTS}/benchmarks/calibrate_cloth.tsv"
    log:
        f"{RESULTS}/logs/calibrate_cloth.log",


ruleorder: calibrate_cloth_scene > calibrate_scene
ruleorder: reality_cloth > reality_demo


rule reality_cloth:
    """Reality films one fabric x trial of the swatch under stripes (footage + truth beside)."""
    input:
        calib=CLOTH_CAL,
    output:
        meta=f"{RESULTS}/footage/cloth_{{fabric}}_{{trial}}/meta.yaml",
        truth=f"{RESULTS}/footage/cloth_{{fabric}}_{{trial}}.truth.yaml",
        sheet=report(
            f"{RESULTS}/footage/cloth_{{fabric}}_{{trial}}/contact_sheet.png",
            caption="../report/cloth_footage.rst",
            category="Cloth",
            subcategory="footage",
        ),
        rrd=f"{RESULTS}/footage/cloth_{{fabric}}_{{trial}}/reality.rrd",
    params:
        out=get_out_dir,
        extra=stage_overrides("reality_cloth"),
        cloth=CLOTH_REALITY_HYDRA,
        fabric=cloth_fabric_reality_overrides,
    benchmark:
        f"{RESULTS}/benchmarks/reality_cloth_{{fabric}}_{{trial}}.tsv"
    log:
        f"{RESULTS}/logs/reality_cloth_{{fabric}}_{{trial}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1500,  # measured peak RSS 820 MB (MuJoCo + pyrender/EGL, 15x15 swatch, 55 frames)
        runtime=10,
    shell:
        "python -m vidsim.cli.cloth_reality paths.calibration={input.calib} paths.out={params.out} "
        "cloth.reality.fabric={wildcards.fabric} cloth.reality.motion={wildcards.trial} "
        "{params.extra} {params.cloth} {params.fabric} > {log} 2>&1"


rule fit_cloth:
    """Grid + annealing of one fabric x trial; evals.jsonl in the folder makes a rerun resume by replay."""
    input:
        meta=f"{RESULTS}/footage/cloth_{{fabric}}_{{trial}}/meta.yaml",
    output:
        fit=f"{RESULTS}/cloth/fit/{{fabric}}_{{trial}}/fit.yaml",
        trace=f"{RESULTS}/cloth/fit/{{fabric}}_{{trial}}/trace.csv",
        energy=report(
            f"{RESULTS}/cloth/fit/{{fabric}}_{{trial}}/energy.png",
            caption="../report/cloth_fit.rst",
            category="Cloth",
            subcategory="fits",
        ),
        rrd=f"{RESULTS}/cloth/fit/{{fabric}}_{{trial}}/cloth.rrd",
    params:
        out=get_out_dir,
        extra=stage_overrides("fit_cloth"),
        cloth=CLOTH_HYDRA,
        fabric=cloth_fabric_overrides,
    benchmark:
        f"{RESULTS}/benchmarks/fit_cloth_{{fabric}}_{{trial}}.tsv"
    log:
        f"{RESULTS}/logs/fit_cloth_{{fabric}}_{{trial}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # measured peak RSS 407 MB quick (12x12, 25 frames), 494 MB full (20x20, 50 frames)
        runtime=90,  # quick: 32 CPU-s per 56 evaluations; full (664 evaluations) ~19 CPU-min extrapolated
    shell:
        "python -m vidsim.cli.cloth_fit paths.footage=$(dirname {input.meta}) paths.out={params.out} "
        "{params.extra} {params.cloth} {params.fabric} > {log} 2>&1"


rule select_cloth:
    """Cross-trial selection of one fabric: each trial's candidates scored on the other trial, least E1+E2."""
    input:
        fits=expand(f"{RESULTS}/cloth/fit/{{{{fabric}}}}_{{trial}}/fit.yaml", trial=CLOTH_FIT_TRIALS),
        metas=expand(f"{RESULTS}/footage/cloth_{{{{fabric}}}}_{{trial}}/meta.yaml", trial=CLOTH_FIT_TRIALS),
    output:
        params=f"{RESULTS}/cloth/select/{{fabric}}/params.yaml",
        table=report(
            f"{RESULTS}/cloth/select/{{fabric}}/table.csv",
            caption="../report/cloth_select.rst",
            category="Cloth",
            subcategory="selection",
        ),
    params:
        out=get_out_dir,
        inputs=cloth_select_inputs,
        extra=stage_overrides("select_cloth"),
        cloth=CLOTH_HYDRA,
        fabric=cloth_fabric_overrides,
    benchmark:
        f"{RESULTS}/benchmarks/select_cloth_{{fabric}}.tsv"
    log:
        f"{RESULTS}/logs/select_cloth_{{fabric}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # measured peak RSS ~310 MB (Snakemake benchmark sampling)
        runtime=20,
    shell:
        "python -m vidsim.cli.cloth_select paths.out={params.out} {params.inputs} "
        "{params.extra} {params.cloth} {params.fabric} > {log} 2>&1"


rule validate_cloth:
    """Validation matrix on the held-out motion (every fabric's parameters x every fabric's footage) and Table 1."""
    input:
        params=expand(f"{RESULTS}/cloth/select/{{fabric}}/params.yaml", fabric=CLOTH_FABRICS),
        metas=expand(f"{RESULTS}/footage/cloth_{{fabric}}_{CLOTH_HELD_OUT}/meta.yaml", fabric=CLOTH_FABRICS),
    output:
        matrix=report(
            f"{RESULTS}/cloth/validate/matrix.png",
            caption="../report/cloth_validate.rst",
            category="Cloth",
            subcategory="validation",
        ),
        csv=f"{RESULTS}/cloth/validate/matrix.csv",
        table=report(
            f"{RESULTS}/cloth/validate/table1.csv",
            caption="../report/cloth_table1.rst",
            category="Cloth",
            subcategory="Table 1",
        ),
        table_png=report(
            f"{RESULTS}/cloth/validate/table1.png",
            caption="../report/cloth_table1.rst",
            category="Cloth",
            subcategory="Table 1",
        ),
    params:
        out=get_out_dir,
        inputs=cloth_validate_inputs,
        extra=stage_overrides("validate_cloth"),
        cloth=CLOTH_HYDRA,
    benchmark:
        f"{RESULTS}/benchmarks/validate_cloth.tsv"
    log:
        f"{RESULTS}/logs/validate_cloth.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # measured peak RSS ~280 MB (Snakemake benchmark sampling)
        runtime=20,
    shell:
        "python -m vidsim.cli.cloth_validate paths.out={params.out} {params.inputs} "
        "{params.extra} {params.cloth} > {log} 2>&1"
