#!/usr/bin/env python3
"""Simulate a SAR image from a DEM held in a NumPy array (no file): a Gaussian hill on a plane in UTM 31N.

    PYTHONPATH=build/python /usr/bin/python3 examples/simulate_array.py [--out DIR]

The result is an xarray.DataArray (band, along_track_m, slant_range_m) in metres, with units and the layover/
shadow mask as a coordinate; with --out, an annotated dB quicklook PNG is written there.
"""
import argparse
import os
import sys

import numpy as np

import gissar


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", help="directory for the quicklook (nothing written without it)")
    args = parser.parse_args()
    # 200 x 200 posts of 30 m: a 1500 m hill (sigma 600 m) in the middle of a 6 km square at 1000 m.
    y, x = np.mgrid[0:200, 0:200] * 30.0
    heights = (1000.0 + 1500.0 * np.exp(-((x - 3000) ** 2 + (y - 3000) ** 2) / (2 * 600.0 ** 2))).astype(np.float32)
    transform = (400000.0, 30.0, 0.0, 4700000.0, 0.0, -30.0)  # GDAL order: x0, dx, 0, y0, 0, dy
    sim = gissar.simulate(heights, transform=transform, crs=32631, heading_deg=0, depression_deg=40,
                          range_spacing_m=30, azimuth_spacing_m=30, vertical_datum="ellipsoid")
    total = sim.sel(band="total")
    mask = sim["mask"]
    print(f"image: {sim.sizes['slant_range_m']} x {sim.sizes['along_track_m']} px, slant range "
          f"{float(sim.slant_range_m[0]):.0f}..{float(sim.slant_range_m[-1]):.0f} m, "
          f"along track {float(sim.along_track_m[0]):.0f}..{float(sim.along_track_m[-1]):.0f} m")
    print(f"bands {list(sim.band.values)}; units '{sim.attrs['units']}' ({sim.attrs['radiometry']}); "
          f"mask categories {mask.attrs['flag_meanings']}")
    print(f"shadow {float(sim['shadow'].mean()):.1%}, layover {float(sim['layover'].mean()):.1%}, "
          f"median intensity {float(total.median()):.3g}")
    # The hill's far side (facing away from the radar) is in shadow, its near side in layover.
    if not (float(sim["shadow"].sum()) > 0 and float(sim["layover"].sum()) > 0):
        return 1
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        g = sim.gissar.geometry
        gissar.write_png(os.path.join(args.out, "hill_quicklook.png"), gissar.annotated_quicklook(
            sim, g.range_spacing_m, g.azimuth_spacing_m, "Gaussian hill from a NumPy array",
            near_range_m=float(sim.slant_range_m[0]), azimuth_origin_m=float(sim.along_track_m[0])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
