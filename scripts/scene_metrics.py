#!/usr/bin/env python3
"""Geometry checks of a built scene, independent of the scene builder.

Reads PREFIX.ply (ENU metres, per-face class) and PREFIX.json (frame origin)
written by `gissar scene build` and prints, as JSON:
  - inverted_walls: near-vertical building triangles whose normal points
    into the roof they carry: a point 5 cm along the normal from the
    triangle's centre lies under a roof whose height equals the wall's top
    (a correct wall has open ground or a lower roof there; the side of a
    pit, where the ground is above the roof, and a step down to a lower
    roof have a roof at their foot: counted apart);
  - downward terrain triangles (normal z < 0) and near-vertical terrain area
    (slope > 80 degrees), terrain = every class but building;
  - with --dem: the reference sea = DEM cells whose four posts are at or
    below --sea-level and 4-connected to the DEM border, and the fraction of
    those cells whose centre lies on a triangle of class `sea`.
Needs numpy and GDAL's Python bindings (Debian: python3-numpy, python3-gdal).

  scripts/scene_metrics.py out/demo/monaco_scene --dem data/monaco/monaco_srtm3_dem.tif
"""
import argparse
import collections
import json
import math
import sys

import numpy as np


def read_ply(path):
    with open(path, "rb") as f:
        names = []
        nv = nf = 0
        while True:
            line = f.readline().decode("ascii").strip()
            if line.startswith("comment class "):
                _, _, idx, name = line.split(" ", 3)
                names.append(name)
            elif line.startswith("element vertex"):
                nv = int(line.split()[-1])
            elif line.startswith("element face"):
                nf = int(line.split()[-1])
            elif line == "end_header":
                break
        v = np.frombuffer(f.read(nv * 12), dtype="<f4").reshape(nv, 3).astype(np.float64)
        faces = np.frombuffer(f.read(nf * 14), dtype=np.dtype([("n", "u1"), ("i", "<i4", 3), ("c", "u1")]))
    return v, faces["i"].astype(np.int64), faces["c"].astype(np.int64), names


class PlanIndex:
    """Triangles hashed by plan grid cells for point-in-triangle queries."""

    def __init__(self, v, tris, cell=10.0):
        self.v, self.tris, self.cell = v, tris, cell
        self.grid = collections.defaultdict(list)
        p = v[tris][:, :, :2]
        lo = np.floor(p.min(axis=1) / cell).astype(np.int64)
        hi = np.floor(p.max(axis=1) / cell).astype(np.int64)
        for k in range(len(tris)):
            for i in range(lo[k, 0], hi[k, 0] + 1):
                for j in range(lo[k, 1], hi[k, 1] + 1):
                    self.grid[(i, j)].append(k)

    def find(self, x, y):
        """Indices (into tris) of triangles containing (x, y) in plan."""
        out = []
        for k in self.grid.get((math.floor(x / self.cell), math.floor(y / self.cell)), ()):
            a, b, c = self.v[self.tris[k]][:, :2]
            d = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
            if d == 0:
                continue
            s = ((x - a[0]) * (c[1] - a[1]) - (y - a[1]) * (c[0] - a[0])) / d
            t = ((b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0])) / d
            if s >= 0 and t >= 0 and s + t <= 1:
                out.append(k)
        return out


