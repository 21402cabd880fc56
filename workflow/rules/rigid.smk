# Rigid bodies from video (issue 3): reality -> footage -> segment -> fit -> score -> summary, and
# the real ball toss. What runs: `rigid:` in the Snakemake config (cases = {name: {seed, overrides}},
# ball = true/false; a case {footage: <folder>} is your own recording: segmented, fitted, never
# scored); how: Hydra (`rigid.*`, `effects.*`; per-rule `overrides: {fit_rigid: ...}`).
# Layout: footage {RESULTS}/footage/rigid_{case}/ (truth and ground-truth masks beside it),
# {RESULTS}/rigid/{case}/{masks.npz,fit.yaml,score.yaml}, {RESULTS}/rigid/summary.csv,
# {RESULTS}/rigid/ball/ball.yaml.
include: "rigid_common.smk"


# the demo's reality rule would also match footage/rigid_<case>/meta.yaml
ruleorder: reality_rigid > reality_demo


if stage_enabled("rigid"):
    TARGETS["rigid"] = [f"{RESULTS}/rigid/{c}/{f}" for c in RIGID_CASES for f in ("overlay.mp4", "errors.png")]
    if RIGID_SYNTHETIC:
        TARGETS["rigid"] += [f"{RESULTS}/rigid/summary.csv", f"{RESULTS}/rigid/summary.png"]
    if RIGID.get("ball", False) and shared_available("tracklab_physics/verticalToss.webm"):
        TARGETS["rigid"] += [f"{RESULTS}/rigid/ball/ball.yaml", f"{RESULTS}/rigid/ball/ball.png"]


rule reality_rigid:
    """Film a thrown T-object (MuJoCo flight, pyrender images); truth and ground-truth masks beside the folder."""
    output:
        meta=f"{RESULTS}/footage/rigid_{{case}}/meta.yaml",
        truth=f"{RESULTS}/footage/rigid_{{case}}.truth.yaml",
        truth_masks=f"{RESULTS}/footage/rigid_{{case}}.truth_masks.npz",
        sheet=report(
            f"{RESULTS}/footage/rigid_{{case}}/contact_sheet.png",
            caption="../report/rigid_footage.rst",
            category="Rigid bodies",
            subcategory="{case}",
        ),
        rrd=f"{RESULTS}/footage/rigid_{{case}}.reality.rrd",
    params:
        conf=CONF_RIGID,
        out=get_out_dir,
        case=rigid_case_overrides,
        extra=stage_overrides("reality_rigid"),
    log:
        f"{RESULTS}/logs/rigid_{{case}}_reality.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1200,  # measured peak RSS 687 MB (640x480, 70 frames, pyrender/EGL)
        runtime=10,
    shell:
        "python -m vidsim.cli.reality_rigid paths.out={params.out} {params.case} {params.extra} > {log} 2>&1"


rule segment_rigid:
    """Silhouettes from the footage alone (per-pixel background model learnt from the clip)."""
    input:
        meta=rigid_meta,
    output:
        masks=f"{RESULTS}/rigid/{{case}}/masks.npz",
        summary=f"{RESULTS}/rigid/{{case}}/segment.yaml",
        sheet=report(
            f"{RESULTS}/rigid/{{case}}/segment_sheet.png",
            caption="../report/rigid_segment.rst",
            category="Rigid bodies",
            subcategory="{case}",
        ),
    params:
        conf=CONF_RIGID,
        out=get_out_dir,
        footage=rigid_footage_dir,
        case=rigid_case_overrides,
        extra=stage_overrides("segment_rigid"),
    log:
        f"{RESULTS}/logs/rigid_{{case}}_segment.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=800,  # measured peak RSS 430 MB
        runtime=10,
    shell:
        "python -m vidsim.cli.segment paths.footage={params.footage} paths.out={params.out} {params.case} {params.extra} > {log} 2>&1"


