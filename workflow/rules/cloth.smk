# cloth stages (wired in this file only; see workflow/rules/demo.smk for the pattern).
# calibrate_scene (scene=cloth, existing rule) -> reality_cloth per fabric x trial ->
# fit_cloth per fabric x fitted trial -> select_cloth per fabric -> validate_cloth (Figure 8, Table 1);
# select -> profile_cloth (which parameters the footage determines);
# twins (the estimator's own simulator as reality, known truth): reality -> fit -> select -> profile
#   -> score_cloth_twin;
# skirts: reality_skirt per fabric -> skirt_cloth (Figure 9 matrix, side-by-side videos);
# comparison: fit_cloth_cmaes + select_cloth_cmaes, fit_cloth_joint -> compare_cloth.
# What runs: the `cloth:` section of workflow/config/{quick,full}.yaml.

CLOTH = config.get("cloth", {}) or {}
CLOTH_FABRICS = list(CLOTH.get("fabrics", ["linen", "satin"]))
CLOTH_FIT_TRIALS = list(CLOTH.get("fit_trials", ["exp1", "exp2"]))
CLOTH_HELD_OUT = CLOTH.get("held_out", "robot")
CLOTH_HYDRA = CLOTH.get("hydra", "") or ""  # fit_cloth, select_cloth, validate_cloth
CLOTH_REALITY_HYDRA = CLOTH.get("reality_hydra", "") or ""  # reality_cloth
CLOTH_CAL_HYDRA = CLOTH.get("calibration_hydra", "") or ""  # the cloth scene's calibration
CLOTH_CAL = f"{RESULTS}/calibration/cloth/calibration.yaml"
CLOTH_TWINS = list(CLOTH.get("twins", []) or [])  # names of twin realities (fabric wildcard values)
CLOTH_SKIRT = bool(CLOTH.get("skirt", False))
CLOTH_COMPARE = list(CLOTH.get("compare", []) or [])  # fabrics of the method comparison
CLOTH_PROFILE = bool(CLOTH.get("profile", True))
CLOTH_SKIRT_HYDRA = CLOTH.get("skirt_hydra", "") or ""  # reality_skirt and skirt_cloth

include: "cloth_functions.smk"


wildcard_constraints:
    fabric="[a-z]+",
    trial="[a-z0-9]+",


if stage_enabled("cloth"):
    TARGETS["cloth"] = [
        f"{RESULTS}/cloth/validate/matrix.png",
        f"{RESULTS}/cloth/validate/table1.csv",
    ] + [f"{RESULTS}/cloth/select/{f}/params.yaml" for f in CLOTH_FABRICS]
    if CLOTH_PROFILE:
        TARGETS["cloth"] += [f"{RESULTS}/cloth/profile/{f}/profile.yaml" for f in CLOTH_FABRICS + CLOTH_TWINS]
    TARGETS["cloth"] += [f"{RESULTS}/cloth/twin/{t}/score.yaml" for t in CLOTH_TWINS]
    # twins in the method comparison: their joint fit scored against the truth too
    TARGETS["cloth"] += [f"{RESULTS}/cloth/twin_joint/{t}/score.yaml" for t in CLOTH_TWINS if t in CLOTH_COMPARE]
    if CLOTH_SKIRT:
        TARGETS["cloth"] += [f"{RESULTS}/cloth/skirt/{x}" for x in ("matrix.png", "skirt.yaml", "side_by_side.png")]
    if CLOTH_COMPARE:
        TARGETS["cloth"] += [f"{RESULTS}/cloth/compare/{x}" for x in ("compare.csv", "heldout.png", "curves.png")]


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
        conf=CONF_CLOTH,
        out=get_out_dir,
        extra=f"{STAGE_BASE} camera=cloth projector=cloth calibrate=cloth {CLOTH_CAL_HYDRA} "
        f"{stage_own('calibrate_scene', 'calibrate_cloth_scene')}".strip(),
    benchmark:
        f"{RESULTS}/benchmarks/calibrate_cloth.tsv"
    log:
        f"{RESULTS}/logs/calibrate_cloth.log",


