# vidsim: the whole study as cached stages. Thin on purpose: what runs is in workflow/config/*.yaml
# (Snakemake config), how each stage runs is Hydra (conf/); rules live in workflow/rules/*.smk.
from snakemake.utils import min_version

min_version("9.0")


configfile: "workflow/config/quick.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/calibration.smk"
include: "workflow/rules/demo.smk"
include: "workflow/rules/rigid.smk"
include: "workflow/rules/cloth.smk"
include: "workflow/rules/fluid.smk"
include: "workflow/rules/posterior.smk"
include: "workflow/rules/gap.smk"
include: "workflow/rules/sweep.smk"


rule all:
    input:
        get_final_outputs,
    default_target: True
