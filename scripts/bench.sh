#!/usr/bin/env bash
# `make bench`: runs the benchmark suite on synthetic fractal terrain and
# writes BENCHMARKS.md (every figure with its exact command, the machine and
# the date). Usage: scripts/bench.sh [BUILD_DIR] [OUTPUT.md]
#
# Figures (docs/performance.md): end-to-end `gissar simulate` on 1024^2,
# 2048^2 and 4096^2 posts at 4 rays per cell with 1 and 3 bounces (wall time,
# rays/s, peak RSS), 4096^2 with Embree's BVH instead of the height field and
# 8192^2 (scale; the raster engine at the same four sizes); the tracer's primary rays/s against raw Embree 16-wide
# coherent packets on the same scene in the same process; BVH build time and
# memory; the DEM-raster engine's cells/s on 4096^2 and a STREAM triad from
# the same process; scene build (CDT) time and memory; raster/tracer agreement
# on Andorra; POV-Ray side by side on a 1000 x 1000 heightfield; poses/s of
# `gissar corridor` on Dask with 1 and 2 workers (bench/corridor_bench.py); the exact-geometry user path on
# Andorra (500^2..4000^2, both engines) against sarsen's measured times; the
# pinned Andorra `evaluate` (seconds per fix). Runs in a few
# minutes on 2 cores; the machine may be shared, so the load average is
# recorded and ratios are always taken within one run.
set -euo pipefail
BUILD_DIR=${1:-build}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${2:-$ROOT/BENCHMARKS.md}
B="$ROOT/$BUILD_DIR"
GISSAR="$B/bin/gissar"
for tool in "$GISSAR" "$B/bench/fractal_dem" "$B/bench/trace_bench" "$B/bench/raster_bench" \
            "$B/bench/scene_build_bench" "$B/bench/raster_agreement" "$B/bench/write_bench"; do
  if [ ! -x "$tool" ]; then
    echo "bench: $tool is not built (run make build)" >&2
    exit 2
  fi
done
if ! command -v povray > /dev/null; then
  echo "bench: povray is not installed (scripts/install-deps.sh installs it)" >&2
  exit 2