ruleorder: calibrate_cloth_scene > calibrate_scene
ruleorder: reality_cloth > reality_demo
ruleorder: reality_skirt > reality_demo


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
        rrd=f"{RESULTS}/footage/cloth_{{fabric}}_{{trial}}.reality.rrd",
    params:
        conf=CONF_CLOTH,
        out=get_out_dir,
        base=STAGE_BASE,
        extra=stage_own("reality_cloth"),
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
        "{params.base} {params.cloth} {params.fabric} {params.extra} > {log} 2>&1"


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
        conf=CONF_CLOTH,
        out=get_out_dir,
        base=STAGE_BASE,
        extra=stage_own("fit_cloth"),
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
        "{params.base} {params.cloth} {params.fabric} {params.extra} > {log} 2>&1"


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
        conf=CONF_CLOTH,
        out=get_out_dir,
        inputs=cloth_select_inputs,
        base=STAGE_BASE,
        extra=stage_own("select_cloth"),
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
        "{params.base} {params.cloth} {params.fabric} {params.extra} > {log} 2>&1"


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
        doc=f"{RESULTS}/cloth/validate/validation.yaml",
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
        conf=CONF_CLOTH,
        out=get_out_dir,
        inputs=cloth_validate_inputs,
        base=STAGE_BASE,
        extra=stage_own("validate_cloth"),
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
        "{params.base} {params.cloth} {params.extra} > {log} 2>&1"


rule profile_cloth:
    """Error profiles around one fabric's selected parameters on its fitted trials: which parameters the footage determines."""
    input:
        params=f"{RESULTS}/cloth/select/{{fabric}}/params.yaml",
        metas=expand(f"{RESULTS}/footage/cloth_{{{{fabric}}}}_{{trial}}/meta.yaml", trial=CLOTH_FIT_TRIALS),
    output:
        profile=f"{RESULTS}/cloth/profile/{{fabric}}/profile.yaml",
        csv=f"{RESULTS}/cloth/profile/{{fabric}}/profiles.csv",
        png=report(
            f"{RESULTS}/cloth/profile/{{fabric}}/profiles.png",
            caption="../report/cloth_profile.rst",
            category="Cloth",
            subcategory="profiles",
        ),
    params:
        conf=CONF_CLOTH,
        out=get_out_dir,
        footage=cloth_meta_folders,
        base=STAGE_BASE,
        extra=stage_own("profile_cloth"),
        cloth=CLOTH_HYDRA,
        fabric=cloth_fabric_overrides,
    benchmark:
        f"{RESULTS}/benchmarks/profile_cloth_{{fabric}}.tsv"
    log:
        f"{RESULTS}/logs/profile_cloth_{{fabric}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,
        runtime=60,
    shell:
        "python -m vidsim.cli.cloth_profile paths.out={params.out} cloth.profile.params={input.params} "
        "cloth.profile.footage={params.footage} {params.base} {params.cloth} {params.fabric} {params.extra} > {log} 2>&1"


rule score_cloth_twin:
    """Twin reality: the selected parameters against the known truth, and on the held-out motion against the true parameters."""
    input:
        params=f"{RESULTS}/cloth/select/{{fabric}}/params.yaml",
        profile=f"{RESULTS}/cloth/profile/{{fabric}}/profile.yaml",
        meta=f"{RESULTS}/footage/cloth_{{fabric}}_{CLOTH_HELD_OUT}/meta.yaml",
        truth=f"{RESULTS}/footage/cloth_{{fabric}}_{CLOTH_HELD_OUT}.truth.yaml",
    output:
        score=f"{RESULTS}/cloth/twin/{{fabric}}/score.yaml",
        csv=report(
            f"{RESULTS}/cloth/twin/{{fabric}}/errors.csv",
            caption="../report/cloth_twin.rst",
            category="Cloth",
            subcategory="twin",
        ),
        png=report(
            f"{RESULTS}/cloth/twin/{{fabric}}/errors.png",
            caption="../report/cloth_twin.rst",
            category="Cloth",
            subcategory="twin",
        ),
    params:
        conf=CONF_CLOTH,
        out=get_out_dir,
        base=STAGE_BASE,
        extra=stage_own("score_cloth_twin"),
        cloth=CLOTH_HYDRA,
        fabric=cloth_fabric_overrides,
    benchmark:
        f"{RESULTS}/benchmarks/score_cloth_twin_{{fabric}}.tsv"
    log:
        f"{RESULTS}/logs/score_cloth_twin_{{fabric}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,
        runtime=10,
    shell:
        "python -m vidsim.cli.cloth_twin_score paths.out={params.out} cloth.twin.params={input.params} "
        "cloth.twin.profile={input.profile} cloth.twin.footage=$(dirname {input.meta}) "
        "{params.base} {params.cloth} {params.fabric} {params.extra} > {log} 2>&1"

