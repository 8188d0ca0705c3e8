#!/usr/bin/env python3
"""Locate: fix an aircraft's pose from one SAR image and a scene, starting at a drifted INS prior.

    PYTHONPATH=build/python /usr/bin/python3 examples/locate.py
"""
import os
import sys
import tempfile

import numpy as np

import gissar

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEM = os.path.join(ROOT, "data", "andorra", "andorra_srtm3_dem_filled.tif")


def main():
    with tempfile.TemporaryDirectory(prefix="gissar_locate_") as out:
        scene = gissar.Scene.build(DEM, os.path.join(out, "s"), window=(150, 70, 120, 100))
        # The "observed" image: a simulation at the true pose (4-look speckle).
        observed = scene.simulate(heading_deg=30, depression_deg=40, slant_range_m=10000, range_spacing_m=30,
                                  azimuth_spacing_m=30, width=160, height=160, speckle_looks=4, seed=3)
        truth = np.array(observed.gissar.geometry.sensor_position())
        prior = {"heading_deg": 31.5, "slant_range_m": 10000.0, "sensor_enu_m": list(truth + [120.0, -90.0, 30.0])}
        fix = gissar.locate(scene, observed, prior, range_spacing_m=30, azimuth_spacing_m=30)
        before = np.linalg.norm(np.array(fix["prior"]["sensor_enu_m"]) - truth)
        after = np.linalg.norm(np.array(fix["pose"]["sensor_enu_m"]) - truth)
        print(f"pose fix: converged {fix['converged']} in {fix['iterations']} iterations; heading "
              f"{fix['pose']['heading_deg']:.2f} deg (true 30); sensor position error {before:.0f} m -> {after:.0f} m")
        return 0 if fix["converged"] and after < before else 1


if __name__ == "__main__":
    sys.exit(main())
