# Fluids edited from video (seed section 5; issue 8). What runs is the `fluid:` section of the
# Snakemake config: synthetic scenes, real PIV recordings, and edits (YAML files, format in
# docs/fluid_editing.md). How each stage runs is Hydra's `fluid` group (conf/fluid/).
#
#   reality_fluid / fluid_piv_footage -> footage/{fluid_<scene>,piv_<name>}/
#   fluid_flow -> fluid/flow/<footage>/ ; fluid_middlebury -> fluid/middlebury/
#   fluid_edit -> fluid/edit/<footage>/<edit>/ ; fluid_metrics -> fluid/metrics/metrics.csv
import yaml as _fluid_yaml

FLUID = config.get("fluid", {}) or {}
FLUID_SCENES = list(FLUID.get("scenes", []))
_PIV_KNOWN = ("karman", "jet")  # the PIVlab recordings fluid_piv_footage imports
for _p in FLUID.get("piv", []) or []:
    if _p not in _PIV_KNOWN:
        raise ValueError(f"fluid.piv: unknown PIV recording {_p!r}: expected one of {list(_PIV_KNOWN)}")
FLUID_PIV = [p for p in FLUID.get("piv", []) if shared_available(f"pivlab_{p}")]
FLUID_MIDDLEBURY = shared_available("middlebury_flow")
FLUID_EDIT_DIR = FLUID.get("edit_dir", "docs/fluid_edits")
FLUID_FRAMES = int(FLUID.get("frames", 120))
FLUID_RENDER_FRAMES = int(FLUID.get("render_frames", 120))


# edit name -> footage folder under footage/, from each edit's `footage:` label read at parse time
# (synthetic:<scene> -> fluid_<scene>, piv:<name> -> piv_<name>; as vidsim.fluid.footage, inlined
# so that parsing the workflow needs no import of the package)
_FLUID_PREFIX = {"synthetic": "fluid_", "piv": "piv_"}
FLUID_EDITS = {}
for _e in FLUID.get("edits", []):
    with open(f"{FLUID_EDIT_DIR}/{_e}.yaml") as _fh:
        _kind, _, _name = str((_fluid_yaml.safe_load(_fh) or {}).get("footage", "")).partition(":")
    if _kind not in _FLUID_PREFIX or not _name:
        raise ValueError(f"{FLUID_EDIT_DIR}/{_e}.yaml: footage must be 'synthetic:<scene>' or 'piv:<name>'")
    if _kind == "piv" and _name not in FLUID_PIV:
        continue  # its real recording is absent (shared_available warned)
    FLUID_EDITS[_e] = f"{_FLUID_PREFIX[_kind]}{_name}"
FLUID_FOOTAGE = [f"fluid_{s}" for s in FLUID_SCENES] + [f"piv_{p}" for p in FLUID_PIV]
FLUID_SUMMARIES = (
    ([f"{RESULTS}/fluid/middlebury/summary.json"] if FLUID_MIDDLEBURY else [])
    + [f"{RESULTS}/fluid/flow/{f}/summary.json" for f in FLUID_FOOTAGE]
    + [f"{RESULTS}/fluid/edit/{f}/{e}/summary.json" for e, f in FLUID_EDITS.items()]
)

if stage_enabled("fluid"):
    TARGETS["fluid"] = (
        [f"{RESULTS}/fluid/metrics/metrics.csv"]
        + ([f"{RESULTS}/fluid/middlebury/middlebury.png"] if FLUID_MIDDLEBURY else [])
        + [f"{RESULTS}/footage/{f}/contact_sheet.png" for f in FLUID_FOOTAGE]
        + [f"{RESULTS}/fluid/flow/{f}/{x}" for f in FLUID_FOOTAGE for x in ("flow.png", "flow.rrd")]
        + [
            f"{RESULTS}/fluid/edit/{f}/{e}/{x}"
            for e, f in FLUID_EDITS.items()
            for x in ("edit.mp4", "edit.gif", "arrows.png", "contact_sheet.png", "fluid.rrd")
        ]
    )


ruleorder: reality_fluid > reality_demo
ruleorder: fluid_piv_footage > reality_demo


