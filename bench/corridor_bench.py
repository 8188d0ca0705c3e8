#!/usr/bin/env python3
"""Poses per second of gissar.distributed.build_corridor with 1 and 2 Dask workers (docs/distributed.md).

A 50-pose corridor over the bundled Andorra DEM (SRTM 3", 480 x 300 posts): a route along lat 42.55 N from
lon 1.45 to 1.75 E (24.6 km), a pose every 500 m, heading 90 deg, 256 x 256 px images at 30 m, 4 rays per
cell. Each run uses a fresh embedded LocalCluster (worker processes, one task thread each) and every
simulation is capped at one thread (--threads 1), so the speed-up is that of the workers alone. Cluster
start-up is timed apart: poses/s counts the simulation phase (first task submitted to last result), the wall
time includes the start-up. Peak worker memory: the largest ru_maxrss of the worker processes
(resource.getrusage in each worker, through client.run).

usage: PYTHONPATH=build/python python3 bench/corridor_bench.py [--workers 1,2] [--poses 50] [--out DIR] [--json F]
Prints a Markdown table; --json writes the figures (scripts/bench.sh, scripts/bench_report.py).
"""
import argparse
import json
import os
import platform
import resource
import shutil
import sys
import tempfile
import time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
DEM = os.path.join(ROOT, "data", "andorra", "andorra_srtm3_dem_filled.tif")


def worker_peak_rss_bytes():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def run(workers, poses, directory, image):
    from distributed import Client, LocalCluster

    from gissar import distributed as gd
    step_m = 500.0
    # poses - 1 steps of 500 m east from (1.45 E, 42.55 N) along the geodesic
    from pyproj import Geod
    lon1, lat1, _ = Geod(ellps="WGS84").fwd(1.45, 42.55, 90.0, step_m * (poses - 1) + 1.0)
    route = [(1.45, 42.55), (lon1, lat1)]
    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None)
    client = Client(cluster)
    client.wait_for_workers(workers)
    client.run(lambda: __import__("gissar.distributed"))  # import gissar in the workers before timing
    t1 = time.perf_counter()
    prefix = os.path.join(directory, f"w{workers}")
    catalog = gd.build_corridor(route, dem=DEM, pose_step_m=step_m, headings_deg=[90.0], out_prefix=prefix,
                                client=client, threads=1, progress=None, **image)
    t2 = time.perf_counter()
    rss = max(client.run(worker_peak_rss_bytes).values())
    client.close()
    cluster.close()
    s = catalog["gissar:summary"]
    if s["simulated"] != poses or s["failed"] or s["skipped"]:
        raise SystemExit(f"unexpected summary: {s}")
    per_pose = [p for p in catalog["gissar:poses"]]
    return {"workers": workers, "poses": s["simulated"], "startup_s": t1 - t0, "simulate_s": t2 - t1,
            "poses_per_s": s["simulated"] / (t2 - t1), "wall_s": t2 - t0, "peak_worker_rss_bytes": rss,
            "task_s_per_pose": s["task_seconds"] / poses, "cpu_s_per_pose": s["task_cpu_seconds"] / poses,
            "ids": [p["id"] for p in per_pose]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--workers", default="1,2")
    parser.add_argument("--poses", type=int, default=50)
    parser.add_argument("--width", type=int, default=256)
    parser.add_argument("--spacing", type=float, default=30.0)
    parser.add_argument("--rays-per-cell", type=float, default=4.0)
    parser.add_argument("--out", help="keep the databases here (default: a temporary directory)")
    parser.add_argument("--json", help="also write the figures here (scripts/bench.sh: BENCHMARKS.md)")
    args = parser.parse_args()
    image = dict(width=args.width, height=args.width, range_spacing_m=args.spacing, azimuth_spacing_m=args.spacing,
                 rays_per_cell=args.rays_per_cell)
    directory = args.out or tempfile.mkdtemp(prefix="corridor_bench_")
    os.makedirs(directory, exist_ok=True)
    results = []
    try:
        for workers in [int(w) for w in args.workers.split(",")]:
            results.append(run(workers, args.poses, directory, image))
            print(f"{workers} workers: {results[-1]['poses_per_s']:.3f} poses/s", file=sys.stderr, flush=True)
    finally:
        if not args.out:
            shutil.rmtree(directory, ignore_errors=True)
    base = results[0]["poses_per_s"]
    print(f"machine: {platform.node()}, {os.cpu_count()} cores, {platform.processor() or platform.machine()}, "
          f"Python {platform.python_version()}")
    print(f"corridor: {args.poses} poses, {args.width}x{args.width} px at {args.spacing:g} m, "
          f"{args.rays_per_cell:g} rays/cell, --threads 1 per simulation")
    print("")
    print("| workers | poses/s | speed-up | simulate phase (s) | cluster start (s) | task s/pose | CPU s/pose "
          "| peak worker RSS (MiB) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in results:
        print(f"| {r['workers']} | {r['poses_per_s']:.3f} | {r['poses_per_s'] / base:.2f}x | {r['simulate_s']:.1f} | "
              f"{r['startup_s']:.1f} | {r['task_s_per_pose']:.2f} | {r['cpu_s_per_pose']:.2f} | "
              f"{r['peak_worker_rss_bytes'] / 2**20:.0f} |")
    print(f"load average at the end: {os.getloadavg()}")
    if args.json:
        for r in results:
            r.pop("ids", None)
        with open(args.json, "w") as f:
            json.dump({"poses": args.poses, "pose_step_m": 500.0, "image": image, "cores": os.cpu_count(),
                       "load_average": os.getloadavg(), "results": results}, f, indent=2)


if __name__ == "__main__":
    main()
