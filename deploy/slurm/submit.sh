#!/bin/sh
# Submits the regions step, the shards after it and the gather after them. PIPELINE, SHARED (a
# shared file system path), OUTPUT and CROWD are passed on to the jobs (sbatch exports the
# environment by default).
#   PIPELINE=$PWD/pipeline.ron SHARED=$PWD/shared OUTPUT=$PWD/build/city \
#   CROWD=$PWD/target/release/crowd deploy/slurm/submit.sh
set -eu
here="$(cd "$(dirname "$0")" && pwd)"
export DEPLOY="$here/.."
regions=$(sbatch --parsable "$here/regions.sbatch")
array=$(sbatch --parsable --dependency=afterok:"$regions" "$here/shards.sbatch")
sbatch --dependency=afterok:"$array" "$here/gather.sbatch"
