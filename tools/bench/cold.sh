#!/bin/sh
# The benchmark behind BENCHMARKS.md's "painting from nothing" figures (issue 20): a build of
# assets/pipelines/painting.ron into an empty folder, the page cache dropped first (needs
# root; without it the runs say so and go on warm), with several binaries, each run in turn,
# RUNS times. Prints each run's wall, user and system time, peak memory, page faults and stage
# seconds (from timings.ron).
#
#   WORK   an empty folder (each run's build, about 0.7 GB)
#   RUNS   how many runs of each binary (default 2)
#   then the crowd binaries to compare (default: target/release/crowd)
#
#   WORK=/tmp/cold tools/bench/cold.sh old/crowd target/release/crowd
set -eu
: "${WORK:?set WORK to an empty folder}"
. "$(dirname "$0")/common.sh"
. "$(dirname "$0")/binaries.sh"
mkdir -p "$WORK"
cd "$WORK"
# painting.ron with its layer's path made absolute and its output here.
sed -e "s#\"\.\./\.\./\.\./shared/#\"$here/../shared/#" -e 's#output: "[^"]*"#output: "out"#' \
  "$here/assets/pipelines/painting.ron" > p.ron
for run in $(seq "${RUNS:-2}"); do
  for crowd in "$@"; do
    rm -rf out && sync
    echo 3 2>/dev/null > /proc/sys/vm/drop_caches || echo "cold.sh: page cache not dropped (not root)" >&2
    /usr/bin/time -f "%e %U %S %M %R" -o time.txt "$crowd" build -q --pipeline p.ron >/dev/null 2>build.log
    read -r wall user sys kb faults < time.txt
    echo "$(date +%H:%M) $(label "$crowd") run $run: ${wall} s (user $user, system $sys)," \
      "$((kb / 1024)) MB, $faults page faults; $(stage_seconds out)"
  done
done
