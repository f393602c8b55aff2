#!/bin/sh
# The benchmark behind BENCHMARKS.md's sharded figures (issue 20): a sharded build on this one
# machine, AT_ONCE shards at a time, each through deploy/shard.sh as a job runner would run it
# (the regions step, then the patches step), then deploy/gather.sh; every run's wall time and
# peak memory from /usr/bin/time.
#
#   PIPELINE  the pipeline file (deploy/million.ron for "a million walkers")
#   SHARDS    how many shards (default 8)
#   AT_ONCE   how many run at a time (default 2, the cores here)
#   WORK      an empty folder for the shards' files and the gathered build
#   CROWD     the crowd binary (default: target/release/crowd)
#   STEPS     "regions patches" (default), or "patches" alone (every shard solves stage 3 whole)
#
#   PIPELINE=deploy/million.ron WORK=/tmp/million tools/bench/sharded.sh
set -eu
: "${PIPELINE:?set PIPELINE to the pipeline file}"
: "${WORK:?set WORK to an empty folder}"
shards="${SHARDS:-8}"
at_once="${AT_ONCE:-2}"
. "$(dirname "$0")/common.sh"
export CROWD="${CROWD:-$here/target/release/crowd}"
export PIPELINE SHARDS="$shards" SHARED="$WORK/shared"
mkdir -p "$WORK/shared" "$WORK/logs"
start=$(date +%s)
# Each shard in its own scratch folder, on one thread (rayon reads RAYON_NUM_THREADS when
# --threads is not given; AT_ONCE of them share the cores).
for step in ${STEPS:-regions patches}; do
  step_start=$(date +%s)
  seq 0 $((shards - 1)) | STEP="$step" xargs -P "$at_once" -I{} sh -c '
    log="$0/logs/$STEP-{}.log"
    SHARD_INDEX={} WORK="$0/shard-{}" RAYON_NUM_THREADS=1 \
      /usr/bin/time -f "$STEP {}: %e s, %M KB" "$1/deploy/shard.sh" > "$log" 2>&1 \
      || { cat "$log" >&2; exit 255; }
    tail -1 "$log"' "$WORK" "$here"
  echo "the $shards shards' $step step, $at_once at a time: $(( $(date +%s) - step_start )) s"
done
shards_s=$(( $(date +%s) - start ))
echo "the $shards shards, $at_once at a time: $shards_s s"
OUTPUT="$WORK/gathered" /usr/bin/time -f "gather: %e s, %M KB" "$here/deploy/gather.sh" \
  > "$WORK/logs/gather.log" 2>&1 || { cat "$WORK/logs/gather.log" >&2; exit 1; }
tail -1 "$WORK/logs/gather.log"
echo "all of it: $(( $(date +%s) - start )) s"