rule fit_rigid:
    """Multi-start hybrid-gradient fit of the free-flight model to the silhouettes (never reads truth)."""
    input:
        meta=rigid_meta,
        masks=f"{RESULTS}/rigid/{{case}}/masks.npz",
    output:
        fit=f"{RESULTS}/rigid/{{case}}/fit.yaml",
        overlay=report(
            f"{RESULTS}/rigid/{{case}}/overlay.mp4",
            caption="../report/rigid_overlay.rst",
            category="Rigid bodies",
            subcategory="{case}",
        ),
        errors=report(
            f"{RESULTS}/rigid/{{case}}/errors.png",
            caption="../report/rigid_errors.rst",
            category="Rigid bodies",
            subcategory="{case}",
        ),
        rrd=f"{RESULTS}/rigid/{{case}}/rigid.rrd",
    params:
        conf=CONF_RIGID,
        out=get_out_dir,
        footage=rigid_footage_dir,
        case=rigid_case_overrides,
        extra=stage_overrides("fit_rigid"),
    log:
        f"{RESULTS}/logs/rigid_{{case}}_fit.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1200,  # measured peak RSS 675 MB
        runtime=20,
    shell:
        "python -m vidsim.cli.fit_rigid paths.footage={params.footage} rigid.paths.masks={input.masks} "
        "paths.out={params.out} {params.case} {params.extra} rigid.overlay=mp4 > {log} 2>&1"  # the declared overlay.mp4


rule score_rigid:
    """Score the fit and the segmentation against the truth (the only reader of truth)."""
    input:
        truth=f"{RESULTS}/footage/rigid_{{case}}.truth.yaml",
        truth_masks=f"{RESULTS}/footage/rigid_{{case}}.truth_masks.npz",
        masks=f"{RESULTS}/rigid/{{case}}/masks.npz",
        fit=f"{RESULTS}/rigid/{{case}}/fit.yaml",
    output:
        score=f"{RESULTS}/rigid/{{case}}/score.yaml",
    params:
        conf=CONF_RIGID,
        out=get_out_dir,
        footage=rigid_footage_dir,
        extra=stage_overrides("score_rigid"),
    log:
        f"{RESULTS}/logs/rigid_{{case}}_score.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=700,  # measured peak RSS 383 MB
        runtime=5,
    shell:
        "python -m vidsim.cli.score_rigid paths.footage={params.footage} rigid.paths.fit={input.fit} "
        "rigid.paths.masks={input.masks} paths.out={params.out} {params.extra} > {log} 2>&1"


rule rigid_summary:
    """One table over the scored throws of the study."""
    input:
        scores=expand(f"{RESULTS}/rigid/{{case}}/score.yaml", case=RIGID_SYNTHETIC),
    output:
        csv=report(f"{RESULTS}/rigid/summary.csv", caption="../report/rigid_summary.rst", category="Rigid bodies"),
        png=report(f"{RESULTS}/rigid/summary.png", caption="../report/rigid_summary.rst", category="Rigid bodies"),
    params:
        conf=CONF_RIGID,
        out=get_out_dir,
        extra=stage_overrides("rigid_summary"),
    log:
        f"{RESULTS}/logs/rigid_summary.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # measured peak RSS 250 MB, and ~170 MB for the job step's own Snakemake process
        runtime=5,
    shell:
        "python -m vidsim.cli.rigid_summary \"rigid.paths.scores='{input.scores}'\" paths.out={params.out} "
        "{params.extra} > {log} 2>&1"


rule rigid_ball:
    """The real toss (TrackLab verticalToss.webm): ball found, free-flight fits with container vs constant timing."""
    input:
        video=SHARED / "tracklab_physics" / "verticalToss.webm",
    output:
        ball=f"{RESULTS}/rigid/ball/ball.yaml",
        plot=report(f"{RESULTS}/rigid/ball/ball.png", caption="../report/rigid_ball.rst", category="Rigid bodies"),
        rrd=f"{RESULTS}/rigid/ball/ball.rrd",
    params:
        conf=CONF_RIGID,
        out=get_out_dir,
        extra=stage_overrides("rigid_ball"),
    log:
        f"{RESULTS}/logs/rigid_ball.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=900,  # measured peak RSS 477 MB
        runtime=5,
    shell:
        "python -m vidsim.cli.rigid_ball rigid.paths.video={input.video} paths.out={params.out} {params.extra} > {log} 2>&1"
