# A Snakemake-level parameter study over a table (Paramspace): each row of the table is one point,
# run as its own cached job. Worked example: how calibration accuracy depends on sensor noise and
# the number of target views (workflow/config/sweeps/calibration_noise.tsv). Add rows or columns
# (any Hydra key, written with "__" for "." since column names become wildcard names:
# calibrate__n_views is calibrate.n_views) and rerun: only the new points run.
import pandas as pd
from snakemake.utils import Paramspace

SWEEP_CFG = config.get("sweep_calibration", {})
_SWEEP_TABLE = pd.read_csv(SWEEP_CFG.get("table", "workflow/config/sweeps/calibration_noise.tsv"), sep="\t")
CALIB_SPACE = Paramspace(
    _SWEEP_TABLE,
    filename_params="*",
    param_sep="-",  # Hydra's override grammar does not take "~" (Paramspace's default) in a path
)
# the plot's x axis and curves: `x:` and `group:` in the config (default: the table's first and
# second columns), checked here so that a table without them fails before any point runs
SWEEP_X = SWEEP_CFG.get("x", _SWEEP_TABLE.columns[0])
SWEEP_GROUP = SWEEP_CFG.get("group", _SWEEP_TABLE.columns[1] if len(_SWEEP_TABLE.columns) > 1 else "")
for _k, _v in (("x", SWEEP_X), ("group", SWEEP_GROUP)):
    if _v and _v not in _SWEEP_TABLE.columns:
        raise ValueError(f"sweep_calibration.{_k} = {_v!r} is not a column of the sweep table "
                         f"{SWEEP_CFG.get('table', 'workflow/config/sweeps/calibration_noise.tsv')} "
                         f"(columns: {list(_SWEEP_TABLE.columns)})")
_q = SWEEP_CFG.get("quantities", ["rms_px", "camera_fx", "camera_scene_reprojection_px_median"])
SWEEP_QUANTITIES = " ".join([_q] if isinstance(_q, str) else [str(x) for x in _q])

if stage_enabled("sweep_calibration"):
    TARGETS["sweep_calibration"] = [f"{RESULTS}/sweeps/calibration/sweep.csv", f"{RESULTS}/sweeps/calibration/sweep.png"]


rule calibrate_sweep_point:
    """One point of the calibration sweep: the calibrate stage with the row's values as Hydra overrides."""
    output:
        summary=f"{RESULTS}/sweeps/calibration/points/{CALIB_SPACE.wildcard_pattern}/summary.csv",
    params:
        conf=CONF_CALIBRATION,
        out=get_out_dir,
        point=paramspace_overrides(CALIB_SPACE),
        extra=stage_overrides("calibrate_sweep_point"),
    log:
        f"{RESULTS}/logs/sweep_calibration/{CALIB_SPACE.wildcard_pattern}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # measured peak RSS 287 MB, and ~170 MB for the job step's own Snakemake process
        runtime=5,
    shell:
        "python -m vidsim.cli.calibrate {params.point} paths.out={params.out} {params.extra} > {log} 2>&1"


rule collect_calibration_sweep:
    """Gather the points of the calibration sweep into one table and one plot."""
    input:
        table=SWEEP_CFG.get("table", "workflow/config/sweeps/calibration_noise.tsv"),
        points=expand(f"{RESULTS}/sweeps/calibration/points/{{p}}/summary.csv", p=CALIB_SPACE.instance_patterns),
    output:
        csv=f"{RESULTS}/sweeps/calibration/sweep.csv",
        png=report(f"{RESULTS}/sweeps/calibration/sweep.png", caption="../report/sweep_calibration.rst", category="Sweeps"),
    params:
        conf=CONF_CALIBRATION,
        points=sweep_point_dirs,
        out=get_out_dir,
        x=SWEEP_X,
        group=f"--group {SWEEP_GROUP}" if SWEEP_GROUP else "",
        quantities=SWEEP_QUANTITIES,
    log:
        f"{RESULTS}/logs/sweep_calibration/collect.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # with ~170 MB for the job step's own Snakemake process
        runtime=5,
    shell:
        "python -m vidsim.report.sweep --table {input.table} --points {params.points} --out {params.out} "
        "--x {params.x} {params.group} --quantities {params.quantities} > {log} 2>&1"
