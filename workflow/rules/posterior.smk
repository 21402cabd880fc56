# Posteriors (issue 6): how sure each estimate is. What runs: `posterior:` in the Snakemake config
# (rigid_cases = names of `rigid: cases:` whose fit gets a posterior, or "all"; hydra = Hydra
# overrides of the family, e.g. "posterior=quick"); how: Hydra (`posterior.*`;
# per-rule `overrides: {posterior_rigid: ...}`, e.g. posterior=quick for short chains).
# Layout: {RESULTS}/posterior/rigid/{case}/{summary.csv,posterior.yaml,corner.png,correlation.png,
# chain.npz,posterior.rrd}. Needs the rigid family's fit (workflow/rules/rigid.smk).
POSTERIOR = config.get("posterior", {}) or {}
_rc = POSTERIOR.get("rigid_cases", []) or []
POSTERIOR_RIGID_CASES = list(RIGID_CASES) if _rc == "all" else [c for c in _rc if c in RIGID_CASES]
POSTERIOR_HYDRA = str(POSTERIOR.get("hydra", "") or "")


if stage_enabled("posterior") and stage_enabled("rigid"):
    TARGETS["posterior"] = [
        f"{RESULTS}/posterior/rigid/{c}/{f}" for c in POSTERIOR_RIGID_CASES for f in ("summary.csv", "corner.png")
    ]


rule posterior_rigid:
    """emcee posterior of a rigid fit: sandwich-calibrated silhouette likelihood, 50-tau convergence check."""
    input:
        meta=f"{RESULTS}/footage/rigid_{{case}}/meta.yaml",
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
