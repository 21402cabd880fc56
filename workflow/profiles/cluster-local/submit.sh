#!/usr/bin/env bash
# A stand-in for `sbatch`: run the job script Snakemake hands us as a detached process and print a job id.
set -euo pipefail
jobscript="$1"
logdir="${VIDSIM_CLUSTER_LOGS:-.snakemake/cluster-local}"
mkdir -p "$logdir"
nohup bash "$jobscript" > "$logdir/$(basename "$jobscript").out" 2>&1 &
echo "$!"
