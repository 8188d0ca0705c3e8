#!/usr/bin/env bash
# Polarimetric check over Monaco (docs/radiometry.md, "Several channels"): builds the
# Monaco scene from the bundled DEM and OSM extract, simulates it with
# `--polarization quad --coherent` (heading 0, depression 40 deg, 5 m pixels, X band)
# and prints the double-bounce HH/VV phase statistics and the Pauli cells' classes.
# Usage: scripts/monaco_polarimetry.sh [BUILD_DIR]  (default: build)
set -euo pipefail
build=${1:-build}
repo=$(cd "$(dirname "$0")/.." && pwd)
gissar=$(find "$(realpath "$build")" -maxdepth 3 -type f -name gissar -perm -u+x | head -1)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$gissar" scene build --dem "$repo/data/monaco/monaco_srtm3_dem.tif" --fill-nodata \
  --osm "$repo/data/monaco/monaco.osm.gz" --out "$work/monaco" --quiet > /dev/null
"$gissar" simulate --scene "$work/monaco.gscene" --heading 0 --depression 40 --range-spacing 5 \
  --azimuth-spacing 5 --polarization quad --coherent --out "$work/quad" --quiet
/usr/bin/python3 - "$work/quad" <<'PY'
import json, sys
import numpy as np
from osgeo import gdal
prefix = sys.argv[1]
slc = gdal.Open(prefix + "_slc.tif")
names = [slc.GetRasterBand(i + 1).GetDescription() for i in range(slc.RasterCount)]
def complex_band(name):
    return slc.GetRasterBand(names.index(name) + 1).ReadAsArray().astype(np.complex128)
hh, hv, vv = complex_band("HH"), complex_band("HV"), complex_band("VV")
hd, vd = complex_band("HH_double"), complex_band("VV_double")
power = np.abs(hd) ** 2
bright = np.isfinite(power) & (power > np.nanpercentile(power, 99.5))
phase = np.angle(hd[bright] * np.conj(vd[bright]), deg=True)
print("bright double-bounce pixels: %d, arg<HH_d VV_d*> = %.1f deg, |phase| > 90 deg: %.1f %%, median HH_d/VV_d "
      "%.2f dB" % (bright.sum(), np.degrees(np.angle(np.sum(hd[bright] * np.conj(vd[bright])))),
                   100 * np.mean(np.abs(phase) > 90),
                   np.median(10 * np.log10(power[bright] / np.maximum(np.abs(vd[bright]) ** 2, 1e-30)))))
detected = gdal.Open(prefix + ".tif")
dnames = [detected.GetRasterBand(i + 1).GetDescription() for i in range(detected.RasterCount)]
def band(name):
    return np.nan_to_num(detected.GetRasterBand(dnames.index(name) + 1).ReadAsArray().astype(np.float64))
L = 3
def look(a):
    h, w = (a.shape[0] // L) * L, (a.shape[1] // L) * L
    return a[:h, :w].reshape(h // L, L, w // L, L).mean(axis=(1, 3))
t11, t22 = look(np.abs(hh + vv) ** 2 / 2), look(np.abs(hh - vv) ** 2 / 2)
single, double = look(band("HH_single")), look(band("HH_double"))
ok = np.isfinite(t11) & (t11 + t22 > 0)
dbl, ground = ok & (double > 2 * single), ok & (double < 0.01 * single) & (single > 0)
print("3x3 cells: double-dominated %d, T22 > T11 in %.1f %%; single-dominated %d, T11 > T22 in %.1f %%" % (
    dbl.sum(), 100 * np.mean(t22[dbl] > t11[dbl]), ground.sum(), 100 * np.mean(t11[ground] > t22[ground])))
shares = json.load(open(prefix + ".json"))["polarimetry"]["bounce_shares"]
print("double-bounce share: " + ", ".join("%s %.2f %%" % (c, 100 * s["double"]) for c, s in shares.items()))
PY
