#!/usr/bin/env bash
# Measures the radiometric figures of docs/radiometry.md end to end through
# the CLI: a flat DEM (0 m, UTM 31N, 5 m posts, 2 km square) with a constant
# sigma0 = -10 dB `default` material, simulated at depressions 30/45/60 deg,
# 1 and 16 rays per cell, 5 and 20 m pixels; the mean over the central
# quarter of the image in dB. Then beta0 and gamma0 at 30 deg.
# Usage: scripts/radiometry_check.sh [BUILD_DIR]  (default: build)
set -euo pipefail
build=${1:-build}
gissar=$(realpath "$build")/apps/gissar
[ -x "$gissar" ] || gissar=$(find "$(realpath "$build")" -maxdepth 3 -type f -name gissar -perm -u+x | head -1)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
gdal_create -q -of GTiff -outsize 401 401 -bands 1 -burn 0 -ot Float32 -a_srs EPSG:32631 \
  -a_ullr 399000 4701000 401005 4698995 "$work/flat.tif"
echo '{"default": {"sigma0_db": [[0, -10], [90, -10]]}}' > "$work/m.json"
mean_db() {  # mean of band 1 over the central quarter, in dB
  local tif=$1
  local size
  size=$(gdalinfo "$tif" | sed -n 's/^Size is \([0-9]*\), \([0-9]*\)/\1 \2/p')
  set -- $size
  local w=$1 h=$2
  gdal_translate -q -b 1 -srcwin $((w * 3 / 8)) $((h * 3 / 8)) $((w / 4)) $((h / 4)) "$tif" "$work/win.tif"
  gdalinfo -stats "$work/win.tif" | sed -n 's/.*STATISTICS_MEAN=\(.*\)/\1/p' |
    awk '{printf "%.3f", 10 * log($1) / log(10)}'
  rm -f "$work/win.tif" "$work/win.tif.aux.xml"
}
printf 'depression rays spacing_m sigma0_db\n'
for dep in 30 45 60; do
  for rays in 1 16; do
    for px in 5 20; do
      "$gissar" simulate --dem "$work/flat.tif" --materials "$work/m.json" --heading 30 --depression "$dep" \
        --rays-per-cell "$rays" --range-res "$px" --azimuth-res "$px" --out "$work/s" --quiet > /dev/null
      printf '%s %s %s %s\n' "$dep" "$rays" "$px" "$(mean_db "$work/s.tif")"
    done
  done
done
for q in beta0 gamma0; do
  "$gissar" simulate --dem "$work/flat.tif" --materials "$work/m.json" --heading 30 --depression 30 \
    --range-res 10 --azimuth-res 10 --radiometry "$q" --out "$work/s" --quiet > /dev/null
  printf '%s at 30 deg: %s dB\n' "$q" "$(mean_db "$work/s.tif")"
done
grep -o '"empty_footprint_fraction": [0-9.e-]*' "$work/s.json" || true
