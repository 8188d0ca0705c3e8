#!/usr/bin/env bash
# The demo, on the bundled real data:
#  1. bare terrain: SAR images of Andorra's SRTM DEM (its 403 voids filled)
#     at headings 0 and 30 degrees, depression 40 degrees, in exact mode (a
#     flight line 20 km from the centre of a 33 km scene: the depression
#     varies across the swath as it does for an airborne radar);
#  2. GIS scene: the Andorra DEM + OpenStreetMap layers (water, forest, urban,
#     roads, waterways) -> classified constrained Delaunay mesh -> SAR image;
#  3. urban scene: Monaco DEM + OpenStreetMap buildings and roads;
#  4. a real image positioned: the UAVSAR San Andreas chip (L band) fixed
#     from a prior 60 m behind and 30 m right of its annotated track, against
#     references simulated on its own zero-Doppler grid (docs/navigation.md).
# Prints one line per product (its main file, how many files, seconds) and a
# closing summary; the commands run with --quiet (warnings still show).
set -euo pipefail
BUILD_DIR=${1:-build}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
GISSAR="$ROOT/$BUILD_DIR/bin/gissar"
OUT="$ROOT/out/demo"
mkdir -p "$OUT"
DATA="$ROOT/data"
START=$SECONDS
PRODUCTS=0

# product NAME MAIN_SUFFIX -- gissar arguments...: runs, then prints one line
# (the lines of stdout that name files are counted; the command's headline,
# its one-line result, follows indented).
product() {
  local name=$1 main=$2
  shift 3
  local t0=$SECONDS output files=0 line headlines=()
  output=$("$GISSAR" "$@" --quiet)
  while IFS= read -r line; do
    if [[ -e "$line" ]]; then files=$((files + 1)); elif [[ -n "$line" ]]; then headlines+=("$line"); fi
  done <<< "$output"
  PRODUCTS=$((PRODUCTS + 1))
  printf '%-22s %-46s %2d files %4d s\n' "$name" "out/demo/$name$main" "$files" $((SECONDS - t0))
  for line in "${headlines[@]}"; do printf '  %s\n' "$line"; done
}

for heading in 0 30; do
  product "andorra_h${heading}" .png -- simulate --dem "$DATA/andorra/andorra_srtm3_dem_raw.tif" --fill-nodata \
    --heading "$heading" --depression 40 --mode exact --slant-range 20000 --range-spacing 30 --azimuth-spacing 30 \
    --out "$OUT/andorra_h${heading}"
done
product andorra_scene _classes.png -- scene build --dem "$DATA/andorra/andorra_srtm3_dem_raw.tif" --fill-nodata \
  --vectors "$DATA/andorra/andorra_osm.gpkg" --out "$OUT/andorra_scene"
"$GISSAR" scene info "$OUT/andorra_scene.gscene" > "$OUT/andorra_scene_info.txt"
product andorra_scene_h0 .png -- simulate --scene "$OUT/andorra_scene.gscene" --heading 0 --depression 40 --mode exact \
  --slant-range 20000 --range-spacing 30 --azimuth-spacing 30 --out "$OUT/andorra_scene_h0"
product monaco_scene _classes.png -- scene build --dem "$DATA/monaco/monaco_srtm3_dem.tif" --fill-nodata \
  --osm "$DATA/monaco/monaco.osm.gz" --out "$OUT/monaco_scene"
product monaco_scene_h0 .png -- simulate --scene "$OUT/monaco_scene.gscene" --heading 0 --depression 35 \
  --slant-range 8000 --range-spacing 5 --azimuth-spacing 5 --out "$OUT/monaco_scene_h0"
product sanand_fix _composite.png -- locate --product "$DATA/uavsar/SanAnd_129.h5" --dem "$DATA/uavsar/SanAnd_dem.tif" \
  --dem-oversample 4 --prior-offset-track -60,30,0 --out "$OUT/sanand_fix" --composite "$OUT/sanand_fix_composite.png"
echo "demo: $PRODUCTS products in out/demo/ in $((SECONDS - START)) s (.png quicklooks and class maps;" \
     ".tif float32 intensity; _mask.tif layover/shadow; .gscene/.ply scenes; .json provenance;" \
     "andorra_scene_info.txt: the scene's classes; sanand_fix.json: a real image's pose fix)"
