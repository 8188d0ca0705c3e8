#!/usr/bin/env bash
# The demo, on the bundled real data:
#  1. bare terrain: SAR images of Andorra's SRTM DEM (its 403 voids filled)
#     at headings 0 and 30 degrees, depression 40 degrees;
#  2. GIS scene: the Andorra DEM + OpenStreetMap layers (water, forest, urban,
#     roads, waterways) -> classified constrained Delaunay mesh -> SAR image;
#  3. urban scene: Monaco DEM + OpenStreetMap buildings and roads.
# Prints the output paths.
set -euo pipefail
BUILD_DIR=${1:-build}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
GISSAR="$ROOT/$BUILD_DIR/bin/gissar"
OUT="$ROOT/out/demo"
mkdir -p "$OUT"
DATA="$ROOT/data"
for heading in 0 30; do
  echo "== Andorra DEM, heading ${heading} deg, depression 40 deg" >&2
  "$GISSAR" simulate --dem "$DATA/andorra/andorra_srtm3_dem_raw.tif" --fill-nodata \
    --heading "$heading" --depression 40 --range 20000 --range-res 30 --azimuth-res 30 \
    --out "$OUT/andorra_h${heading}"
done
echo "== Andorra GIS scene from the bundled GeoPackage" >&2
"$GISSAR" scene build --dem "$DATA/andorra/andorra_srtm3_dem_raw.tif" --fill-nodata \
  --vectors "$DATA/andorra/andorra_osm.gpkg" --out "$OUT/andorra_scene"
"$GISSAR" scene info "$OUT/andorra_scene.gscene"
"$GISSAR" simulate --scene "$OUT/andorra_scene.gscene" --heading 0 --depression 40 \
  --range 20000 --range-res 30 --azimuth-res 30 --out "$OUT/andorra_scene_h0"
echo "== Monaco GIS scene from OpenStreetMap (buildings, roads)" >&2
"$GISSAR" scene build --dem "$DATA/monaco/monaco_srtm3_dem.tif" --fill-nodata \
  --osm "$DATA/monaco/monaco.osm.gz" --out "$OUT/monaco_scene"
"$GISSAR" simulate --scene "$OUT/monaco_scene.gscene" --heading 0 --depression 35 \
  --range 8000 --range-res 5 --azimuth-res 5 --out "$OUT/monaco_scene_h0"
echo "demo outputs are in $OUT (.png quicklooks and class maps; .tif float32 intensity;" \
     "_mask.tif layover/shadow; .gscene/.ply scenes; .json provenance)" >&2