rule score_cloth_twin_joint:
    """Twin reality: the joint fit (one annealing over both trials) against the known truth, like score_cloth_twin."""
    input:
        params=f"{RESULTS}/cloth/fit_joint/{{fabric}}/fit.yaml",
        meta=f"{RESULTS}/footage/cloth_{{fabric}}_{CLOTH_HELD_OUT}/meta.yaml",
        truth=f"{RESULTS}/footage/cloth_{{fabric}}_{CLOTH_HELD_OUT}.truth.yaml",
    output:
        score=f"{RESULTS}/cloth/twin_joint/{{fabric}}/score.yaml",
        csv=report(
            f"{RESULTS}/cloth/twin_joint/{{fabric}}/errors.csv",
            caption="../report/cloth_twin.rst",
            category="Cloth",
            subcategory="twin",
        ),
        png=report(
            f"{RESULTS}/cloth/twin_joint/{{fabric}}/errors.png",
            caption="../report/cloth_twin.rst",
            category="Cloth",
            subcategory="twin",
        ),
    params:
        conf=CONF_CLOTH,
        out=get_out_dir,
        base=STAGE_BASE,
        extra=stage_own("score_cloth_twin", "score_cloth_twin_joint"),
        cloth=CLOTH_HYDRA,
        fabric=cloth_fabric_overrides,
    benchmark:
        f"{RESULTS}/benchmarks/score_cloth_twin_joint_{{fabric}}.tsv"
    log:
        f"{RESULTS}/logs/score_cloth_twin_joint_{{fabric}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,
        runtime=10,
    shell:
        "python -m vidsim.cli.cloth_twin_score paths.out={params.out} cloth.twin.params={input.params} "
        "cloth.twin.profile= cloth.twin.footage=$(dirname {input.meta}) "
        "{params.base} {params.cloth} {params.fabric} {params.extra} > {log} 2>&1"


rule reality_skirt:
    """Reality dresses the skipping body with a MuJoCo skirt of one fabric, filmed under the stripes."""
    input:
        calib=CLOTH_CAL,
    output:
        meta=f"{RESULTS}/footage/skirt_{{fabric}}/meta.yaml",
        truth=f"{RESULTS}/footage/skirt_{{fabric}}.truth.yaml",
        sheet=report(
            f"{RESULTS}/footage/skirt_{{fabric}}/contact_sheet.png",
            caption="../report/cloth_footage.rst",
            category="Cloth",
            subcategory="footage",
        ),
        rrd=f"{RESULTS}/footage/skirt_{{fabric}}.reality.rrd",
    params:
        conf=CONF_CLOTH,
        out=get_out_dir,
        base=STAGE_BASE,
        extra=stage_own("reality_skirt"),
        cloth=CLOTH_REALITY_HYDRA,
        skirt=CLOTH_SKIRT_HYDRA,
    benchmark:
        f"{RESULTS}/benchmarks/reality_skirt_{{fabric}}.tsv"
    log:
        f"{RESULTS}/logs/reality_skirt_{{fabric}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1500,
        runtime=15,
    shell:
        "python -m vidsim.cli.cloth_reality paths.calibration={input.calib} paths.out={params.out} "
        "cloth.reality.fabric={wildcards.fabric} cloth.reality.object=skirt "
        "{params.base} {params.cloth} {params.skirt} {params.extra} > {log} 2>&1"


