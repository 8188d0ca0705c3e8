#!/usr/bin/env python3
"""Where the SanAnd pose fixes' along-track bias comes from (issue 45, docs/navigation.md).

The real UAVSAR chip and gissar's simulation on its own annotated geometry (no prior error) are compared
directly: the shift of the real image against the simulation (whole-image NCC of the 3 x 3 box-filtered
dB images, full-resolution pixels, parabolic sub-pixel peak) over the whole chip, in 3 x 3 tiles, with the
real image's brightest pixels (streets, buildings) masked out, and with the DEM moved by fractions of its
1" post. A bias that the matching causes depends on the region and on the mask; a displacement between the
real image and the DEM does not, and disappears when the DEM is moved by it.

Usage: PYTHONPATH=build/python /usr/bin/python3 scripts/sanand_bias.py [--out bias.json]
Needs only numpy, GDAL's Python bindings and the gissar package; about 1 minute on 2 cores.
"""
import argparse
import json
import pathlib

import numpy as np
from osgeo import gdal

import gissar

ROOT = pathlib.Path(__file__).resolve().parent.parent
PRODUCT = ROOT / "data/uavsar/SanAnd_129.h5"
DEM = ROOT / "data/uavsar/SanAnd_dem.tif"


def box3_db(x):
    """3 x 3 box filter (edge-replicated) of a linear intensity, in dB."""
    p = np.pad(x, 1, mode="edge")
    s = sum(p[i:i + x.shape[0], j:j + x.shape[1]] for i in range(3) for j in range(3)) / 9.0
    return 10.0 * np.log10(np.maximum(s, 1e-6))


def ncc_shift(sim_db, real_db, mask, max_lines=12, max_bins=6):
    """(lines, bins, ncc): where the real image's pixel (y, x) best matches the simulation's (y + lines, x + bins)."""
    h, w = sim_db.shape
    scores = {}
    for dy in range(-max_lines, max_lines + 1):
        for dx in range(-max_bins, max_bins + 1):
            ys, xs = slice(max(0, -dy), min(h, h - dy)), slice(max(0, -dx), min(w, w - dx))
            ys2, xs2 = slice(ys.start + dy, ys.stop + dy), slice(xs.start + dx, xs.stop + dx)
            m = mask[ys, xs]
            a, b = real_db[ys, xs][m], sim_db[ys2, xs2][m]
            if a.size < 50:
                continue
            a, b = a - a.mean(), b - b.mean()
            scores[(dy, dx)] = float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))
    (dy, dx) = max(scores, key=scores.get)
    c0 = scores[(dy, dx)]

    def vertex(km, kp):
        den = km - 2 * c0 + kp
        return 0.0 if den >= 0 else 0.5 * (km - kp) / den

    sy = vertex(scores.get((dy - 1, dx), c0), scores.get((dy + 1, dx), c0))
    sx = vertex(scores.get((dy, dx - 1), c0), scores.get((dy, dx + 1), c0))
    return dy + sy, dx + sx, c0


def simulate(dem, transform):
    r = gissar.simulate_product(str(PRODUCT), dem=dem, transform=transform, crs="EPSG:4979", dem_oversample=4,
                                progress=False)
    sim = r.sel(band="total").values.astype(np.float64)
    real = r.coords["real_amplitude"].values.astype(np.float64) ** 2
    return sim, real, r


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="write the figures as JSON here")
    args = ap.parse_args()
    ds = gdal.Open(str(DEM))
    heights = ds.GetRasterBand(1).ReadAsArray().astype(np.float32)
    gt = list(ds.GetGeoTransform())

    sim, real, r = simulate(heights, gt)
    t = r.zero_doppler_time_s.values
    sim_db, real_db = box3_db(sim), box3_db(real)
    valid = sim > 0
    out = {"line_interval_s": float(t[1] - t[0]), "range_bin_m": float(r.slant_range_m.values[1] - r.slant_range_m.values[0])}
    whole = ncc_shift(sim_db, real_db, valid)
    out["whole"] = whole
    print(f"whole chip: real = simulation shifted {whole[0]:+.2f} lines, {whole[1]:+.2f} bins (NCC {whole[2]:.3f})")

    h, w = sim.shape
    tiles = []
    print("3 x 3 tiles (lines, bins, NCC):")
    for i in range(3):
        row = []
        for j in range(3):
            m = np.zeros_like(valid)
            m[i * h // 3:(i + 1) * h // 3, j * w // 3:(j + 1) * w // 3] = True
            row.append(ncc_shift(sim_db, real_db, valid & m))
        tiles.append(row)
        print("  " + "  ".join(f"({a:+5.1f}, {b:+4.1f}, {c:.2f})" for a, b, c in row))
    out["tiles_3x3"] = tiles

    median = np.median(real_db[valid])
    out["real_masked"] = {}
    for above in (3, 6, 10):
        s = ncc_shift(sim_db, real_db, valid & (real_db < median + above))
        out["real_masked"][f"below_median_plus_{above}_db"] = s
        print(f"real pixels brighter than median + {above} dB masked: {s[0]:+.2f} lines, {s[1]:+.2f} bins (NCC {s[2]:.3f})")

    out["dem_moved"] = []
    print("DEM moved by (east, north) posts: shift in lines, bins, NCC")
    for fx, fy in [(0.5, 0.0), (-0.5, 0.0), (0.0, 0.5), (0.0, -0.5), (0.55, 0.2)]:
        moved = list(gt)
        moved[0] += fx * gt[1]
        moved[3] -= fy * gt[5]  # gt[5] < 0: north is -gt[5]
        s_sim, s_real, _ = simulate(heights, moved)
        s = ncc_shift(box3_db(s_sim), box3_db(s_real), s_sim > 0)
        out["dem_moved"].append({"east_posts": fx, "north_posts": fy, "shift": s})
        print(f"  ({fx:+.2f}, {fy:+.2f}): {s[0]:+.2f} lines, {s[1]:+.2f} bins (NCC {s[2]:.3f})")
    if args.out:
        pathlib.Path(args.out).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
