#!/usr/bin/env bash
# The demo: simulate SAR images of Andorra (SRTM DEM with its 403 voids
# filled) at headings 0 and 30 degrees, depression 40 degrees, and print the
# output paths.
set -euo pipefail
BUILD_DIR=${1:-build}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
GISSAR="$ROOT/$BUILD_DIR/bin/gissar"
OUT="$ROOT/out/demo"
mkdir -p "$OUT"
DEM="$ROOT/data/andorra/andorra_srtm3_dem_raw.tif"
for heading in 0 30; do
  echo "== gissar simulate: Andorra, heading ${heading} deg, depression 40 deg" >&2
  "$GISSAR" simulate --dem "$DEM" --fill-nodata --heading "$heading" --depression 40 \
    --range 20000 --range-res 30 --azimuth-res 30 --out "$OUT/andorra_h${heading}"
done
echo "demo outputs are in $OUT (open the .png quicklooks; .tif = float32 intensity," \
     "_mask.tif = layover/shadow, .json = provenance)" >&2
