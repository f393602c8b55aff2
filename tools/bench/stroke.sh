#!/bin/sh
# The benchmark behind BENCHMARKS.md's brush-stroke figures (issue 20): `painting` per m2, one
# brush stroke (a disc of radius 5 px at 324,396 on its density layer, `crowd-paintings
# stroke`), rebuilt from a copy of the folder built before it; with several binaries, each run
# in turn on a base it built itself (a base from another binary whose stage versions differ
# would be rebuilt whole, not by the stroke), RUNS times. Prints each run's wall time, peak
# memory and stage seconds (from timings.ron).
#
#   WORK   an empty folder (a base build per binary, about 0.7 GB each, and the runs' copies)
#   RUNS   how many runs of each binary (default 3)
#   then the crowd binaries to compare (default: target/release/crowd)
#
#   WORK=/tmp/stroke tools/bench/stroke.sh old/crowd target/release/crowd
set -eu
: "${WORK:?set WORK to an empty folder}"
. "$(dirname "$0")/common.sh"
. "$(dirname "$0")/binaries.sh"
paint="$here/target/release/crowd-paintings"
[ -x "$paint" ] || { echo "stroke.sh: build crowd-paintings first (cargo build --release)" >&2; exit 1; }
mkdir -p "$WORK"
cd "$WORK"
cat > p.ron <<'RON'
(
    scene: (meters_per_pixel: 1.0, layers: [(kind: Density, path: "density.png")]),
    people: PerSquareMetre(walkers: 0.5, standers: 0.0),
    patch_side_m: 8.0,
    period_s: 20.0,
    radius_m: 0.3,
    seed: 1,
    optimize: (region_patches: Some(16)),
    output: "out",
    export: (gltf_region: Some((400.0, 240.0, 560.0, 400.0))),
)
RON
if [ ! -f after.png ]; then
  cp "$here/../shared/scenes/painting/density.png" before.png
  cp before.png after.png
  "$paint" stroke --layer after.png --at 324,396 --radius 5
fi
# The base folder of binary $1.
base() {
  echo "base-$(label "$1" | tr / -)"
}
for crowd in "$@"; do
  [ -d "$(base "$crowd")" ] && continue
  cp before.png density.png
  rm -rf out
  echo "stroke.sh: building $(base "$crowd") (painting from nothing)" >&2
  "$crowd" build -q --pipeline p.ron >/dev/null 2>build.log
  mv out "$(base "$crowd")"
done
for run in $(seq "${RUNS:-3}"); do
  for crowd in "$@"; do
    rm -rf out && cp -a "$(base "$crowd")" out && cp after.png density.png && sync
    /usr/bin/time -f "%e %M" -o time.txt "$crowd" build -q --pipeline p.ron >/dev/null 2>build.log
    cp before.png density.png
    read -r wall kb < time.txt
    echo "$(label "$crowd") run $run: ${wall} s, $((kb / 1024)) MB; $(stage_seconds out)"
  done
done