rule skirt_cloth:
    """Skirt matrix (seed Figure 9): every fabric's selected swatch parameters dress every fabric's skirt footage."""
    input:
        params=expand(f"{RESULTS}/cloth/select/{{fabric}}/params.yaml", fabric=CLOTH_FABRICS),
        metas=expand(f"{RESULTS}/footage/skirt_{{fabric}}/meta.yaml", fabric=CLOTH_FABRICS),
    output:
        matrix=report(
            f"{RESULTS}/cloth/skirt/matrix.png",
            caption="../report/cloth_skirt.rst",
            category="Cloth",
            subcategory="skirt",
        ),
        csv=f"{RESULTS}/cloth/skirt/matrix.csv",
        doc=f"{RESULTS}/cloth/skirt/skirt.yaml",
        stills=report(
            f"{RESULTS}/cloth/skirt/side_by_side.png",
            caption="../report/cloth_skirt.rst",
            category="Cloth",
            subcategory="skirt",
        ),
        rrd=f"{RESULTS}/cloth/skirt/skirt.rrd",
    params:
        conf=CONF_CLOTH,
        out=get_out_dir,
        inputs=cloth_skirt_inputs,
        base=STAGE_BASE,
        extra=stage_own("skirt_cloth"),
        cloth=CLOTH_HYDRA,
        skirt=CLOTH_SKIRT_HYDRA,
    benchmark:
        f"{RESULTS}/benchmarks/skirt_cloth.tsv"
    log:
        f"{RESULTS}/logs/skirt_cloth.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1500,
        runtime=30,
    shell:
        "python -m vidsim.cli.cloth_skirt paths.out={params.out} {params.inputs} "
        "{params.base} {params.cloth} {params.skirt} {params.extra} > {log} 2>&1"


use rule fit_cloth as fit_cloth_cmaes with:
    output:
        fit=f"{RESULTS}/cloth/fit_cmaes/{{fabric}}_{{trial}}/fit.yaml",
        trace=f"{RESULTS}/cloth/fit_cmaes/{{fabric}}_{{trial}}/trace.csv",
        energy=f"{RESULTS}/cloth/fit_cmaes/{{fabric}}_{{trial}}/energy.png",
        rrd=f"{RESULTS}/cloth/fit_cmaes/{{fabric}}_{{trial}}/cloth.rrd",
    params:
        conf=CONF_CLOTH,
        out=get_out_dir,
        base=STAGE_BASE,
        extra=f"{stage_own('fit_cloth', 'fit_cloth_cmaes')} cloth.fit.method=cmaes".strip(),
        cloth=CLOTH_HYDRA,
        fabric=cloth_fabric_overrides,
    benchmark:
        f"{RESULTS}/benchmarks/fit_cloth_cmaes_{{fabric}}_{{trial}}.tsv"
    log:
        f"{RESULTS}/logs/fit_cloth_cmaes_{{fabric}}_{{trial}}.log",


use rule select_cloth as select_cloth_cmaes with:
    input:
        fits=expand(f"{RESULTS}/cloth/fit_cmaes/{{{{fabric}}}}_{{trial}}/fit.yaml", trial=CLOTH_FIT_TRIALS),
        metas=expand(f"{RESULTS}/footage/cloth_{{{{fabric}}}}_{{trial}}/meta.yaml", trial=CLOTH_FIT_TRIALS),
    output:
        params=f"{RESULTS}/cloth/select_cmaes/{{fabric}}/params.yaml",
        table=f"{RESULTS}/cloth/select_cmaes/{{fabric}}/table.csv",
    params:
        conf=CONF_CLOTH,
        out=get_out_dir,
        inputs=cloth_select_inputs,
        base=STAGE_BASE,
        extra=stage_own("select_cloth", "select_cloth_cmaes"),
        cloth=CLOTH_HYDRA,
        fabric=cloth_fabric_overrides,
    benchmark:
        f"{RESULTS}/benchmarks/select_cloth_cmaes_{{fabric}}.tsv"
    log:
        f"{RESULTS}/logs/select_cloth_cmaes_{{fabric}}.log",


