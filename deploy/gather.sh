#!/bin/sh
# The gather of a sharded crowd build: every shard's files from "$SHARED/shards", then stages 4
# to 6 put together and stages 7-8 and the check (taking what the shards judged of it), into
# OUTPUT: the bytes one process would write.
#
#   PIPELINE  the pipeline file
#   SHARED    the folder the shards wrote to
#   OUTPUT    the build folder to write
#   CROWD     the crowd binary (default: crowd on the PATH)
#   MAX_MEMORY bytes the build may take (`--max-memory`; default: the machine's)
set -eu
: "${PIPELINE:?set PIPELINE to the pipeline file}"
: "${SHARED:?set SHARED to the folder the shards wrote to}"
: "${OUTPUT:?set OUTPUT to the build folder to write}"
crowd="${CROWD:-crowd}"
if ! ls "$SHARED"/shards/*-of-*.ron >/dev/null 2>&1; then
  echo "gather.sh: no shard files in $SHARED/shards: run deploy/shard.sh for every shard first" >&2
  exit 1
fi
mkdir -p "$OUTPUT/shards"
# Stages 1-3 as shard 0 made them, where it left them (checked again, not trusted).
if [ -d "$SHARED/stages" ]; then
  cp "$SHARED"/stages/* "$OUTPUT/"
fi
cp "$SHARED"/shards/*-of-*.bin "$SHARED"/shards/*-of-*.ron "$OUTPUT/shards/"
# What the shards judged of the check, taken by the gather's check instead of judged again.
for f in "$SHARED"/shards/check-*-of-*.memo; do
  if [ -f "$f" ]; then cp "$f" "$OUTPUT/shards/"; fi
done
set -- build --quiet --pipeline "$PIPELINE" --output "$OUTPUT" --gather
if [ -n "${MAX_MEMORY:-}" ]; then set -- "$@" --max-memory "$MAX_MEMORY"; fi
"$crowd" "$@"
echo "gathered -> $OUTPUT"
