#!/usr/bin/env bash
# Runs every libFuzzer harness of a PENUMBRA_FUZZ build for a bounded time, two at a time.
#
#   fuzz/run.sh BUILD_DIR [SECONDS] [HARNESS...]     (default 60 s each, every harness)
#
# Each harness fuzzes its corpus, which lives outside the repository and grows from run to run:
# ${PENUMBRA_FUZZ_CORPUS:-~/.cache/penumbra/fuzz}/NAME. It is seeded from fuzz/seeds/NAME, the
# kept crash inputs fuzz/regressions/NAME, the examples and the shared test data (../shared/data,
# or PENUMBRA_SHARED_DATA), read in place, never copied into the repository.
#
# A crash, leak, timeout or out-of-memory fails the run: the input is copied into
# fuzz/regressions/NAME/ (replayed by the test suite from then on; fix the bug, commit the file).
# The last line of each harness's log, with executions and coverage, is printed.
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$here")
build=${1:?usage: fuzz/run.sh BUILD_DIR [SECONDS] [HARNESS...]}
seconds=${2:-60}
shift $(( $# >= 2 ? 2 : 1 ))
harnesses=("$@")
if ((${#harnesses[@]} == 0)); then
  for bin in "$build"/fuzz/fuzz_*; do
    [ -x "$bin" ] && [[ $bin != *_replay ]] && harnesses+=("$(basename "$bin" | sed 's/^fuzz_//')")
  done
fi
((${#harnesses[@]})) || { echo "fuzz: no harnesses in $build/fuzz (configure with -DPENUMBRA_FUZZ=ON)" >&2; exit 2; }

shared=${PENUMBRA_SHARED_DATA:-$repo/../shared/data}
if [ ! -d "$shared" ]; then
  origin=$(git -C "$repo" remote get-url origin 2>/dev/null || true)
  [ -n "$origin" ] && [ -d "$origin/../shared/data" ] && shared="$origin/../shared/data"
fi
corpora=${PENUMBRA_FUZZ_CORPUS:-${XDG_CACHE_HOME:-$HOME/.cache}/penumbra/fuzz}
logs="$build/fuzz/logs"
mkdir -p "$logs"

# Extra seed directories per harness (read only; missing ones are skipped).
extra_seeds() {
  case "$1" in
    scene) echo "$repo/examples" ;;
    obj) echo "$repo/examples $shared/meshes" ;;
    gltf) echo "$shared/gltf" ;;
  esac
}

run_one() {
  local name=$1 bin="$build/fuzz/fuzz_$1" corpus="$corpora/$1" artifacts="$logs/$1-artifacts"
  mkdir -p "$corpus" "$artifacts"
  rm -f "$artifacts"/*
  local dirs=("$corpus" "$here/seeds/$name" "$here/regressions/$name")
  for d in $(extra_seeds "$name"); do [ -d "$d" ] && dirs+=("$d"); done
  # Text formats stay small; large seeds are read in part. The RSS limit is far above what any
  # reader needs for inputs of that size.
  "$bin" -max_total_time="$seconds" -timeout=60 -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 \
    -artifact_prefix="$artifacts/" "${dirs[@]}" >"$logs/$name.log" 2>&1
  local status=$?
  local found=("$artifacts"/*)
  if [ $status -ne 0 ] || [ -e "${found[0]}" ]; then
    mkdir -p "$here/regressions/$name"
    for f in "${found[@]}"; do [ -e "$f" ] && cp "$f" "$here/regressions/$name/"; done
    echo "fuzz: $name FAILED (exit $status); inputs kept in fuzz/regressions/$name/, log $logs/$name.log" >&2
    grep -m3 -E "ERROR|SUMMARY|==[0-9]+==" "$logs/$name.log" >&2
    return 1
  fi
  local done_line execs
  done_line=$(grep -E "^#[0-9]+[[:space:]]+DONE" "$logs/$name.log" | tail -1)
  execs=$(grep -m1 "stat::number_of_executed_units" "$logs/$name.log" | awk '{print $2}')
  echo "fuzz: $name ok, ${seconds}s, ${execs:-?} executions; ${done_line:-no DONE line}" >&2
}

export -f run_one extra_seeds
export build seconds here repo shared corpora logs
printf '%s\n' "${harnesses[@]}" | xargs -P 2 -I{} bash -c 'run_one "$@"' _ {}