def enu_from_geodetic(lon, lat, h, lon0, lat0):
    a, f = 6378137.0, 1 / 298.257223563
    e2 = f * (2 - f)

    def ecef(lo, la, hh):
        lo, la = np.radians(lo), np.radians(la)
        n = a / np.sqrt(1 - e2 * np.sin(la) ** 2)
        return np.stack([(n + hh) * np.cos(la) * np.cos(lo), (n + hh) * np.cos(la) * np.sin(lo),
                         (n * (1 - e2) + hh) * np.sin(la)], axis=-1)

    d = ecef(lon, lat, h) - ecef(np.array(lon0), np.array(lat0), np.array(0.0))
    lo, la = math.radians(lon0), math.radians(lat0)
    e = np.array([-math.sin(lo), math.cos(lo), 0])
    n = np.array([-math.sin(la) * math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la)])
    u = np.array([math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)])
    return np.stack([d @ e, d @ n, d @ u], axis=-1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("prefix")
    ap.add_argument("--dem", help="DEM the scene was built from (for the sea fraction)")
    ap.add_argument("--sea-level", type=float, default=0.0)
    args = ap.parse_args()
    v, tris, cls, names = read_ply(args.prefix + ".ply")
    meta = json.load(open(args.prefix + ".json"))
    building = names.index("building")
    cross = np.cross(v[tris[:, 1]] - v[tris[:, 0]], v[tris[:, 2]] - v[tris[:, 0]])
    norm = np.linalg.norm(cross, axis=1)
    area = 0.5 * norm
    ok = norm > 0
    nz = np.where(ok, cross[:, 2] / np.where(ok, norm, 1), 0)
    cos80 = math.cos(math.radians(80))
    terrain = (cls != building) & ok
    out = {"triangles": int(len(tris))}
    out["terrain_downward_triangles"] = int(np.sum(terrain & (nz < 0)))
    out["terrain_downward_area_m2"] = float(area[terrain & (nz < 0)].sum())
    out["terrain_near_vertical_area_m2"] = float(area[terrain & (nz < cos80)].sum())
    out["terrain_near_vertical_triangles"] = int(np.sum(terrain & (nz < cos80)))

    walls = np.where((cls == building) & ok & (np.abs(nz) < cos80))[0]
    roofs = np.where((cls == building) & ok & (nz > 0.99))[0]
    index = PlanIndex(v, tris[roofs])
    inverted = pits = 0
    for t in walls:
        p = v[tris[t]]
        c = p.mean(axis=0)
        d = cross[t, :2] / np.linalg.norm(cross[t, :2]) * 0.05
        top, foot = p[:, 2].max(), p[:, 2].min()
        hits = index.find(c[0] + d[0], c[1] + d[1])
        zs = [v[tris[roofs[k]]][:, 2].mean() for k in hits]
        # The roof there is the wall's own when it sits at the wall's top
        # (closer to the top than to the foot, within 5 cm).
        if any(abs(z - top) < 0.05 and abs(z - top) < abs(z - foot) for z in zs):
            inverted += 1
        elif any(abs(z - foot) < 0.05 and abs(z - foot) <= abs(z - top) for z in zs):
            pits += 1
    out["wall_triangles"] = int(len(walls))
    out["inverted_wall_triangles"] = inverted
    out["inverted_wall_fraction"] = inverted / max(1, len(walls))
    out["pit_or_step_wall_triangles"] = pits
    out["class_plan_area_km2"] = {names[c]: float(np.abs(cross[cls == c, 2]).sum() / 2e6) for c in range(len(names))}

    if args.dem:
        from osgeo import gdal
        ds = gdal.Open(args.dem)
        band = ds.GetRasterBand(1)
        h = band.ReadAsArray().astype(np.float64)
        nodata = band.GetNoDataValue()
        valid = np.isfinite(h) if nodata is None else (h != nodata) & np.isfinite(h)
        low = valid & (h <= args.sea_level)
        rows, cols = h.shape
        sea = np.zeros_like(low)
        queue = collections.deque()
        for r in range(rows):
            for c in range(cols):
                if (r in (0, rows - 1) or c in (0, cols - 1)) and low[r, c]:
                    sea[r, c] = True
                    queue.append((r, c))
        while queue:
            r, c = queue.popleft()
            for rr, cc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
                if 0 <= rr < rows and 0 <= cc < cols and low[rr, cc] and not sea[rr, cc]:
                    sea[rr, cc] = True
                    queue.append((rr, cc))
        cells = sea[:-1, :-1] & sea[1:, :-1] & sea[:-1, 1:] & sea[1:, 1:]
        rr, cc = np.nonzero(cells)
        gt = ds.GetGeoTransform()  # EPSG:4326 assumed (the bundled DEMs)
        col, row = cc + 1.0, rr + 1.0  # centre of the cell between posts (c, r) .. (c + 1, r + 1)
        lon = gt[0] + col * gt[1] + row * gt[2]
        lat = gt[3] + col * gt[4] + row * gt[5]
        frame = meta["frame"]
        enu = enu_from_geodetic(lon, lat, np.zeros_like(lon), frame["origin_lon_deg"], frame["origin_lat_deg"])
        ground = np.where(cls != building)[0]
        gindex = PlanIndex(v, tris[ground], cell=50.0)
        sea_id = names.index("sea") if "sea" in names else -1
        hit = 0
        for x, y in enu[:, :2]:
            ks = gindex.find(x, y)
            if ks and cls[ground[ks[0]]] == sea_id:
                hit += 1
        out["reference_sea_cells"] = int(len(rr))
        out["sea_fraction_of_reference"] = hit / max(1, len(rr))
    json.dump(out, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