rule fit_cloth_joint:
    """One annealing over all fitted trials of a fabric at once (their errors summed)."""
    input:
        metas=expand(f"{RESULTS}/footage/cloth_{{{{fabric}}}}_{{trial}}/meta.yaml", trial=CLOTH_FIT_TRIALS),
    output:
        fit=f"{RESULTS}/cloth/fit_joint/{{fabric}}/fit.yaml",
        trace=f"{RESULTS}/cloth/fit_joint/{{fabric}}/trace.csv",
        energy=f"{RESULTS}/cloth/fit_joint/{{fabric}}/energy.png",
        rrd=f"{RESULTS}/cloth/fit_joint/{{fabric}}/cloth.rrd",
    params:
        conf=CONF_CLOTH,
        out=get_out_dir,
        footage=cloth_meta_folders,
        base=STAGE_BASE,
        extra=stage_own("fit_cloth", "fit_cloth_joint"),
        cloth=CLOTH_HYDRA,
        fabric=cloth_fabric_overrides,
    benchmark:
        f"{RESULTS}/benchmarks/fit_cloth_joint_{{fabric}}.tsv"
    log:
        f"{RESULTS}/logs/fit_cloth_joint_{{fabric}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,
        runtime=180,  # two trials per evaluation: twice a per-trial fit
    shell:
        "python -m vidsim.cli.cloth_fit cloth.fit.footage={params.footage} paths.out={params.out} "
        "{params.base} {params.cloth} {params.fabric} {params.extra} > {log} 2>&1"


rule compare_cloth:
    """Per-trial annealing + selection vs joint annealing vs CMA-ES + selection, on each fabric's held-out motion."""
    input:
        heldout=expand(f"{RESULTS}/footage/cloth_{{fabric}}_{CLOTH_HELD_OUT}/meta.yaml", fabric=CLOTH_COMPARE),
        anneal=expand(f"{RESULTS}/cloth/select/{{fabric}}/params.yaml", fabric=CLOTH_COMPARE),
        cmaes=expand(f"{RESULTS}/cloth/select_cmaes/{{fabric}}/params.yaml", fabric=CLOTH_COMPARE),
        joint=expand(f"{RESULTS}/cloth/fit_joint/{{fabric}}/fit.yaml", fabric=CLOTH_COMPARE),
        anneal_traces=expand(f"{RESULTS}/cloth/fit/{{fabric}}_{{trial}}/trace.csv", fabric=CLOTH_COMPARE,
                             trial=CLOTH_FIT_TRIALS),
        cmaes_traces=expand(f"{RESULTS}/cloth/fit_cmaes/{{fabric}}_{{trial}}/trace.csv", fabric=CLOTH_COMPARE,
                            trial=CLOTH_FIT_TRIALS),
        joint_traces=expand(f"{RESULTS}/cloth/fit_joint/{{fabric}}/trace.csv", fabric=CLOTH_COMPARE),
    output:
        csv=report(
            f"{RESULTS}/cloth/compare/compare.csv",
            caption="../report/cloth_compare.rst",
            category="Cloth",
            subcategory="methods",
        ),
        doc=f"{RESULTS}/cloth/compare/compare.yaml",
        heldout=report(
            f"{RESULTS}/cloth/compare/heldout.png",
            caption="../report/cloth_compare.rst",
            category="Cloth",
            subcategory="methods",
        ),
        curves=report(
            f"{RESULTS}/cloth/compare/curves.png",
            caption="../report/cloth_compare.rst",
            category="Cloth",
            subcategory="methods",
        ),
    params:
        conf=CONF_CLOTH,
        out=get_out_dir,
        inputs=cloth_compare_inputs,
        base=STAGE_BASE,
        extra=stage_own("compare_cloth"),
        cloth=CLOTH_HYDRA,
    benchmark:
        f"{RESULTS}/benchmarks/compare_cloth.tsv"
    log:
        f"{RESULTS}/logs/compare_cloth.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,
        runtime=20,
    shell:
        "python -m vidsim.cli.cloth_compare paths.out={params.out} {params.inputs} "
        "{params.base} {params.cloth} {params.extra} > {log} 2>&1"
