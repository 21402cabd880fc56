# Sim-to-real gap (issue 7): where the gap of a fit lies, which unmodelled effect causes it, how far
# it shrinks. What runs: `gap:` in the Snakemake config -- suite_cases (names of entries of
# conf/gap/default.yaml `cases`; empty list = all), diagnose_cases (rigid cases of `rigid.cases`
# whose fit is diagnosed), ball (the real toss, both timings), cloth_suite_cases (the cloth cases,
# below), cloth_diagnose (cloth fabrics whose selection is diagnosed) and cloth_diagnose_trial. How:
# Hydra (`gap.*`; per-rule `overrides: {gap_suite: ..., diagnose_rigid: ..., gap_ball: ...,
# gap_cloth_suite: ..., diagnose_cloth: ...}`).
# Layout: {RESULTS}/gap/suite/{suite.json,confusion.*,shrinkage.csv,suite.rrd,cases/},
# {RESULTS}/gap/rigid_{case}/{diagnosis.json,diagnosis.png,diagnosis.rrd}, {RESULTS}/gap/ball/,
# {RESULTS}/gap/cloth_suite/{suite.json,confusion.*,shrinkage.csv,cases/},
# {RESULTS}/gap/cloth_{fabric}_{trial}/{diagnosis.json,diagnosis.png,diagnosis.rrd} (cloth_diagnose).
GAP = config.get("gap", {}) or {}
GAP_SUITE_ONLY = ",".join(str(c) for c in (GAP.get("suite_cases", []) or []))
GAP_DIAGNOSE = list(GAP.get("diagnose_cases", []) or [])
# cloth_suite_cases: absent or null = the cloth cases do not run; [] = all of conf/gap/default.yaml
# `cloth.cases`; a list = those (docs/gap.md, cloth: measured, nothing named yet)
GAP_CLOTH = GAP.get("cloth_suite_cases")
GAP_CLOTH_ONLY = ",".join(str(c) for c in (GAP_CLOTH or []))
# cloth_diagnose: fabrics of the cloth study whose selected parameters are diagnosed blind on the
# footage of trial cloth_diagnose_trial (default: the held-out motion); needs the cloth family on
GAP_CLOTH_DIAG = list(GAP.get("cloth_diagnose", []) or [])
GAP_CLOTH_DIAG_TRIAL = GAP.get("cloth_diagnose_trial", CLOTH_HELD_OUT)


if stage_enabled("gap"):
    TARGETS["gap"] = [f"{RESULTS}/gap/suite/suite.json", f"{RESULTS}/gap/suite/confusion.png"]
    TARGETS["gap"] += [f"{RESULTS}/gap/rigid_{c}/diagnosis.json" for c in GAP_DIAGNOSE]
    if GAP.get("ball", False) and shared_available("tracklab_physics/verticalToss.webm"):
        TARGETS["gap"] += [f"{RESULTS}/gap/ball/ball_gap.json"]
    if GAP_CLOTH is not None:
        TARGETS["gap"] += [f"{RESULTS}/gap/cloth_suite/suite.json"]
    if stage_enabled("cloth"):
        TARGETS["gap"] += [f"{RESULTS}/gap/cloth_{f}_{GAP_CLOTH_DIAG_TRIAL}/diagnosis.json" for f in GAP_CLOTH_DIAG]


rule gap_suite:
    """Withheld-effect suite: film each case, fit it, diagnose it blind, score the diagnosis against the truth."""
    output:
        suite=f"{RESULTS}/gap/suite/suite.json",
        confusion=report(
            f"{RESULTS}/gap/suite/confusion.png", caption="../report/gap_confusion.rst", category="Sim-to-real gap"
        ),
        shrinkage=report(
            f"{RESULTS}/gap/suite/shrinkage.csv", caption="../report/gap_shrinkage.rst", category="Sim-to-real gap"
        ),
        rrd=f"{RESULTS}/gap/suite/suite.rrd",
    params:
        conf=CONF_GAP,
        out=get_out_dir,
        only=f"gap.only=[{GAP_SUITE_ONLY}]",
        extra=stage_overrides("gap_suite"),
    log:
        f"{RESULTS}/logs/gap_suite.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1500,  # measured peak RSS 986 MB (whole public suite, 14 cases, 805 CPU-s, 2026-12-01)
        runtime=60,
    shell:
        "python -m vidsim.cli.gap_suite paths.out={params.out} {params.only} {params.extra} > {log} 2>&1"