rule reality_fluid:
    """Simulate a fluid scene (stable fluids with obstacles) and film it; true velocity beside."""
    output:
        meta=f"{RESULTS}/footage/fluid_{{scene}}/meta.yaml",
        truth=f"{RESULTS}/footage/fluid_{{scene}}.truth.yaml",
        truth_arrays=f"{RESULTS}/footage/fluid_{{scene}}.truth.npz",
        sheet=report(
            f"{RESULTS}/footage/fluid_{{scene}}/contact_sheet.png",
            caption="../report/fluid_footage.rst",
            category="Fluid",
            subcategory="footage",
        ),
        rrd=f"{RESULTS}/footage/fluid_{{scene}}.reality.rrd",
    wildcard_constraints:
        scene="[a-z_]+",
    params:
        conf=CONF_FLUID,
        out=get_out_dir,
        frames=FLUID_FRAMES,
        extra=stage_overrides("reality_fluid"),
    log:
        f"{RESULTS}/logs/reality_fluid_{{scene}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # measured peak RSS 420 MB (128x128, 120 frames)
        runtime=10,
    shell:
        "python -m vidsim.cli.reality_fluid fluid.reality.scene={wildcards.scene} fluid.reality.n_frames={params.frames} "
        "paths.out={params.out} {params.extra} > {log} 2>&1"


rule fluid_piv_footage:
    """Import a real PIV recording (PIVlab) as a footage folder, area-downsampled."""
    input:
        recording=f"{SHARED}/pivlab_{{name}}",
    output:
        meta=f"{RESULTS}/footage/piv_{{name}}/meta.yaml",
        sheet=report(
            f"{RESULTS}/footage/piv_{{name}}/contact_sheet.png",
            caption="../report/fluid_footage.rst",
            category="Fluid",
            subcategory="footage",
        ),
        rrd=f"{RESULTS}/footage/piv_{{name}}/footage.rrd",
    wildcard_constraints:
        name="|".join(_PIV_KNOWN),
    params:
        conf=CONF_FLUID,
        out=get_out_dir,
        extra=stage_overrides("fluid_piv_footage"),
    log:
        f"{RESULTS}/logs/fluid_piv_footage_{{name}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=800,  # measured peak RSS 322 MB (karman)
        runtime=5,
    shell:
        "python -m vidsim.cli.fluid_piv_footage fluid.piv.name={wildcards.name} paths.footage={input.recording} "
        "paths.out={params.out} {params.extra} > {log} 2>&1"


rule fluid_flow:
    """Optical flow of fluid footage; on synthetic footage scored against the true velocity."""
    input:
        meta=f"{RESULTS}/footage/{{footage}}/meta.yaml",
    output:
        flow=f"{RESULTS}/fluid/flow/{{footage}}/flow.npz",
        summary=f"{RESULTS}/fluid/flow/{{footage}}/summary.json",
        table=report(
            f"{RESULTS}/fluid/flow/{{footage}}/summary.csv",
            caption="../report/fluid_flow.rst",
            category="Fluid",
            subcategory="optical flow",
        ),
        fig=report(
            f"{RESULTS}/fluid/flow/{{footage}}/flow.png",
            caption="../report/fluid_flow.rst",
            category="Fluid",
            subcategory="optical flow",
        ),
        rrd=f"{RESULTS}/fluid/flow/{{footage}}/flow.rrd",
    params:
        conf=CONF_FLUID,
        out=get_out_dir,
        extra=stage_overrides("fluid_flow"),
    log:
        f"{RESULTS}/logs/fluid_flow_{{footage}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # measured peak RSS 404 MB (128x128, 120 frames, with the truth; PIV karman 296 MB)
        runtime=10,
    shell:
        "python -m vidsim.cli.fluid_flow paths.footage=$(dirname {input.meta}) paths.out={params.out} {params.extra} > {log} 2>&1"


