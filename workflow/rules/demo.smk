# The foundation's demo: reality renders a short clip into a footage folder (truth kept beside it).

if stage_enabled("demo"):
    TARGETS["demo"] = [
        f"{RESULTS}/footage/{s}/{f}" for s in config["demo"]["scenes"] for f in ("meta.yaml", "contact_sheet.png")
    ]


import re

# the demo's footage folders: only the names listed (an unknown footage name, e.g. a PIV recording
# that is not imported, had fallen through to this rule and become a tumbling box)
DEMO_SCENES = [str(s) for s in (config.get("demo", {}) or {}).get("scenes", [])]


rule reality_demo:
    """Render a tumbling box over a textured wall; write the footage folder and its truth beside it."""
    wildcard_constraints:
        scene="|".join(re.escape(s) for s in DEMO_SCENES) or "(?!)",
    input:
        calib=f"{RESULTS}/calibration/{{scene}}/calibration.yaml",
    output:
        meta=f"{RESULTS}/footage/{{scene}}/meta.yaml",
        truth=f"{RESULTS}/footage/{{scene}}.truth.yaml",
        sheet=report(
            f"{RESULTS}/footage/{{scene}}/contact_sheet.png",
            caption="../report/footage_demo.rst",
            category="Footage",
            subcategory="{scene}",
        ),
        rrd=f"{RESULTS}/footage/{{scene}}.reality.rrd",
    params:
        conf=CONF_DEMO,
        out=get_out_dir,
        extra=stage_overrides("reality_demo"),
    log:
        f"{RESULTS}/logs/reality_{{scene}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # measured peak RSS 543 MB (pyrender/EGL)
        runtime=10,
    shell:
        "python -m vidsim.cli.reality_demo paths.calibration={input.calib} paths.out={params.out} {params.extra} > {log} 2>&1"
