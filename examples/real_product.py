#!/usr/bin/env python3
"""Simulate a real product's radar grid: the bundled UAVSAR Winnipeg chip (NISAR RSLC HDF5) over its DEM, the
product's own |SLC| alongside.

    PYTHONPATH=build/python /usr/bin/python3 examples/real_product.py
"""
import os
import sys

import numpy as np

import gissar

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
UAVSAR = os.path.join(ROOT, "data", "uavsar")


def main():
    sim = gissar.simulate_product(os.path.join(UAVSAR, "winnipeg.h5"), dem=os.path.join(UAVSAR, "winnipeg_dem.tif"),
                                  seed=3)
    t, r = sim["zero_doppler_time_s"].values, sim["slant_range_m"].values
    print(f"product grid: {len(t)} lines x {len(r)} bins, {t[-1] - t[0]:.2f} s, slant range {r[0]:.0f}..{r[-1]:.0f} m, "
          f"wavelength {sim.attrs['wavelength_m']:.3f} m, {sim.attrs['look_side']}-looking")
    lon, lat = sim["lon_deg"].values, sim["lat_deg"].values
    print(f"ground: lon {np.nanmin(lon):.4f}..{np.nanmax(lon):.4f}, lat {np.nanmin(lat):.4f}..{np.nanmax(lat):.4f}")
    simulated = sim.sel(band="total").values
    real = sim["real_amplitude"].values ** 2
    ok = np.isfinite(simulated) & (simulated > 0) & (real > 0)
    print(f"median intensity over {ok.sum()} pixels: simulated {10 * np.log10(np.median(simulated[ok])):.1f} dB "
          f"(sigma0), real {10 * np.log10(np.median(real[ok])):.1f} dB (|SLC|^2, uncalibrated)")
    return 0 if ok.mean() > 0.5 else 1


if __name__ == "__main__":
    sys.exit(main())
