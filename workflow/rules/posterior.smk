# Posteriors (issue 6): how sure each estimate is. What runs: `posterior:` in the Snakemake config
# (rigid_cases = names of `rigid: cases:` whose fit gets a posterior, or "all"; cloth_cases = fabrics
# or twins (names of `cloth: fabrics:`/`cloth: twins:`) whose selection gets a posterior, or "all";
# hydra = Hydra overrides of the family, e.g. "posterior=quick"); how: Hydra (`posterior.*`;
# per-rule `overrides: {posterior_rigid: ..., posterior_cloth: ...}`).
# Layout: {RESULTS}/posterior/rigid/{case}/{summary.csv,posterior.yaml,corner.png,correlation.png,
# chain.npz,posterior.rrd}; {RESULTS}/posterior/cloth/{fabric}/{summary.csv,posterior.yaml,corner.png,
# correlation.png,check.png,chain.npz,evals.jsonl}. Needs the rigid family's fit
# (workflow/rules/rigid.smk) and the cloth family's fits and selection (workflow/rules/cloth.smk).
POSTERIOR = config.get("posterior", {}) or {}
_rc = POSTERIOR.get("rigid_cases", []) or []
POSTERIOR_RIGID_CASES = list(RIGID_CASES) if _rc == "all" else [c for c in _rc if c in RIGID_CASES]
_cc = POSTERIOR.get("cloth_cases", []) or []
_cloth_all = list(CLOTH_FABRICS) + [t for t in CLOTH_TWINS if t not in CLOTH_FABRICS]
POSTERIOR_CLOTH_CASES = _cloth_all if _cc == "all" else [c for c in _cc if c in _cloth_all]
POSTERIOR_HYDRA = str(POSTERIOR.get("hydra", "") or "")
# Table 1 with intervals: the fabrics (not twins) that have a posterior, in study order
POSTERIOR_TABLE1_FABRICS = [f for f in CLOTH_FABRICS if f in POSTERIOR_CLOTH_CASES]


if stage_enabled("posterior"):
    TARGETS["posterior"] = []
    if stage_enabled("rigid"):
        TARGETS["posterior"] += [
            f"{RESULTS}/posterior/rigid/{c}/{f}" for c in POSTERIOR_RIGID_CASES for f in ("summary.csv", "corner.png")
        ]
    if stage_enabled("cloth"):
        TARGETS["posterior"] += [
            f"{RESULTS}/posterior/cloth/{c}/{f}" for c in POSTERIOR_CLOTH_CASES for f in ("summary.csv", "check.png")
        ]
        if POSTERIOR_TABLE1_FABRICS:
            TARGETS["posterior"] += [f"{RESULTS}/posterior/cloth/table1/table1_intervals.png"]


rule posterior_rigid:
    """emcee posterior of a rigid fit: sandwich-calibrated silhouette likelihood, 50-tau convergence check."""
    input:
        meta=rigid_meta,
        fit=f"{RESULTS}/rigid/{{case}}/fit.yaml",
        masks=f"{RESULTS}/rigid/{{case}}/masks.npz",
    output:
        summary=report(
            f"{RESULTS}/posterior/rigid/{{case}}/summary.csv",
            caption="../report/posterior_rigid_summary.rst",
            category="Posteriors",
            subcategory="{case}",
        ),
        corner=report(
            f"{RESULTS}/posterior/rigid/{{case}}/corner.png",
            caption="../report/posterior_rigid_corner.rst",
            category="Posteriors",
            subcategory="{case}",
        ),
        corr=report(
            f"{RESULTS}/posterior/rigid/{{case}}/correlation.png",
            caption="../report/posterior_rigid_correlation.rst",
            category="Posteriors",
            subcategory="{case}",
        ),
        diagnostics=f"{RESULTS}/posterior/rigid/{{case}}/posterior.yaml",
        chain=f"{RESULTS}/posterior/rigid/{{case}}/chain.npz",
        rrd=f"{RESULTS}/posterior/rigid/{{case}}/posterior.rrd",
    params:
        conf=CONF_POSTERIOR,
        out=get_out_dir,
        footage=rigid_footage_dir,
        family=POSTERIOR_HYDRA,
        extra=stage_overrides("posterior_rigid"),
    log:
        f"{RESULTS}/logs/posterior_rigid_{{case}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1500,  # measured peak RSS 781 MB (throw101, posterior=quick, 640x480, 40 frames)
        runtime=30,
    shell:
        "python -m vidsim.cli.posterior_rigid paths.footage={params.footage} posterior.paths.fit={input.fit} "
        "posterior.paths.masks={input.masks} paths.out={params.out} {params.family} {params.extra} > {log} 2>&1"


