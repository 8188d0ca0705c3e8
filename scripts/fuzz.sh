#!/usr/bin/env bash
# `make fuzz`: builds the libFuzzer harnesses of fuzz/ with clang (ASan +
# UBSan) into BUILD_DIR and runs each for SECONDS, one after the other,
# niced. Seeds: the bad-input catalogue's inputs (exported by the normal
# build's bad_inputs_driver) plus the growing corpus of earlier runs in
# BUILD_DIR/corpus. A crash, leak, timeout or out-of-memory input is saved
# as BUILD_DIR/findings/FUZZER-* and makes the script fail. FUZZ_PARALLEL=N
# (default 1) runs N harnesses at a time.
#   usage: scripts/fuzz.sh BUILD_DIR SECONDS NORMAL_BUILD_DIR [FUZZER...]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${1:-build-fuzz}
SECONDS_EACH=${2:-60}
NORMAL_BUILD=${3:-build}
shift 3 || true
FUZZERS=("$@")
if [ ${#FUZZERS[@]} -eq 0 ]; then FUZZERS=(scene_config points_csv scene_file dem sentinel1_xml orbit radar_grid_json nisar_hdf5 reflectors_csv
  materials_json options_json)
fi

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
# The other readers: small valid documents (fuzz/seeds/NAME/), the real
# files of data/ and tests/data/, and the catalogue's inline files of their
# kind (exported above as scene_config/*.json and points_csv/*.csv).
for f in radar_grid_json options_json materials_json reflectors_csv nisar_hdf5; do
  mkdir -p "$seeds/$f"
  cp fuzz/seeds/$f/* "$seeds/$f/" 2>/dev/null || true
done
cp "$seeds"/scene_config/*.json "$seeds/radar_grid_json/"
cp "$seeds"/scene_config/*.json "$seeds/options_json/"
cp "$seeds"/scene_config/*.json "$seeds/materials_json/"
cp "$seeds"/points_csv/*.csv "$seeds/reflectors_csv/"
cp data/alos_rio_branco/*.csv "$seeds/reflectors_csv/"
# NISAR RSLC: the real products small enough to be read whole (-max_len
# below), the one of data/uavsar truncated.
cp data/alos_rio_branco/*.h5 data/uavsar/SanAnd_129.h5 tests/data/hostile_hdf5/*.h5 "$seeds/nisar_hdf5/"
# Orbits: the first byte picks the reader by content (0) or by extension
# (1 .csv, 2 .json, 3 .EOF, 4 .xml): each file with the byte of its format
# and with 0.
mkdir -p "$seeds/orbit"
orbit_seed() {  # FILE BYTE
  { printf "\\$(printf '%03o' "$2")"; cat "$1"; } >"$seeds/orbit/$2_$(basename "$1")"
  { printf '\000'; cat "$1"; } >"$seeds/orbit/0_$(basename "$1")"
}
for f in fuzz/seeds/orbit/*.csv "$seeds"/points_csv/*.csv; do orbit_seed "$f" 1; done
for f in fuzz/seeds/orbit/*.json; do orbit_seed "$f" 2; done
for f in tests/data/orbits/*.EOF; do orbit_seed "$f" 3; orbit_seed "$f" 4; done

export ASAN_OPTIONS="detect_leaks=1"
export LSAN_OPTIONS="suppressions=$PWD/scripts/sanitizer/lsan.supp"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
mkdir -p "$BUILD_DIR/findings"
status=0
run_one() {  # FUZZER: runs it, prints its figures; fails on a finding
  local f=$1 corpus="$BUILD_DIR/corpus/$1" max_len=65536 rc=0 asan="$ASAN_OPTIONS"
  # HDF5 products are larger than the text files. libhdf5 (not gissar's
  # code) allocates what a corrupt file's metadata declares (hundreds of GB
  # for a 14 KB file) and handles malloc's NULL as an error: let ASan return
  # NULL as glibc does instead of aborting.
  # libhdf5 1.10.8 also crashes on some corrupt files
  # (tests/data/hostile_hdf5/): the reader's probe process takes those
  # crashes, so any crash here is a finding.
  if [ "$f" = nisar_hdf5 ]; then
    max_len=262144 asan="$ASAN_OPTIONS:allocator_may_return_null=1"
  fi
  local findings_before
  findings_before=$(find "$BUILD_DIR/findings" -name "$f-*" | wc -l)
  mkdir -p "$corpus"
  echo "fuzz: $f for ${SECONDS_EACH} s" >&2
  if ! ASAN_OPTIONS="$asan" nice -n 19 "$BUILD_DIR/fuzz/fuzz_$f" -max_total_time="$SECONDS_EACH" -timeout=20 \
       -rss_limit_mb=2048 -max_len=$max_len -print_final_stats=1 \
       -artifact_prefix="$BUILD_DIR/findings/$f-" "$corpus" "$seeds/$f" \
       2>"$BUILD_DIR/fuzz_$f.log" ||
     [ "$(find "$BUILD_DIR/findings" -name "$f-*" | wc -l)" -ne "$findings_before" ]; then
    echo "fuzz: $f found a problem: see $BUILD_DIR/fuzz_$f.log and $BUILD_DIR/findings/" >&2
    rc=1
  fi
  grep -E "^stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb)|^#[0-9]+ +DONE" \
    "$BUILD_DIR/fuzz_$f.log" >&2 || true
  echo "fuzz: $f corpus $(find "$corpus" -type f | wc -l) files" >&2
  return $rc
}
pids=()
for f in "${FUZZERS[@]}"; do
  run_one "$f" &
  pids+=($!)
  if [ ${#pids[@]} -ge "${FUZZ_PARALLEL:-1}" ]; then
    wait "${pids[0]}" || status=1
    pids=("${pids[@]:1}")
  fi
done
for pid in "${pids[@]}"; do wait "$pid" || status=1; done
exit $status
