# Sourced after common.sh by the benchmarks that compare crowd binaries (cold.sh, stroke.sh),
# not run: the script's arguments become the binaries to compare (the release build when none
# is given), each made absolute, as "$@" (the runs are made in WORK).
[ $# -gt 0 ] || set -- "$here/target/release/crowd"
for crowd in "$@"; do
  shift
  set -- "$@" "$(absolute "$crowd")"
done
