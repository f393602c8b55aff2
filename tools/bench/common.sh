# What the benchmarks here share, sourced by each (`. "$(dirname "$0")/common.sh"`), not run:
# `here` (the repository), a check that GNU time is there, and helpers for the runs' lines.
here="$(cd "$(dirname "$0")/../.." && pwd)"
[ -x /usr/bin/time ] || { echo "$(basename "$0"): needs /usr/bin/time (GNU time)" >&2; exit 1; }

# The path $1 made absolute (the runs are made in WORK, not where the script was started).
absolute() {
  echo "$(cd "$(dirname "$1")" && pwd)/$(basename "$1")"
}

# The binary $1 as a run's line names it: its folder and its name.
label() {
  echo "$(basename "$(dirname "$1")")/$(basename "$1")"
}

# "stage=seconds ..." from the build folder $1's timings.ron.
stage_seconds() {
  sed -n 's/^ *"\([a-z]*\)": (/\1/p; s/^ *seconds: \([0-9.]*\),/\1/p' "$1/timings.ron" \
    | paste -d= - - | awk -F= '{printf "%s=%.2f ", $1, $2}'
}
