#!/usr/bin/env bash
# `make fuzz`: builds the libFuzzer harnesses of fuzz/ with clang (ASan +
# UBSan) into BUILD_DIR and runs each for SECONDS, one after the other,
# niced. Seeds: the bad-input catalogue's inputs (exported by the normal
# build's bad_inputs_driver) plus the growing corpus of earlier runs in
# BUILD_DIR/corpus. A crash, leak, timeout or out-of-memory input is saved
# as BUILD_DIR/findings/FUZZER-* and makes the script fail.
#   usage: scripts/fuzz.sh BUILD_DIR SECONDS NORMAL_BUILD_DIR [FUZZER...]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${1:-build-fuzz}
SECONDS_EACH=${2:-60}
NORMAL_BUILD=${3:-build}
shift 3 || true
FUZZERS=("$@")
if [ ${#FUZZERS[@]} -eq 0 ]; then FUZZERS=(scene_config points_csv scene_file dem sentinel1_xml); fi

# clang and its fuzzer runtime are needed only here: installed on demand.
if ! command -v clang++ >/dev/null ||
   ! compgen -G "/usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a" >/dev/null; then
  echo "fuzz: installing clang and libclang-rt-14-dev" >&2
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends clang libclang-rt-14-dev >/dev/null
fi

cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=clang \
  -DCMAKE_CXX_COMPILER=clang++ -DGISSAR_FUZZ=ON -DGISSAR_BUILD_TESTS=OFF \
  -DGISSAR_BUILD_BENCH=OFF >/dev/null
targets=()
for f in "${FUZZERS[@]}"; do targets+=(--target "fuzz_$f"); done
nice -n 19 cmake --build "$BUILD_DIR" -j"${JOBS:-1}" "${targets[@]}"

seeds="$BUILD_DIR/seeds"
rm -rf "$seeds"
"$NORMAL_BUILD/tests/bad_inputs_driver" --catalogue tests/bad_inputs/cases --export-seeds "$seeds"
# Sentinel-1 XML: the bundled annotations, calibration and noise files
# (libFuzzer reads the first -max_len bytes of each, so these are truncated)
# and small valid documents (fuzz/seeds/sentinel1_xml/).
mkdir -p "$seeds/sentinel1_xml"
find data/sentinel1 -name '*.xml' -exec cp {} "$seeds/sentinel1_xml/" \;
cp fuzz/seeds/sentinel1_xml/*.xml "$seeds/sentinel1_xml/"  # small valid documents (whole within -max_len)

export ASAN_OPTIONS="detect_leaks=1"
export LSAN_OPTIONS="suppressions=$PWD/scripts/sanitizer/lsan.supp"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
mkdir -p "$BUILD_DIR/findings"
status=0
for f in "${FUZZERS[@]}"; do
  corpus="$BUILD_DIR/corpus/$f"
  mkdir -p "$corpus"
  echo "fuzz: $f for ${SECONDS_EACH} s" >&2
  if ! nice -n 19 "$BUILD_DIR/fuzz/fuzz_$f" -max_total_time="$SECONDS_EACH" -timeout=20 \
       -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 \
       -artifact_prefix="$BUILD_DIR/findings/$f-" "$corpus" "$seeds/$f" \
       2>"$BUILD_DIR/fuzz_$f.log"; then
    echo "fuzz: $f found a problem: see $BUILD_DIR/fuzz_$f.log and $BUILD_DIR/findings/" >&2
    status=1
  fi
  grep -E "^stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb)|^#[0-9]+ +DONE" \
    "$BUILD_DIR/fuzz_$f.log" >&2 || true
  echo "fuzz: $f corpus $(find "$corpus" -type f | wc -l) files" >&2
done
exit $status