fi
WORK=$(mktemp -d "${TMPDIR:-/tmp}/gissar-bench.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
R="$WORK/results"
mkdir -p "$R"
say() { echo "bench: $*" >&2; }
START=$(date +%s)
uptime > "$R/load_start.txt"
# The code measured: commit, and "-dirty" when tracked sources differ from
# it (the report and the profile notes excepted).
commit=$(git -C "$ROOT" rev-parse --short HEAD 2>/dev/null || echo unknown)
if [ -n "$(git -C "$ROOT" status --porcelain --untracked-files=no -- . ':!BENCHMARKS.md' ':!bench/PROFILES.md' 2>/dev/null)" ]; then
  commit="$commit-dirty"
fi
echo "$commit" > "$R/commit.txt"

# Every command is logged verbatim (commands.txt) and run from $WORK.
cd "$WORK"
run() {  # run NAME CMD...: stdout to $R/NAME.out, wall time and peak RSS to $R/NAME.time
  local name=$1; shift
  printf '%s\t%s\n' "$name" "$*" >> "$R/commands.txt"
  /usr/bin/time -f "%e %M" -o "$R/$name.time" "$@" > "$R/$name.out" 2> "$R/$name.err" || {
    say "$name failed:"; cat "$R/$name.err" >&2; exit 1; }
}

say "fractal DEMs"
for n in 1024 2048 4096; do run "dem_$n" "$B/bench/fractal_dem" "fractal_$n.tif" "$n"; done
run dem_1000 "$B/bench/fractal_dem" fractal_1000.tif 1000 10 800 1 fractal_1000.pgm

# Outputs as issue 18 defines the benchmark: tiled ZSTD GeoTIFFs (COG
# layout) without overviews, and fixed sampling (the primary rays of the ray
# grid, no adaptive sub-rays: the rays counted are the rays traced).
SIM=(simulate --heading 30 --depression 40 --slant-range 20000 --rays-per-cell 4 --no-overviews --fixed-sampling --quiet)
for n in 1024 2048 4096; do
  for b in 1 3; do
    say "simulate ${n}^2, $b bounce(s)"
    run "sim_${n}_b$b" "$GISSAR" "${SIM[@]}" --dem "fractal_$n.tif" --bounces "$b" --out "sim_${n}_b$b"
    cp "sim_${n}_b$b.json" "$R/"
    rm -f "sim_${n}_b$b".png "sim_${n}_b$b"_quicklook.png "sim_${n}_b$b"_mask.tif
    [ "$n-$b" = "4096-3" ] || rm -f "sim_${n}_b$b.tif"
  done
done

# The DEM-raster engine (single bounce), whole simulate, same DEMs and geometry.
RSIM=(simulate --heading 30 --depression 40 --slant-range 20000 --no-overviews --quiet --engine raster)
for n in 1024 2048 4096; do
  say "simulate ${n}^2, raster engine"
  run "ras_${n}" "$GISSAR" "${RSIM[@]}" --dem "fractal_$n.tif" --out "ras_${n}"
  cp "ras_${n}.json" "$R/"
  rm -f "ras_${n}".tif "ras_${n}".png "ras_${n}"_quicklook.png "ras_${n}"_mask.tif
done

# The same 4096^2, 3-bounce run with Embree's BVH over the DEM's triangles
# instead of the height field (the default): time and memory side by side.
say "simulate 4096^2, 3 bounces, --no-heightfield"
run sim_4096_b3_bvh "$GISSAR" "${SIM[@]}" --dem fractal_4096.tif --bounces 3 --no-heightfield --out sim_4096_b3_bvh
cp sim_4096_b3_bvh.json "$R/"
rm -f sim_4096_b3_bvh.tif sim_4096_b3_bvh.png sim_4096_b3_bvh_quicklook.png sim_4096_b3_bvh_mask.tif

# Scale: 8192^2 posts at 5 m (4x the cells and rays of 4096^2 on the same
# ground, so the same viewing geometry), 1 bounce.
say "scale: simulate 8192^2, 1 bounce"
run dem_8192 "$B/bench/fractal_dem" fractal_8192.tif 8192 5
run sim_8192_b1 "$GISSAR" "${SIM[@]}" --dem fractal_8192.tif --bounces 1 --out sim_8192_b1
cp sim_8192_b1.json "$R/"
rm -f sim_8192_b1.tif sim_8192_b1.png sim_8192_b1_quicklook.png sim_8192_b1_mask.tif
say "scale: simulate 8192^2, raster engine"
run ras_8192 "$GISSAR" "${RSIM[@]}" --dem fractal_8192.tif --out ras_8192
cp ras_8192.json "$R/"
rm -f fractal_8192.tif ras_8192.tif ras_8192.png ras_8192_quicklook.png ras_8192_mask.tif

# 16384^2 posts at 2.5 m, both engines, when it fits: simulate's memory
# estimate (docs/robustness.md) stays on the safe side and refuses it within
# the default budget of a 24 GiB machine, so it runs with --force when at
# least 16 GiB are available (measured peak: about 11 GiB for either engine).
avail_kb=$(awk '/^MemAvailable:/ {print $2}' /proc/meminfo)
echo "$avail_kb" > "$R/mem_available_kb_16384.txt"
if [ "$avail_kb" -ge $((16 * 1024 * 1024)) ]; then
  say "scale: simulate 16384^2, trace and raster engines (--force)"
  run dem_16384 "$B/bench/fractal_dem" fractal_16384.tif 16384 2.5
  run sim_16384_b1 "$GISSAR" "${SIM[@]}" --dem fractal_16384.tif --bounces 1 --force --out sim_16384_b1
  cp sim_16384_b1.json "$R/"
  rm -f sim_16384_b1.tif sim_16384_b1.png sim_16384_b1_quicklook.png sim_16384_b1_mask.tif
  run ras_16384 "$GISSAR" "${RSIM[@]}" --dem fractal_16384.tif --force --out ras_16384
  cp ras_16384.json "$R/"
  rm -f fractal_16384.tif ras_16384.tif ras_16384.png ras_16384_quicklook.png ras_16384_mask.tif
else
  say "scale: 16384^2 left out ($((avail_kb / 1024 / 1024)) GiB available, 16 GiB asked)"
fi

say "GeoTIFF writer: the 4096^2 image's float32 bands, with and without overviews"
GISSAR_BENCH_IMAGE=sim_4096_b3.tif run write_4096 "$B/bench/write_bench" \
  --benchmark_format=json --benchmark_out="$R/write_4096.json"
printf '%s\t%s\n' write_4096_env "GISSAR_BENCH_IMAGE=sim_4096_b3.tif" >> "$R/commands.txt"
rm -f sim_4096_b3.tif

# Both BVH qualities are built separately on the smaller scenes; on 4096^2
# the figure is that of the BVH the throughput benchmarks use.
for n in 1024 2048 4096; do
  say "tracer vs raw Embree, BVH build, ${n}^2"
  filter=.; [ "$n" -eq 4096 ] && filter='BM_RawEmbreeStream|BM_TracerPrimary'
  GISSAR_BENCH_DEM="fractal_$n.tif" run "trace_$n" "$B/bench/trace_bench" \
    --benchmark_filter="$filter" --benchmark_format=json --benchmark_out="$R/trace_$n.json"
done

say "raster engine and STREAM triad, 4096^2"
GISSAR_BENCH_DEM=fractal_4096.tif run raster_4096 "$B/bench/raster_bench" \
  --benchmark_format=json --benchmark_out="$R/raster_4096.json"
printf '%s\t%s\n' raster_4096_env "GISSAR_BENCH_DEM=fractal_4096.tif" >> "$R/commands.txt"

say "scene build (CDT)"
run scene_build "$B/bench/scene_build_bench" --benchmark_format=json --benchmark_out="$R/scene_build.json"

say "raster/tracer agreement on Andorra"
for h in 0 30 135 250; do
  run "agree_$h" "$B/bench/raster_agreement" --dem "$ROOT/data/andorra/andorra_srtm3_dem_raw.tif" \
    --fill-nodata --heading "$h" --depression 40 --rays-per-cell 16
done

say "POV-Ray side by side, 1000 x 1000 heightfield"
# gissar: heading 0 (flying north, looking east), depression 40 deg, pixels
# of the DEM's 10 m; rays per cell chosen so that the primary rays are
# 1000 x 1000 (measured with a first run at 1 ray per cell).
run pov_probe "$GISSAR" simulate --dem fractal_1000.tif --heading 0 --depression 40 --slant-range 20000 \
  --rays-per-cell 1 --bounces 1 --fixed-sampling --quiet --out probe
RPC=$(python3 -c "import json; j=json.load(open('probe.json')); print('%.4f' % (1e6 / j['stats']['rays']))")
RPC16=$(python3 -c "import json; j=json.load(open('probe.json')); print('%.4f' % (16e6 / j['stats']['rays']))")
# POV-Ray: the same heights (16-bit PGM, identical quantisation) as a
# height_field of 10 km x 800 m x 10 km, an orthographic camera and a
# parallel light both along the radar's look direction (so POV-Ray's shadows
# are radar shadow), 1000 x 1000 rays, no anti-aliasing, 2 worker threads.
# One bounce: diffuse only, max_trace_level 1; three levels: reflection 0.3,
# max_trace_level 3 (gissar: --bounces 3, the same mirror share).
for levels in 1 3; do
  reflection=0; [ "$levels" -gt 1 ] && reflection=0.3
  cat > "pov_$levels.pov" <<EOF
#version 3.7;
global_settings { max_trace_level $levels assumed_gamma 1.0 }
#declare L = <cos(radians(40)), -sin(radians(40)), 0>;
#declare C = <0, 500, 0>;
camera { orthographic location C - 30000 * L direction L right <0, 0, -10000> up vcross(L, <0, 0, 1>) * 7100 look_at C }
light_source { C - 30000 * L color rgb 1 parallel point_at C }
height_field { pgm "fractal_1000.pgm"
  texture { pigment { color rgb 1 } finish { ambient 0 diffuse 1 reflection { $reflection } } }
  translate <-0.5, 0, -0.5> scale <10000, 800, 10000> translate <0, 500, 0> }
EOF
  say "POV-Ray, $levels level(s), 1 M and 16 M rays"
  # 1 M rays: three runs of each, alternating (the report takes the median wall times).
  for r in 1 2 3; do
    suffix=""; [ "$r" -gt 1 ] && suffix="_r$r"
    run "pov_$levels$suffix" povray "+Ipov_$levels.pov" "+Opov_$levels.png" +W1000 +H1000 -A +Q9 +WT2 -D +FN
    run "ours_pov_$levels$suffix" "$GISSAR" simulate --dem fractal_1000.tif --heading 0 --depression 40 \
      --slant-range 20000 --rays-per-cell "$RPC" --bounces "$levels" --fixed-sampling --quiet --out "ours_pov_$levels"
    [ "$r" -eq 1 ] && cp "ours_pov_$levels.json" "$R/"
  done
  # The same heightfield with 4000 x 4000 rays (16 M) on both sides.
  run "pov16_$levels" povray "+Ipov_$levels.pov" "+Opov16_$levels.png" +W4000 +H4000 -A +Q9 +WT2 -D +FN
  run "ours_pov16_$levels" "$GISSAR" simulate --dem fractal_1000.tif --heading 0 --depression 40 \
    --slant-range 20000 --rays-per-cell "$RPC16" --bounces "$levels" --fixed-sampling --quiet --out "ours_pov16_$levels"
  cp "ours_pov16_$levels.json" "$R/"
  rm -f "pov16_$levels.png" "ours_pov16_$levels".tif "ours_pov16_$levels".png "ours_pov16_$levels"_*
done

say "exact geometry on Andorra, the user path of issue 47 (sarsen's times measured outside the project)"
# Andorra's filled SRTM reprojected to UTM 31N, a 27 km square centred on it
# at N x N posts (spacing 27000/N m); a straight track at 60 km slant range,
# pixels of the post spacing, default outputs, both engines.
run andorra_utm gdalwarp -q -overwrite -t_srs EPSG:32631 -r cubic \
  "$ROOT/data/andorra/andorra_srtm3_dem_filled.tif" andorra_utm.tif
for n in 500 1000 2000 4000; do
  run "andorra_$n" gdalwarp -q -overwrite -r cubic -te 371472.23 4697824.76 398472.23 4724824.76 -ts "$n" "$n" \
    andorra_utm.tif "andorra_$n.tif"
  spacing=$(python3 -c "print(27000 / $n)")
  # Three runs of each engine, alternating (the report takes the median wall
  # time: a single run moves by 10-20 % with the machine's page faults).
  for r in 1 2 3; do
    suffix=""; [ "$r" -gt 1 ] && suffix="_r$r"
    for engine in raster trace; do
      run "exact_${engine}_$n$suffix" "$GISSAR" simulate --dem "andorra_$n.tif" --vertical-datum ellipsoid --mode exact \
        --heading -0.9438 --depression 45 --slant-range 60000 --range-spacing "$spacing" --azimuth-spacing "$spacing" \
        --bounces 1 --engine "$engine" --quiet --out "exact_${engine}_$n"
      [ "$r" -eq 1 ] && cp "exact_${engine}_$n.json" "$R/"
      rm -f "exact_${engine}_$n".* "exact_${engine}_$n"_*
    done
  done
  rm -f "andorra_$n.tif"
done

say "corridor on Dask: 50 poses with 1 and 2 workers, --threads 1"
# The Python the module was built for (Debian's, with python3-distributed).
PY=$(sed -n 's/^Python_EXECUTABLE:FILEPATH=//p' "$B/CMakeCache.txt")
PYTHONPATH="$B/python" run corridor "${PY:-python3}" "$ROOT/bench/corridor_bench.py" --json "$R/corridor.json"
say "corridor on Dask: 30 poses of 512 x 512 px at 15 m with 2 workers (issue 47)"
PYTHONPATH="$B/python" run corridor_512 "${PY:-python3}" "$ROOT/bench/corridor_bench.py" --workers 2 --width 512 \
  --spacing 15 --poses 30 --json "$R/corridor_512.json"

say "pose fixes: the Andorra pinned evaluate command of docs/navigation.md, 200 trials (issue 47)"
# The scene as `make demo` builds it; the command as docs/navigation.md pins it.
run andorra_scene "$GISSAR" scene build --dem "$ROOT/data/andorra/andorra_srtm3_dem_raw.tif" --fill-nodata \
  --vectors "$ROOT/data/andorra/andorra_osm.gpkg" --quiet --out andorra_scene
uptime > "$R/evaluate_load.txt"
run evaluate_andorra "$GISSAR" evaluate --scene andorra_scene.gscene --trials 200 --seed 1 --search 28 --quiet \
  --out andorra200
cp andorra200.json "$R/evaluate_andorra.json"
rm -f andorra_scene.* andorra_scene_* andorra200.* andorra200_*

say "gissar view: a 202-pose corridor in headless chromium (bench/view_bench.py)"
if command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; then
  uptime > "$R/view_load.txt"
  PYTHONPATH="$B/python" run view_bench "${PY:-python3}" "$ROOT/bench/view_bench.py" --gissar "$GISSAR" \
    --json "$R/view.json"
else
  say "chromium not installed: gissar view bench skipped"
fi

say "pose fixes from stored references against rendered ones, 200 trials (bench/database_bench.py)"
uptime > "$R/database_load.txt"
PYTHONPATH="$B/python" run database_bench "${PY:-python3}" "$ROOT/bench/database_bench.py" --gissar "$GISSAR" \
  --trials 200 --json "$R/database.json"

uptime > "$R/load_end.txt"
END=$(date +%s)
echo $((END - START)) > "$R/bench_seconds.txt"
# The raw results stay in BUILD_DIR/bench-results (the report can be
# rewritten from them: python3 scripts/bench_report.py DIR . > BENCHMARKS.md).
rm -rf "$B/bench-results"
cp -r "$R" "$B/bench-results"
python3 "$ROOT/scripts/bench_report.py" "$B/bench-results" "$ROOT" > "$OUT.tmp"
mv "$OUT.tmp" "$OUT"
say "wrote $OUT in $((END - START)) s"
