# Camera (and projector) calibration: the real chessboard set and synthetic scene targets.
import re

if stage_enabled("calibration_chessboard") and shared_available("opencv_chessboard"):
    TARGETS["calibration_chessboard"] = [f"{RESULTS}/calibration/chessboard/calibration.yaml"]


rule calibrate_chessboard:
    """Calibrate the left camera of OpenCV's real chessboard set; compare with OpenCV's reference."""
    input:
        images=SHARED / "opencv_chessboard",
    output:
        calib=f"{RESULTS}/calibration/chessboard/calibration.yaml",
        summary=report(
            f"{RESULTS}/calibration/chessboard/summary.csv",
            caption="../report/calibration_chessboard.rst",
            category="Calibration",
        ),
        plot=report(
            f"{RESULTS}/calibration/chessboard/reprojection.png",
            caption="../report/calibration_chessboard.rst",
            category="Calibration",
        ),
    params:
        conf=CONF_CALIBRATION,
        out=get_out_dir,
        extra=stage_overrides("calibrate_chessboard"),
    log:
        f"{RESULTS}/logs/calibrate_chessboard.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=1000,  # measured peak RSS 176 MB, and ~170 MB for the job step's own Snakemake process
        runtime=10,
    shell:
        "python -m vidsim.cli.calibrate_real paths.footage={input.images} paths.out={params.out} {params.extra} > {log} 2>&1"


rule calibrate_scene:
    """Film a calibration target with the scene's camera (and projector) and calibrate from the images."""
    wildcard_constraints:
        # the demo's scenes only (the cloth studio has its own rule, calibrate_cloth_scene); another
        # name had matched and been calibrated as the demo scene
        scene="|".join(re.escape(str(s)) for s in (config.get("demo", {}) or {}).get("scenes", [])) or "(?!)",
    output:
        calib=f"{RESULTS}/calibration/{{scene}}/calibration.yaml",
        summary=report(
            f"{RESULTS}/calibration/{{scene}}/summary.csv",
            caption="../report/calibration_scene.rst",
            category="Calibration",
            subcategory="{scene}",
        ),
        rrd=f"{RESULTS}/calibration/{{scene}}/calibrate.rrd",
    params:
        conf=CONF_CALIBRATION,
        out=get_out_dir,
        extra=stage_overrides("calibrate_scene"),
    log:
        f"{RESULTS}/logs/calibrate_{{scene}}.log",
    conda:
        CONDA_ENV
    resources:
        mem_mb=800,  # measured peak RSS 287 MB (camera only; with the projector ~+100 MB)
        runtime=10,
    shell:
        "python -m vidsim.cli.calibrate paths.out={params.out} {params.extra} > {log} 2>&1"
