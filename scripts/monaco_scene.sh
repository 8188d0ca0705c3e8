# Sourced by the Monaco scripts (monaco_double_bounce.sh, monaco_polarimetry.sh):
# finds the gissar binary under BUILD_DIR ($1, default build), makes a
# work directory removed on exit ($work) and builds the Monaco scene from
# the bundled DEM and OSM extract into $work/monaco.gscene.
build=${1:-build}
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
gissar=$(find "$(realpath "$build")" -maxdepth 3 -type f -name gissar -perm -u+x | head -1)
if [ -z "$gissar" ]; then
  echo "$0: no gissar binary under $build (run make build)" >&2
  exit 2
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$gissar" scene build --dem "$repo/data/monaco/monaco_srtm3_dem.tif" --fill-nodata \
  --osm "$repo/data/monaco/monaco.osm.gz" --out "$work/monaco" --quiet > /dev/null
