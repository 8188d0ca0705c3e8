#!/usr/bin/env bash
# Polarimetric check over Monaco (docs/radiometry.md, "Several channels"): builds the
# Monaco scene from the bundled DEM and OSM extract, simulates it with
# `--polarization quad --coherent` (heading 0, depression 40 deg, 5 m pixels, X band)
# twice: with the default materials (concrete walls, eps 6 - 0.5j) and with the
# built-up classes made conductor-like (eps 1000 - 100j: no pseudo-Brewster angle).
# For each it prints the double-bounce HH/VV phase statistics, the double-bounce
# shares and the classes of the multilooked (3 x 3) Pauli cells: red where
# T22 > T11 (|HH - VV| above |HH + VV|), blue where T11 > T22.
# Usage: scripts/monaco_polarimetry.sh [BUILD_DIR]  (default: build)
set -euo pipefail
source "$(dirname "$0")/monaco_scene.sh"
echo '{"building": {"permittivity": [1000, 100]}, "urban": {"permittivity": [1000, 100]},
 "road": {"permittivity": [1000, 100]}}' > "$work/conductor_materials.json"
for run in default conductor; do
  extra=()
  [ "$run" = conductor ] && extra=(--materials "$work/conductor_materials.json")
  "$gissar" simulate --scene "$work/monaco.gscene" --heading 0 --depression 40 --range-spacing 5 \
    --azimuth-spacing 5 --polarization quad --coherent "${extra[@]}" --out "$work/$run" --quiet > /dev/null
  echo "== materials: $run"
  /usr/bin/python3 - "$work/$run" <<'PY'
import json, sys
import numpy as np
from osgeo import gdal
prefix = sys.argv[1]
slc = gdal.Open(prefix + "_slc.tif")
names = [slc.GetRasterBand(i + 1).GetDescription() for i in range(slc.RasterCount)]
def complex_band(name):
    return np.nan_to_num(slc.GetRasterBand(names.index(name) + 1).ReadAsArray().astype(np.complex128))
hh, vv = complex_band("HH"), complex_band("VV")
hd, vd, hs = complex_band("HH_double"), complex_band("VV_double"), complex_band("HH_single")
power = np.abs(hd) ** 2
bright = power > np.percentile(power, 99.5)
phase = np.angle(hd[bright] * np.conj(vd[bright]), deg=True)
print("bright double-bounce pixels: %d, arg<HH_d VV_d*> = %.1f deg, |phase| > 90 deg: %.1f %%, median HH_d/VV_d "
      "%.2f dB" % (bright.sum(), np.degrees(np.angle(np.sum(hd[bright] * np.conj(vd[bright])))),
                   100 * np.mean(np.abs(phase) > 90),
                   np.median(10 * np.log10(power[bright] / np.maximum(np.abs(vd[bright]) ** 2, 1e-30)))))
L = 3
def look(a):
    h, w = (a.shape[0] // L) * L, (a.shape[1] // L) * L
    return a[:h, :w].reshape(h // L, L, w // L, L).mean(axis=(1, 3))
t11, t22 = look(np.abs(hh + vv) ** 2 / 2), look(np.abs(hh - vv) ** 2 / 2)
t11_d, t22_d = look(np.abs(hd + vd) ** 2 / 2), look(np.abs(hd - vd) ** 2 / 2)
single, double = look(np.abs(hs) ** 2), look(np.abs(hd) ** 2)
ok = t11 + t22 > 0
dbl, ground = ok & (double > 2 * single), ok & (double < 0.01 * single) & (single > 0)
red = t22 > t11
print("3x3 cells where the double bounce dominates HH: %d; red (T22 > T11) %.1f %%; their double-bounce power in red "
      "cells %.1f %%; the double bounce alone red in %.1f %%" % (
          dbl.sum(), 100 * np.mean(red[dbl]), 100 * double[dbl & red].sum() / double[dbl].sum(),
          100 * np.mean(t22_d[dbl] > t11_d[dbl])))
brightest = np.argsort(-double[dbl])
for n in (100, 250, 500):
    print("  the %d brightest double-bounce cells: red %.1f %%" % (n, 100 * np.mean(red[dbl][brightest[:n]])))
print("single-dominated cells %d, blue (T11 > T22) in %.1f %%" % (ground.sum(), 100 * np.mean(~red[ground])))
shares = json.load(open(prefix + ".json"))["polarimetry"]["bounce_shares"]
print("double-bounce share: " + ", ".join("%s %.2f %%" % (c, 100 * s["double"]) for c, s in shares.items()))
PY
done
