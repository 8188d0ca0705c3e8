#!/usr/bin/env python3
"""Build a GIS scene (DEM + OpenStreetMap layers -> classified mesh) and simulate it.

    PYTHONPATH=build/python /usr/bin/python3 examples/gis_scene.py --out DIR
"""
import argparse
import os
import sys
import tempfile

import gissar

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "data", "andorra")


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", help="output directory (default: a temporary one)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="gissar_scene_") as temp:
        out = args.out or temp
        os.makedirs(out, exist_ok=True)
        scene = gissar.Scene.build(os.path.join(DATA, "andorra_srtm3_dem_filled.tif"), os.path.join(out, "andorra"),
                                   vectors=[os.path.join(DATA, "andorra_osm.gpkg")], window=(150, 70, 120, 100))
        counts = {name: int((scene.classes == i).sum()) for i, name in enumerate(scene.class_names)}
        print(f"scene: {len(scene.triangles)} triangles; per class {counts}")
        sim = scene.simulate(heading_deg=30, depression_deg=40, range_spacing_m=30, azimuth_spacing_m=30,
                             width=200, height=200, speckle_looks=4, seed=1)
        means = {str(b): float(sim.sel(band=b).mean(skipna=True)) for b in sim.band.values}
        print("mean intensity per contribution: " + ", ".join(f"{b} {v:.3g}" for b, v in means.items()))
        print(f"shadow {float(sim['shadow'].mean()):.1%}, layover {float(sim['layover'].mean()):.1%}")
        gissar.write_png(os.path.join(out, "andorra_sar.png"), gissar.quicklook(sim)[0])
        return 0 if means["total"] > 0 and counts.get("water", 0) > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
