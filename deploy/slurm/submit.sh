#!/bin/sh
# Submits the shards and the gather after them. PIPELINE, SHARED (a shared file system path),
# OUTPUT and CROWD are passed on to the jobs (sbatch exports the environment by default).
#   PIPELINE=$PWD/pipeline.ron SHARED=$PWD/shared OUTPUT=$PWD/build/city \
#   CROWD=$PWD/target/release/crowd deploy/slurm/submit.sh
set -eu
here="$(cd "$(dirname "$0")" && pwd)"
export DEPLOY="$here/.."
array=$(sbatch --parsable "$here/shards.sbatch")
sbatch --dependency=afterok:"$array" "$here/gather.sbatch"
