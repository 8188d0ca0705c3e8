#!/usr/bin/env bash
# Runs the benchmarks and writes BENCHMARKS.md. The benchmark suite arrives
# with the performance work; until then this reports that there is none.
set -euo pipefail
BUILD_DIR=${1:-build}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
shopt -s nullglob
benches=("$ROOT/$BUILD_DIR"/bench/*)
if [ ${#benches[@]} -eq 0 ]; then
  echo "bench: no benchmarks are built yet" >&2
  exit 0
fi
for b in "${benches[@]}"; do "$b"; done