rule fluid_middlebury:
    """Optical-flow accuracy on the real Middlebury scenes (average endpoint error vs ground truth)."""
    input:
        scenes=SHARED / "middlebury_flow",
    output:
        summary=f"{RESULTS}/fluid/middlebury/summary.json",
        table=report(
            f"{RESULTS}/fluid/middlebury/epe.csv",
            caption="../report/fluid_middlebury.rst",
            category="Fluid",
            subcategory="optical flow",
        ),
        fig=report(
            f"{RESULTS}/fluid/middlebury/middlebury.png",
            caption="../report/fluid_middlebury.rst",
            category="Fluid",
            subcategory="optical flow",
        ),
    params:
        conf=CONF_FLUID,
        out=get_out_dir,
        extra=stage_overrides("fluid_middlebury"),
    log:
        f"{RESULTS}/logs/fluid_middlebury.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # measured peak RSS 239 MB, and ~170 MB for the job step's own Snakemake process
        runtime=5,
    shell:
        "python -m vidsim.cli.fluid_middlebury paths.footage={input.scenes} paths.out={params.out} {params.extra} > {log} 2>&1"


rule fluid_edit:
    """A source-sink edit: optimise the edited field, render it by texture transfer, measure it."""
    input:
        spec=f"{FLUID_EDIT_DIR}/{{edit}}.yaml",
        meta=f"{RESULTS}/footage/{{footage}}/meta.yaml",
        flow=f"{RESULTS}/fluid/flow/{{footage}}/flow.npz",
    output:
        summary=f"{RESULTS}/fluid/edit/{{footage}}/{{edit}}/summary.json",
        table=report(
            f"{RESULTS}/fluid/edit/{{footage}}/{{edit}}/summary.csv",
            caption="../report/fluid_edit.rst",
            category="Fluid",
            subcategory="{edit}",
        ),
        video=report(
            f"{RESULTS}/fluid/edit/{{footage}}/{{edit}}/edit.mp4",
            caption="../report/fluid_edit.rst",
            category="Fluid",
            subcategory="{edit}",
        ),
        gif=report(
            f"{RESULTS}/fluid/edit/{{footage}}/{{edit}}/edit.gif",
            caption="../report/fluid_edit.rst",
            category="Fluid",
            subcategory="{edit}",
        ),
        arrows=report(
            f"{RESULTS}/fluid/edit/{{footage}}/{{edit}}/arrows.png",
            caption="../report/fluid_edit.rst",
            category="Fluid",
            subcategory="{edit}",
        ),
        sheet=report(
            f"{RESULTS}/fluid/edit/{{footage}}/{{edit}}/contact_sheet.png",
            caption="../report/fluid_edit.rst",
            category="Fluid",
            subcategory="{edit}",
        ),
        field=f"{RESULTS}/fluid/edit/{{footage}}/{{edit}}/field.npz",
        rrd=f"{RESULTS}/fluid/edit/{{footage}}/{{edit}}/fluid.rrd",
    params:
        conf=CONF_FLUID,
        out=get_out_dir,
        frames=FLUID_RENDER_FRAMES,
        extra=stage_overrides("fluid_edit"),
    log:
        f"{RESULTS}/logs/fluid_edit_{{footage}}_{{edit}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1300,  # measured peak RSS 561 MB (PIV edit, 256x190 output, 120 frames; synthetic 531 MB)
        runtime=15,
    shell:
        "python -m vidsim.cli.fluid_edit fluid.edit.spec={input.spec} paths.footage=$(dirname {input.meta}) "
        "fluid.edit.flow={input.flow} fluid.edit.frames={params.frames} paths.out={params.out} {params.extra} > {log} 2>&1"


rule fluid_metrics:
    """The fluid family's measured figures against the issue's targets, in one table."""
    input:
        summaries=FLUID_SUMMARIES,
    output:
        table=report(
            f"{RESULTS}/fluid/metrics/metrics.csv",
            caption="../report/fluid_metrics.rst",
            category="Fluid",
            subcategory="metrics",
        ),
    params:
        conf=CONF_FLUID,
        out=get_out_dir,
        inputs=f"[{','.join(FLUID_SUMMARIES)}]",
        extra=stage_overrides("fluid_metrics"),
    log:
        f"{RESULTS}/logs/fluid_metrics.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # measured peak RSS 128 MB, and ~170 MB for the job step's own Snakemake process
        runtime=5,
    shell:
        "python -m vidsim.cli.fluid_metrics 'fluid.inputs={params.inputs}' paths.out={params.out} {params.extra} > {log} 2>&1"