rule posterior_cloth:
    """Cloth posterior of one fabric's selection: sandwich-calibrated E1+E2 likelihood on a GP surrogate, checked at 50 draws."""
    input:
        params=f"{RESULTS}/cloth/select/{{fabric}}/params.yaml",
        fits=expand(f"{RESULTS}/cloth/fit/{{{{fabric}}}}_{{trial}}/fit.yaml", trial=CLOTH_FIT_TRIALS),
        metas=expand(f"{RESULTS}/footage/cloth_{{{{fabric}}}}_{{trial}}/meta.yaml", trial=CLOTH_FIT_TRIALS),
    output:
        summary=report(
            f"{RESULTS}/posterior/cloth/{{fabric}}/summary.csv",
            caption="../report/posterior_cloth_summary.rst",
            category="Posteriors",
            subcategory="cloth {fabric}",
        ),
        corner=report(
            f"{RESULTS}/posterior/cloth/{{fabric}}/corner.png",
            caption="../report/posterior_cloth_corner.rst",
            category="Posteriors",
            subcategory="cloth {fabric}",
        ),
        corr=report(
            f"{RESULTS}/posterior/cloth/{{fabric}}/correlation.png",
            caption="../report/posterior_cloth_correlation.rst",
            category="Posteriors",
            subcategory="cloth {fabric}",
        ),
        check=report(
            f"{RESULTS}/posterior/cloth/{{fabric}}/check.png",
            caption="../report/posterior_cloth_check.rst",
            category="Posteriors",
            subcategory="cloth {fabric}",
        ),
        diagnostics=f"{RESULTS}/posterior/cloth/{{fabric}}/posterior.yaml",
        chain=f"{RESULTS}/posterior/cloth/{{fabric}}/chain.npz",
    params:
        conf=CONF_POSTERIOR,
        out=get_out_dir,
        inputs=posterior_cloth_inputs,
        base=STAGE_BASE,
        cloth=CLOTH_HYDRA,
        fabric=cloth_fabric_overrides,
        family=POSTERIOR_HYDRA,
        extra=stage_own("posterior_cloth"),
    log:
        f"{RESULTS}/logs/posterior_cloth_{{fabric}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/posterior_cloth_{{fabric}}.tsv"
    conda:
        CONDA_ENV
    resources:
        mem_mb=1500,  # measured peak RSS 392 MB (quick twin, 5 parameters), 587 MB (default: 20x20, 9 parameters)
        runtime=30,  # measured 2.1 CPU-min (quick twin), 15.4 CPU-min (default setting, no annealing cache)
    shell:
        "python -m vidsim.cli.posterior_cloth paths.out={params.out} {params.inputs} "
        "{params.base} {params.cloth} {params.fabric} {params.family} {params.extra} > {log} 2>&1"


rule table1_cloth:
    """Table 1 with a 90 % posterior interval per parameter: every fabric's selection beside its posterior."""
    input:
        params=expand(f"{RESULTS}/cloth/select/{{fabric}}/params.yaml", fabric=POSTERIOR_TABLE1_FABRICS),
        summaries=expand(f"{RESULTS}/posterior/cloth/{{fabric}}/summary.csv", fabric=POSTERIOR_TABLE1_FABRICS),
    output:
        csv=report(
            f"{RESULTS}/posterior/cloth/table1/table1_intervals.csv",
            caption="../report/posterior_cloth_table1.rst",
            category="Posteriors",
            subcategory="cloth Table 1",
        ),
        png=report(
            f"{RESULTS}/posterior/cloth/table1/table1_intervals.png",
            caption="../report/posterior_cloth_table1.rst",
            category="Posteriors",
            subcategory="cloth Table 1",
        ),
    params:
        conf=CONF_POSTERIOR,
        out=get_out_dir,
        inputs=table1_cloth_inputs,
        extra=stage_overrides("table1_cloth"),
    log:
        f"{RESULTS}/logs/table1_cloth.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # with ~170 MB for the job step's own Snakemake process
        runtime=5,
    shell:
        "python -m vidsim.cli.cloth_table1 paths.out={params.out} {params.inputs} {params.extra} > {log} 2>&1"