rule gap_cloth_suite:
    """Cloth withheld-effect cases: film a twin swatch with the effect on, fit it, diagnose it blind, score it."""
    output:
        suite=f"{RESULTS}/gap/cloth_suite/suite.json",
        confusion=report(
            f"{RESULTS}/gap/cloth_suite/confusion.png",
            caption="../report/gap_cloth_confusion.rst",
            category="Sim-to-real gap",
        ),
        shrinkage=report(
            f"{RESULTS}/gap/cloth_suite/shrinkage.csv", caption="../report/gap_shrinkage.rst", category="Sim-to-real gap"
        ),
    params:
        conf=CONF_GAP,
        out=get_out_dir,
        only=f"gap.cloth.only=[{GAP_CLOTH_ONLY}]",
        extra=stage_overrides("gap_cloth_suite"),
    log:
        f"{RESULTS}/logs/gap_cloth_suite.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1200,  # measured peak RSS 646 MB (the 11 public cases, 2026-12-02; 502-597 MB in smaller runs)
        runtime=60,  # minutes: the 14 cases 1906 CPU-s in one process (4 Dec 2026; 733 CPU-s for 11 on 2 Dec)
    shell:
        "python -m vidsim.cli.gap_cloth_suite paths.out={params.out} {params.only} {params.extra} > {log} 2>&1"


rule diagnose_rigid:
    """Blind diagnosis of a rigid case's fit: where the gap lies, which effect, how far it shrinks."""
    input:
        meta=rigid_meta,
        masks=f"{RESULTS}/rigid/{{case}}/masks.npz",
        fit=f"{RESULTS}/rigid/{{case}}/fit.yaml",
    output:
        diagnosis=f"{RESULTS}/gap/rigid_{{case}}/diagnosis.json",
        plot=report(
            f"{RESULTS}/gap/rigid_{{case}}/diagnosis.png",
            caption="../report/gap_diagnosis.rst",
            category="Sim-to-real gap",
            subcategory="{case}",
        ),
        rrd=f"{RESULTS}/gap/rigid_{{case}}/diagnosis.rrd",
    params:
        conf=CONF_GAP,
        out=get_out_dir,
        extra=stage_overrides("diagnose_rigid"),
    log:
        f"{RESULTS}/logs/gap_rigid_{{case}}_diagnose.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1500,  # same code path as a suite case (suite peak RSS 986 MB); not measured alone
        runtime=20,
    shell:
        "python -m vidsim.cli.diagnose paths.footage=$(dirname {input.meta}) gap.paths.masks={input.masks} "
        "gap.paths.fit={input.fit} paths.out={params.out} {params.extra} > {log} 2>&1"


rule diagnose_cloth:
    """Blind diagnosis of a fabric's selected parameters on one of its trials (default the held-out motion)."""
    input:
        meta=f"{RESULTS}/footage/cloth_{{fabric}}_{{trial}}/meta.yaml",
        params=f"{RESULTS}/cloth/select/{{fabric}}/params.yaml",
    output:
        diagnosis=f"{RESULTS}/gap/cloth_{{fabric}}_{{trial}}/diagnosis.json",
        plot=report(
            f"{RESULTS}/gap/cloth_{{fabric}}_{{trial}}/diagnosis.png",
            caption="../report/gap_diagnosis_cloth.rst",
            category="Sim-to-real gap",
            subcategory="cloth {fabric}",
        ),
        rrd=f"{RESULTS}/gap/cloth_{{fabric}}_{{trial}}/diagnosis.rrd",
    wildcard_constraints:
        fabric="[A-Za-z0-9]+",
        trial="[A-Za-z0-9]+",
    params:
        conf=CONF_GAP,
        out=get_out_dir,
        base=STAGE_BASE,
        cloth=CLOTH_HYDRA,
        fabric=cloth_fabric_overrides,
        extra=stage_own("diagnose_cloth"),
    benchmark:
        f"{RESULTS}/benchmarks/diagnose_cloth_{{fabric}}_{{trial}}.tsv"
    log:
        f"{RESULTS}/logs/gap_cloth_{{fabric}}_{{trial}}_diagnose.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1200,  # the same diagnosis as a cloth suite case (suite peak RSS 654 MB; full setting 902 MB)
        runtime=60,  # minutes: quick 1-4.5 CPU-min; full setting linen 17 CPU-min, satin about twice that
    shell:
        "python -m vidsim.cli.diagnose_cloth paths.footage=$(dirname {input.meta}) gap.paths.fit={input.params} "
        "paths.out={params.out} {params.base} {params.cloth} {params.fabric} {params.extra} > {log} 2>&1"


rule gap_ball:
    """The real toss read with the container's timestamps and at a constant rate: is frame timing the gap?"""
    input:
        video=SHARED / "tracklab_physics" / "verticalToss.webm",
    output:
        gap=f"{RESULTS}/gap/ball/ball_gap.json",
        plot=report(f"{RESULTS}/gap/ball/ball_gap.png", caption="../report/gap_ball.rst", category="Sim-to-real gap"),
        rrd=f"{RESULTS}/gap/ball/ball_gap.rrd",
    params:
        conf=CONF_GAP,
        out=get_out_dir,
        extra=stage_overrides("gap_ball"),
    log:
        f"{RESULTS}/logs/gap_ball.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=900,  # measured peak RSS 455 MB
        runtime=5,
    shell:
        "python -m vidsim.cli.gap_ball rigid.paths.video={input.video} paths.out={params.out} {params.extra} > {log} 2>&1"
