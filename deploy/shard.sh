#!/bin/sh
# One shard of a crowd build, on any job runner, in two steps (each an array job of its own):
#   STEP=regions  this shard's run of stage 3's regions (stages 1-2 first), its files copied to
#                 "$SHARED/shards" (`optimize-I-of-N`): so that no shard solves stage 3 whole;
#   STEP=patches  (the default) stages 1-3, taking every region from the region files in
#                 "$SHARED/shards" (any missing is solved here), then this shard's patches of
#                 stages 4-6, copied to "$SHARED/shards" (a volume, or a folder the runner
#                 uploads). Without a regions step first every shard solves stage 3 whole.
#
#   PIPELINE  the pipeline file (its layers beside it, as on a workstation)
#   SHARDS    how many shards the build is split into
#   SHARED    the folder every shard's files go to and the gather reads
#   the shard's index, from the first of these that is set:
#     SHARD_INDEX            (given by hand, or by a CI matrix)
#     JOB_COMPLETION_INDEX   (a Kubernetes Indexed Job)
#     SLURM_ARRAY_TASK_ID    (a Slurm array job)
#   STEP      regions or patches (default)
#   CROWD     the crowd binary (default: crowd on the PATH)
#   WORK      scratch space for this shard's build folder (default: a temporary folder)
#   MAX_MEMORY bytes the build may take (`--max-memory`; default: the machine's): a shard is
#             held to its own estimate (its part of the world), not the one-process build's
set -eu
: "${PIPELINE:?set PIPELINE to the pipeline file}"
: "${SHARDS:?set SHARDS to the number of shards}"
: "${SHARED:?set SHARED to the folder the shards write to}"
index="${SHARD_INDEX:-${JOB_COMPLETION_INDEX:-${SLURM_ARRAY_TASK_ID:-}}}"
if [ -z "$index" ]; then
  echo "shard.sh: no shard index: set SHARD_INDEX, or run as a Kubernetes Indexed Job" \
    "(JOB_COMPLETION_INDEX) or a Slurm array task (SLURM_ARRAY_TASK_ID)" >&2
  exit 2
fi
crowd="${CROWD:-crowd}"
work="${WORK:-$(mktemp -d)}"
step="${STEP:-patches}"
out="$work/shard-$index"
set -- build --quiet --pipeline "$PIPELINE" --output "$out" --shard "$index/$SHARDS"
case "$step" in
  regions)
    set -- "$@" --until optimize
    mine="optimize-$index-of-$SHARDS" ;;
  patches)
    # Every shard's regions, where the regions step left them.
    mkdir -p "$out/shards"
    for f in "$SHARED"/shards/optimize-*-of-"$SHARDS".*; do
      if [ -f "$f" ]; then cp "$f" "$out/shards/"; fi
    done
    mine="*-$index-of-$SHARDS" ;;
  *)
    echo "shard.sh: STEP is regions or patches, not $step" >&2
    exit 2 ;;
esac
if [ -n "${MAX_MEMORY:-}" ]; then set -- "$@" --max-memory "$MAX_MEMORY"; fi
"$crowd" "$@"
mkdir -p "$SHARED/shards"
# Side file first, then the file that names it: a gather never reads a half-copied shard as whole.
# The patches step also leaves its share of the check (`check-I-of-N.memo`, a cache).
for f in "$out"/shards/$mine.bin "$out"/shards/$mine.memo "$out"/shards/$mine.ron; do
  [ -f "$f" ] || continue
  name="$(basename "$f")"
  case "$step-$name" in patches-optimize-*) continue ;; esac
  cp "$f" "$SHARED/shards/.$name.part"
  mv "$SHARED/shards/.$name.part" "$SHARED/shards/$name"
done
if [ "$step" = regions ]; then
  echo "shard $index/$SHARDS regions -> $SHARED/shards"
  exit 0
fi
# Shard 0 also leaves its stage 1-3 files (the same in every shard) for the gather, which then
# need not make them again (it checks them against its inputs, and remakes any that differ).
if [ "$index" = 0 ]; then
  mkdir -p "$SHARED/stages"
  for f in "$out"/*; do
    name="$(basename "$f")"
    [ -f "$f" ] && [ "$name" != timings.ron ] || continue
    cp "$f" "$SHARED/stages/.$name.part"
    mv "$SHARED/stages/.$name.part" "$SHARED/stages/$name"
  done
fi
echo "shard $index/$SHARDS -> $SHARED/shards"
