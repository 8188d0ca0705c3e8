#!/usr/bin/env bash
# Share of the image energy in each bounce band over Monaco (docs/radiometry.md,
# issue 17 item 4): builds the Monaco scene from the bundled DEM and OSM
# extract, simulates it at 40 deg depression, 5 m pixels, default materials,
# for headings 0/45/90/135 deg, X (3.1 cm) and C (5.55 cm) band, VV and HH,
# and prints sum(band) / sum(total) of the double and triple bands (linear
# sigma0, whole image: land, buildings and sea).
# Usage: scripts/monaco_double_bounce.sh [BUILD_DIR]  (default: build)
set -euo pipefail
source "$(dirname "$0")/monaco_scene.sh"
share() {  # double and triple shares (%) of a simulated GeoTIFF
  /usr/bin/python3 - "$1" <<'PY'
import sys
from osgeo import gdal
import numpy as np
ds = gdal.Open(sys.argv[1])
b = [np.nan_to_num(ds.GetRasterBand(i + 1).ReadAsArray().astype(np.float64)).sum() for i in range(ds.RasterCount)]
print("%.2f %.3f" % (100 * b[2] / b[0], 100 * b[3] / b[0]))
PY
}
printf 'band pol heading_deg double_pct triple_pct\n'
for wl in 0.031 0.0555; do
  for pol in VV HH; do
    for heading in 0 45 90 135; do
      "$gissar" simulate --scene "$work/monaco.gscene" --heading "$heading" --depression 40 \
        --range-spacing 5 --azimuth-spacing 5 --wavelength "$wl" --polarization "$pol" \
        --out "$work/sim" --quiet > /dev/null
      band=X; [ "$wl" = 0.0555 ] && band=C
      printf '%s %s %s %s\n' "$band" "$pol" "$heading" "$(share "$work/sim.tif")"
    done
  done
done
