#!/usr/bin/env python3
"""Writes BENCHMARKS.md (stdout) from the results directory of scripts/bench.sh.

Usage: bench_report.py RESULTS_DIR REPO_ROOT
"""
import json
import os
import platform
import re
import statistics
import subprocess
import sys
from datetime import datetime, timezone

R, ROOT = sys.argv[1], sys.argv[2]
GIB = 1024.0 ** 3
MIB = 1024.0 ** 2


def read(name):
    with open(os.path.join(R, name)) as f:
        return f.read()


def load(name):
    return json.loads(read(name))


def wall_rss(name):
    """(wall seconds, peak RSS bytes) of a command run by bench.sh; a command run three times (NAME, NAME_r2,
    NAME_r3): the median wall time and the largest peak."""
    runs = [name] + [name + suffix for suffix in ("_r2", "_r3") if os.path.exists(os.path.join(R, name + suffix + ".time"))]
    walls, peaks = [], []
    for run in runs:
        wall, kb = read(run + ".time").split()[-2:]
        walls.append(float(wall))
        peaks.append(float(kb) * 1024.0)
    return statistics.median(walls), max(peaks)


def benchmarks(name):
    return {b["name"]: b for b in load(name)["benchmarks"]}


commands = {}
for line in read("commands.txt").splitlines():
    key, cmd = line.split("\t", 1)
    cmd = re.sub(r"/[^\s=]*/gissar-bench\.[^/]+/", "", cmd)  # the scratch directory
    commands[key] = cmd.replace(os.path.abspath(ROOT) + "/", "")


def cmd(key):
    return "`" + commands[key] + "`"


def cpu_model():
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor()


def mem_total():
    with open("/proc/meminfo") as f:
        for line in f:
            if line.startswith("MemTotal"):
                return float(line.split()[1]) * 1024.0
    return 0.0


def git_commit():
    try:
        return subprocess.check_output(["git", "-C", ROOT, "describe", "--always", "--dirty"],
                                       text=True).strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def verdict(ok):
    return "**reached**" if ok else "**missed**"


out = []
w = out.append
w("# gissar benchmarks")
w("")
w("Written by `make bench` (scripts/bench.sh, scripts/bench_report.py); do not edit by hand.")
w("")
w("| | |")
w("|---|---|")
w("| date (UTC) | %s |" % datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M"))
w("| commit measured | %s |" % (read("commit.txt").strip() if os.path.exists(os.path.join(R, "commit.txt"))
                                else git_commit()))
w("| CPU | %s |" % cpu_model())
w("| cores | %d (`nproc`) |" % os.cpu_count())
w("| memory | %.1f GiB |" % (mem_total() / GIB))
w("| OS | %s |" % platform.platform())
w("| load average at start / end | %s / %s |" % (read("load_start.txt").split("load average:")[1].strip(),
                                               read("load_end.txt").split("load average:")[1].strip()))
w("| whole suite | %s s |" % read("bench_seconds.txt").strip())
w("")
w("The machine may be shared (a load average above the core count means other jobs were running):")
w("absolute times are then pessimistic, and every comparison below is a ratio of two figures")
w("measured in the same run, back to back. All terrain is synthetic fractal terrain")
w("(`bench/fractal_dem`: 10 m posts, 800 m relief, seed 1); the geometry is heading 30 deg,")
w("depression 40 deg, slant range 20 km, pixels of the post spacing, unless said otherwise.")
w("")

# ---------------------------------------------------------------- simulate
w("## End-to-end `gissar simulate`, 4 rays per cell")
w("")
w("Wall time and peak RSS of the whole process (`/usr/bin/time`), from reading the DEM to the")
w("committed GeoTIFFs, PNG and JSON. Rays/s: primary rays per second of wall time, and per second")
w("of the tracing phase alone. Phases from the JSON sidecar (`timings_s`).")
w("")
w("| posts | triangles | bounces | image | primary rays | wall s | rays/s (wall) | rays/s (trace) | peak RSS | terrain s | BVH s | trace s | mask s | write s |")
w("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
sims = {}
for n in (1024, 2048, 4096):
    for b in (1, 3):
        key = "sim_%d_b%d" % (n, b)
        j = load(key + ".json")
        wall, rss = wall_rss(key)
        t = j["timings_s"]
        rays = j["stats"]["rays"]
        sims[(n, b)] = (wall, rss, j)
        w("| %d² | %.1f M | %d | %d × %d | %.1f M | %.1f | %.2f M | %.2f M | %.2f GiB | %.1f | %.1f | %.1f | %.1f | %.1f |" % (
            n, j["stats"]["triangles"] / 1e6, b, j["geometry"]["width"], j["geometry"]["height"],
            rays / 1e6, wall, rays / wall / 1e6, rays / t["trace"] / 1e6, rss / GIB,
            t["terrain"], t.get("bvh", 0.0), t["trace"], t.get("mask", 0.0), t["write"]))
w("")
w("Commands (run in a scratch directory holding the DEMs):")
w("")
w("- DEMs: " + ", ".join(cmd("dem_%d" % n) for n in (1024, 2048, 4096)))
for n in (1024, 2048, 4096):
    for b in (1, 3):
        w("- %d², %d bounce(s): %s" % (n, b, cmd("sim_%d_b%d" % (n, b))))
w("")
wall, rss, _ = sims[(4096, 3)]
w("Target (issue 18): 4096², 4 rays per cell, 3 bounces: whole `simulate` including writing ≤ 8 s wall")
w("(idle machine) and ≤ 1.5 GiB peak. Reached here: **%.1f s** wall (%s), **%.2f GiB** peak (%s)." % (
    wall, verdict(wall <= 8.0), rss / GIB, verdict(rss <= 1.5 * GIB)))
w("")

# ---------------------------------------------------------------- height field
w("### Terrain as a height field against Embree's BVH (4096², 3 bounces)")
w("")
w("`simulate` traces a DEM's terrain as a height field by default (`render/heightfield.h`: a quadtree")
w("of 3-D bounds over the grid's cells whose 8 × 8-cell tiles are an Embree user geometry, triangles")
w("intersected on the fly, watertight, in double precision); `--no-heightfield` builds Embree's BVH")
w("over the DEM's quads instead. Same DEM, same command otherwise, back to back:")
w("")
w("| terrain | wall s | peak RSS | index build s | trace s | mask s |")
w("|---|---|---|---|---|---|")
wall_b, rss_b = wall_rss("sim_4096_b3_bvh")
jb = load("sim_4096_b3_bvh.json")
wall_h, rss_h, jh = sims[(4096, 3)]
for label, wall_x, rss_x, jx in (("height field (default)", wall_h, rss_h, jh), ("Embree BVH (`--no-heightfield`)", wall_b, rss_b, jb)):
    t = jx["timings_s"]
    w("| %s | %.1f | %.2f GiB | %.2f | %.1f | %.1f |" % (label, wall_x, rss_x / GIB, t.get("bvh", 0.0), t["trace"], t.get("mask", 0.0)))
w("")
w("Height field / BVH: wall %.2f×, peak memory %.2f×, index build %.2f×, trace %.2f×. Command: %s." % (
    wall_h / wall_b, rss_h / rss_b, jh["timings_s"]["bvh"] / jb["timings_s"]["bvh"],
    jh["timings_s"]["trace"] / jb["timings_s"]["trace"], cmd("sim_4096_b3_bvh")))
w("")

# ---------------------------------------------------------------- scale
w("### Scale (1 bounce)")
w("")
w("The same command on 1024² … 16384² posts (8192² and 16384²: 5 m and 2.5 m posts over the ground of the")
w("4096² DEM, so the viewing geometry is the same and the cells, primary rays and pixels are 4× and 16× those")
w("of 4096²; 16384² runs with `--force` when it fits, see below):")
w("")
w("| posts | primary rays | image | wall s | peak RSS | µs per primary ray (wall) | wall / wall at 4096² |")
w("|---|---|---|---|---|---|---|")
scale = {n: sims[(n, 1)] for n in (1024, 2048, 4096)}
wall8, rss8 = wall_rss("sim_8192_b1")
scale[8192] = (wall8, rss8, load("sim_8192_b1.json"))
ran_16384 = os.path.exists(os.path.join(R, "sim_16384_b1.time"))
if ran_16384:
    wall16, rss16 = wall_rss("sim_16384_b1")
    scale[16384] = (wall16, rss16, load("sim_16384_b1.json"))
for n, (wall_x, rss_x, jx) in scale.items():
    w("| %d² | %.1f M | %d × %d | %.1f | %.2f GiB | %.2f | %.2f |" % (
        n, jx["stats"]["rays"] / 1e6, jx["geometry"]["width"], jx["geometry"]["height"], wall_x, rss_x / GIB,
        wall_x / jx["stats"]["rays"] * 1e6, wall_x / scale[4096][0]))
w("")
ratio8 = wall8 / scale[4096][0]
w("Target (issue 18): 8192² within 24 GiB in ≈ 4× the 4096² time (± 30 %%). Reached here: %.2f× (%s), %.2f GiB (%s). Commands: %s, %s." % (
    ratio8, verdict(2.8 <= ratio8 <= 5.2), rss8 / GIB, verdict(rss8 < 24 * GIB), cmd("dem_8192"), cmd("sim_8192_b1")))
w("")
w("The DEM-raster engine (`--engine raster`: single bounce, no rays), whole `simulate` including writing,")
w("on the same DEMs:")
w("")
w("| posts | DEM cells | image | wall s | peak RSS | ns per cell (wall) | render s | wall / wall at 4096² |")
w("|---|---|---|---|---|---|---|---|")
raster_scale = {}
for n in (1024, 2048, 4096, 8192) + ((16384,) if ran_16384 else ()):
    wall_x, rss_x = wall_rss("ras_%d" % n)
    raster_scale[n] = (wall_x, rss_x, load("ras_%d.json" % n))
for n, (wall_x, rss_x, jx) in raster_scale.items():
    cells = (n - 1) ** 2
    w("| %d² | %.1f M | %d × %d | %.1f | %.2f GiB | %.0f | %.1f | %.2f |" % (
        n, cells / 1e6, jx["geometry"]["width"], jx["geometry"]["height"], wall_x, rss_x / GIB,
        wall_x / cells * 1e9, jx["timings_s"]["raster"], wall_x / raster_scale[4096][0]))
w("")
w("Command: %s (and the same on each DEM)." % cmd("ras_4096"))
w("")
# 16384^2 against simulate's own memory estimate (pipeline/simulate.cc, docs/robustness.md): 128 B per
# post (height field or raster engine) against the default budget, 3/4 of the machine's memory.
need16 = 16384.0 ** 2 * 128
budget = 0.75 * mem_total()
avail16 = float(read("mem_available_kb_16384.txt").split()[0]) * 1024.0
if ran_16384:
    w("16384² (268 M posts): `simulate`'s memory estimate (128 B per DEM post, docs/robustness.md) asks for"
      " about %.0f GiB, over this machine's default budget of %.1f GiB (3/4 of its memory), so both runs use"
      " `--force`; they peak at %.1f GiB (trace) and %.1f GiB (raster). Wall time against 8192²: trace %.2f×,"
      " raster %.2f× (4× the cells). Commands: %s, %s, %s." % (
          need16 / GIB, budget / GIB, scale[16384][1] / GIB, raster_scale[16384][1] / GIB,
          scale[16384][0] / scale[8192][0], raster_scale[16384][0] / raster_scale[8192][0],
          cmd("dem_16384"), cmd("sim_16384_b1"), cmd("ras_16384")))
else:
    w("16384² (268 M posts) left out: %.1f GiB of memory available when it was due, 16 GiB asked (its peak"
      " is about 11 GiB; `simulate`'s estimate, on the safe side, asks for %.0f GiB)." % (avail16 / GIB, need16 / GIB))
w("")

# ---------------------------------------------------------------- writing
w("## Writing the product")
w("")
w("`write_bench`: the four float32 bands (total, single, double, triple) of the 4096², 3-bounce image above written again by `geo::WriteFloatGeoTiff`, the")
w("writer `simulate` uses (COG layout, 512-pixel ZSTD level-1 tiles, floating-point predictor, GDAL's")
w("threads), with the COG's internal overviews (simulate's default: AVERAGE of the finite pixels, computed")
w("by gissar) and without them (`--no-overviews`, the outputs of the simulate runs above); mean of 3.")
w("")
w("| image | overviews | seconds | MB/s of float32 pixels | file |")
w("|---|---|---|---|---|")
wb = benchmarks("write_4096.json")
write_seconds = {}
for name, b in sorted(wb.items()):
    ov = int(b["overviews"])
    write_seconds[ov] = b["real_time"] / 1000.0
    w("| %.1f Mpx × %d bands | %s | %.2f | %.0f | %.0f MB |" % (
        b["megapixels"], int(b["bands"]), "yes" if ov else "no", b["real_time"] / 1000.0,
        b["bytes_per_second"] / 1e6, b["file_MB"]))
w("")
detail = sims[(4096, 3)][2]["timings_s"].get("write_detail", {})
if detail:
    w("Inside the 4096², 3-bounce `simulate` (sidecar `timings_s.write_detail`, seconds; the quicklooks")
    w("are drawn on another thread while the georeferencing and the image are written):")
    w("")
    w("| " + " | ".join(detail.keys()) + " | whole `write` |")
    w("|" + "---|" * (len(detail) + 1))
    w("| " + " | ".join("%.2f" % v for v in detail.values()) + " | %.2f |" % sims[(4096, 3)][2]["timings_s"]["write"])
    w("")
w("Command: `GISSAR_BENCH_IMAGE=sim_4096_b3.tif " + commands["write_4096"] + "`.")
w("")
w("Target (issue 18): 24 Mpx × 5 float32 bands written in ≤ 1.5 s. Reached here: %.2f s without overviews (%s), %.2f s with them." % (
    write_seconds.get(0, float("nan")), verdict(write_seconds.get(0, 1e9) <= 1.5), write_seconds.get(1, float("nan"))))
w("")

# ---------------------------------------------------------------- limit
w("## The limit: tracer primary rays against raw Embree")
w("")
w("`BM_RawEmbreeStream` intersects exactly the tracer's primary rays (same ray grid, same float")
w("origins and directions, same parallel blocks) 16 at a time with `rtcIntersect16` and the coherent")
w("flag, and does nothing else. `BM_TracerPrimary` is `RenderSar` with one bounce, timed over its")
w("tracing phase (ray generation, intersection, shading, splatting, merging the bands). Same")
w("process, same BVH (automatic quality), run back to back, 2 iterations each.")
w("")
w("| posts | rays | raw Embree rays/s | tracer rays/s | tracer / raw | raw height field rays/s | tracer on the height field rays/s |")
w("|---|---|---|---|---|---|---|")
ratios = {}
for n in (1024, 2048, 4096):
    bm = benchmarks("trace_%d.json" % n)
    raw = bm["BM_RawEmbreeStream/0/iterations:2/real_time"]
    ours = bm["BM_TracerPrimary/0/iterations:2/manual_time"]
    raw_h = bm["BM_RawEmbreeStream/1/iterations:2/real_time"]
    ours_h = bm["BM_TracerPrimary/1/iterations:2/manual_time"]
    ratio = ours["rays_per_s"] / raw["rays_per_s"]
    ratios[n] = ratio
    w("| %d² | %.1f M | %.2f M | %.2f M | %.0f %% | %.2f M | %.2f M |" % (
        n, raw["rays"] / 1e6, raw["rays_per_s"] / 1e6, ours["rays_per_s"] / 1e6, 100 * ratio,
        raw_h["rays_per_s"] / 1e6, ours_h["rays_per_s"] / 1e6))
w("")
w("The last two columns: the same rays through the height field (`/1` in the benchmark names) instead")
w("of Embree's BVH over the quads (`/0`).")
w("")
w("Commands: " + ", ".join(cmd("trace_%d" % n) + " with `GISSAR_BENCH_DEM=fractal_%d.tif`" % n
                            for n in (1024, 2048, 4096)) + ".")
w("")
w("Target: tracer ≥ 60 %% of raw Embree. Reached here: %s (%s)." % (
    ", ".join("%d²: %.0f %%" % (n, 100 * r) for n, r in ratios.items()),
    verdict(min(ratios.values()) >= 0.6)))
w("")

# ---------------------------------------------------------------- scene build
w("## Scene build: BVH and constrained Delaunay triangulation")
w("")
w("BVH (`BM_BvhBuild` in the same runs): build time and the resident memory it adds (Embree's")
w("copy of the mesh included). DEM meshes go into Embree as quads (16.8 M for 4096² posts).")
w("`simulate` picks medium quality for grids of any size (`EmbreeScene`, `BvhQuality::kAuto`;")
w("low quality with compact leaves only for non-grid meshes above 4 Mi triangles).")
w("")
w("| posts | triangles | quality | build s | triangles/s | memory |")
w("|---|---|---|---|---|---|")
for n in (1024, 2048, 4096):
    bm = benchmarks("trace_%d.json" % n)
    for arg in (1, 2):
        b = bm.get("BM_BvhBuild/%d/iterations:1/real_time" % arg)
        if b is None:
            continue
        seconds = b["real_time"] / 1e3
        w("| %d² | %.1f M | %s | %.2f | %.1f M | %.0f MiB |" % (
            n, b["triangles"] / 1e6, b["label"], seconds, b["triangles"] / seconds / 1e6, b["added_MiB"]))
    for arg in (0, 1):
        raw = bm["BM_RawEmbreeStream/%d/iterations:2/real_time" % arg]
        label = "height field (no BVH over the terrain)" if arg else raw["label"] + " (automatic: the BVH of the throughput runs)"
        w("| %d² | %.1f M | %s | %.2f | %.1f M | %.0f MiB |" % (
            n, raw["triangles"] / 1e6, label, raw["bvh_build_s"], raw["triangles"] / raw["bvh_build_s"] / 1e6,
            raw["bvh_added_MiB"]))
w("")
w("GIS scene (`scene_build_bench`: DEM window plus 5,000 random water/forest/urban polygons, read,")
w("triangulated (the cells the polygons touch with CGAL's constrained Delaunay triangulation, the")
w("others split directly), classes assigned; one iteration each; peak RSS of the process so far):")
w("")
w("| posts | polygons | triangles | cells through the CDT | seconds | posts/s | peak RSS |")
w("|---|---|---|---|---|---|---|")
scene_rows = load("scene_build.json")["benchmarks"]
for b in scene_rows:
    seconds = b["real_time"]  # unit: s
    w("| %d² | %d | %.1f M | %.1f %% | %.1f | %.2f M | %.2f GiB |" % (
        int(round(b["posts"] ** 0.5)), b["polygons"], b["triangles"] / 1e6, 100.0 * b.get("cdt_cell_share", 1.0),
        seconds, b["posts_per_s"] / 1e6, b["peak_rss_MiB"] / 1024.0))
w("")
w("Command: " + cmd("scene_build") + ".")
w("")
largest = max(scene_rows, key=lambda b: b["posts"])
if int(round(largest["posts"] ** 0.5)) == 4096:
    ok = largest["real_time"] <= 15.0 and largest["peak_rss_MiB"] <= 2048.0
    w("Target: 4096² + 5,000 polygons in ≤ 15 s and ≤ 2 GiB. Reached here: %.1f s, %.2f GiB (%s)." % (
        largest["real_time"], largest["peak_rss_MiB"] / 1024.0, verdict(ok)))
    w("")

# ---------------------------------------------------------------- raster
w("## DEM-raster engine (`--engine raster`) and memory bandwidth, 4096²")
w("")
bm = benchmarks("raster_4096.json")
raster = [b for name, b in bm.items() if name.startswith("BM_RasterCells")][0]
stream = [b for name, b in bm.items() if name.startswith("BM_StreamTriad")][0]
ms = raster["real_time"]
cells_per_s = raster["cells_per_s"]
w("| figure | value |")
w("|---|---|")
w("| DEM cells | %.1f M |" % (raster["cells"] / 1e6))
w("| image | %.1f M pixels |" % (raster["image_pixels"] / 1e6))
w("| render time after loading (mean of %d) | %.0f ms |" % (raster["iterations"], ms))
w("| cells/s | %.1f M |" % (cells_per_s / 1e6))
w("| STREAM triad, same process | %.1f GB/s |" % (stream["bytes_per_s"] / 1e9))
w("| bytes of post data per second at that rate (12 B/post) | %.2f GB/s |" % (cells_per_s * 12 / 1e9))
floor = {int(name.split("/")[1]): b for name, b in bm.items() if name.startswith("BM_SplatFloor/")}
if {0, 1, 2} <= floor.keys():
    w("| floor of this sampling, same process: posts projected, six bilinear splats per cell, nothing else | %.0f ms, %.1f M cells/s |" % (
        floor[0]["real_time"], floor[0]["cells_per_s"] / 1e6))
    w("| of which the projection / per-triangle arithmetic / splats | %.0f / %.0f / %.0f ms |" % (
        floor[1]["real_time"], floor[2]["real_time"] - floor[1]["real_time"], floor[0]["real_time"] - floor[2]["real_time"]))
w("")
w("Command: `GISSAR_BENCH_DEM=fractal_4096.tif " + commands["raster_4096"] + "`. The floor (`BM_SplatFloor`)")
w("samples the image as the engine does (each triangle's power splatted bilinearly at its three edge")
w("midpoints), without horizons, shadow, layover, mask or classes: the engine does all of this and")
w("more (bench/PROFILES.md: what else was measured against this floor).")
w("")
w("Target (issue 18): ≥ 100 M cells/s on 2 threads (4096² in ≤ 168 ms). Reached here: %.1f M cells/s, %.0f ms (%s)." % (
    cells_per_s / 1e6, ms, verdict(cells_per_s >= 100e6)))
w("")

# ---------------------------------------------------------------- agreement
w("## Raster engine against the ray tracer on Andorra")
w("")
w("SRTM3 Andorra (data/andorra, voids filled), depression 40 deg, pixels of the post spacing,")
w("tracer at 16 rays per cell, single bounce. Pearson r of the dB images where both are non-zero;")
w("mask pixels that differ, and those not explained by an edge within one pixel (must be 0).")
w("")
w("| heading | image | r (dB) | flagged mask pixels | differing | unexplained | raster s | tracer s (with BVH) |")
w("|---|---|---|---|---|---|---|---|")
for h in (0, 30, 135, 250):
    j = json.loads(read("agree_%d.out" % h))
    w("| %d | %d × %d | %.4f | %d | %d | %d | %.3f | %.2f |" % (
        h, j["image"][0], j["image"][1], j["db_pearson"], j["mask_flagged_pixels"],
        j["mask_differing_pixels"], j["mask_differing_away_from_edges"], j["raster_seconds"],
        j["trace_seconds_with_bvh"]))
w("")
w("Commands: " + ", ".join(cmd("agree_%d" % h) for h in (0, 30, 135, 250)) + ".")
w("")

# ---------------------------------------------------------------- POV-Ray
w("## Side by side with POV-Ray (the engine RaySAR is built on)")
w("")
probe = load("ours_pov_1.json")
w("The same 1000 × 1000-post heightfield (16-bit PGM for POV-Ray, the identical quantised heights")
w("as a GeoTIFF for gissar), 10 km × 10 km × 800 m, seen along the same look direction (depression")
w("40 deg): POV-Ray with an orthographic camera and a parallel light along it (its shadows are the")
w("radar shadow), 1000 × 1000 and 4000 × 4000 rays, no anti-aliasing, 2 worker threads; gissar with")
w("the rays per cell that give %.2f M and %.2f M primary rays (fixed sampling). One bounce: POV-Ray" % (
    probe["stats"]["rays"] / 1e6, load("ours_pov16_1.json")["stats"]["rays"] / 1e6))
w("`max_trace_level 1`, diffuse only;")
w("three levels: `max_trace_level 3` with `reflection 0.3`, gissar `--bounces 3`. Whole process,")
w("wall time, both including parsing or loading and building their acceleration structure; at 1 M rays")
w("the median of three runs of each, alternating.")
w("")
w("Rendering alone: POV-Ray's own \"Trace Time\" (camera, shadow and reflected rays) against")
w("gissar's trace and mask phases (primary and later bounces, and the visibility rays of the")
w("layover/shadow mask), from the same runs.")
w("")
w("| rays | reflection levels | POV-Ray wall s | gissar wall s | whole process: POV-Ray / gissar | POV-Ray trace s | gissar trace + mask s | rendering: POV-Ray / gissar |")
w("|---|---|---|---|---|---|---|---|")
pov_ratios = {}
render_ratios = {}
for tag, rays in (("pov", "1 M"), ("pov16", "16 M")):
    for levels in (1, 3):
        pov, _ = wall_rss("%s_%d" % (tag, levels))
        ours, _ = wall_rss("ours_%s_%d" % (tag, levels))
        j = load("ours_%s_%d.json" % (tag, levels))
        pov_trace = float(re.search(r"Trace Time:.*?\(([0-9.]+) seconds\)", read("%s_%d.err" % (tag, levels)),
                                    re.S).group(1))
        ours_render = j["timings_s"]["trace"] + j["timings_s"]["mask"]
        pov_ratios.setdefault(tag, []).append(pov / ours)
        render_ratios.setdefault(tag, []).append(pov_trace / ours_render)
        w("| %s | %d | %.2f | %.2f | %.1f× | %.2f | %.2f | %.1f× |" % (
            rays, levels, pov, ours, pov / ours, pov_trace, ours_render, pov_trace / ours_render))
w("")
w("Commands: " + ", ".join(cmd(k) for k in ("pov_probe", "pov_1", "ours_pov_1", "pov16_1", "ours_pov16_1", "pov_3",
                                           "ours_pov_3", "pov16_3", "ours_pov16_3")) +
  " (scene files `pov_1.pov`, `pov_3.pov` written by scripts/bench.sh).")
w("")
w("Target (issue 18): ≥ 3× POV-Ray at 1 M rays and ≥ 10× at 16 M rays, whole process. Reached here: 1 M rays %s (%s); "
  "16 M rays %s (%s). Rendering alone: %s at 1 M, %s at 16 M." % (
    ", ".join("%.1f×" % r for r in pov_ratios["pov"]), verdict(min(pov_ratios["pov"]) >= 3.0),
    ", ".join("%.1f×" % r for r in pov_ratios["pov16"]), verdict(min(pov_ratios["pov16"]) >= 10.0),
    ", ".join("%.1f×" % r for r in render_ratios["pov"]), ", ".join("%.1f×" % r for r in render_ratios["pov16"])))
w("")
w("Target (issue 47): ≥ 5× POV-Ray at 1 M rays and ≥ 12× at 16 M rays, whole process. Reached here: %s (%s); %s (%s)." % (
    ", ".join("%.1f×" % r for r in pov_ratios["pov"]), verdict(min(pov_ratios["pov"]) >= 5.0),
    ", ".join("%.1f×" % r for r in pov_ratios["pov16"]), verdict(min(pov_ratios["pov16"]) >= 12.0)))
w("")

# ---------------------------------------------------------------- exact geometry against sarsen
#: sarsen's wall times for the same job on this machine (issue 47; sarsen is not installable here, so it was
#: measured outside the project on the same inputs).
SARSEN_S = {500: 2.5, 1000: 5.1, 2000: 8.5, 4000: 32.8}
if os.path.exists(os.path.join(R, "exact_raster_500.time")):
    w("## The user path: exact geometry on Andorra, side by side with sarsen")
    w("")
    w("Andorra's filled SRTM reprojected to UTM 31N (`gdalwarp -r cubic`), a 27 km square centred on it at")
    w("N × N posts (spacing 27000/N m); `simulate --mode exact` (a straight track, zero-Doppler, 60 km slant")
    w("range, depression 45 deg, heading -0.9438 deg), pixels of the post spacing, one bounce, default outputs")
    w("(GeoTIFF with overviews, mask, quicklooks, sidecars). Whole process, wall time (the median of three runs")
    w("of each engine, alternating) and peak RSS (the largest of the three). sarsen")
    w("(bopen/sarsen, the xarray/Dask DEM simulator) is not installable here (no Python package index): its times")
    w("for the same job on this machine are those measured outside the project (issue 47), not in this run,")
    w("so the ratios compare this run with those figures.")
    w("")
    w("| posts | image | raster s | raster × sarsen | trace s | trace × sarsen | sarsen s | peak RSS raster / trace | trace run: terrain / trace / mask / write s |")
    w("|---|---|---|---|---|---|---|---|---|")
    exact_ratios = {"raster": [], "trace": []}
    for n in (500, 1000, 2000, 4000):
        raster, raster_rss = wall_rss("exact_raster_%d" % n)
        trace, trace_rss = wall_rss("exact_trace_%d" % n)
        jr = load("exact_raster_%d.json" % n)
        jt = load("exact_trace_%d.json" % n)
        t = jt["timings_s"]
        exact_ratios["raster"].append(SARSEN_S[n] / raster)
        exact_ratios["trace"].append(SARSEN_S[n] / trace)
        w("| %d² | %d × %d | %.2f | %.1f× | %.2f | %.1f× | %.1f | %.2f / %.2f GiB | %.2f / %.2f / %.2f / %.2f |" % (
            n, jr["geometry"]["width"], jr["geometry"]["height"], raster, SARSEN_S[n] / raster, trace, SARSEN_S[n] / trace, SARSEN_S[n],
            raster_rss / GIB, trace_rss / GIB, t.get("terrain", 0.0), t.get("trace", 0.0), t.get("mask", 0.0),
            t.get("write", 0.0)))
    w("")
    w("Commands: " + ", ".join(cmd(k) for k in ("andorra_utm", "andorra_4000", "exact_raster_4000",
                                               "exact_trace_4000")) + " (the other sizes alike).")
    w("")
    w("Target (issue 47): ≥ 10× sarsen with the raster engine and ≥ 5× with the tracer at every size. Reached "
      "here: raster %s (%s), trace %s (%s)." % (
          ", ".join("%.1f×" % r for r in exact_ratios["raster"]), verdict(min(exact_ratios["raster"]) >= 10.0),
          ", ".join("%.1f×" % r for r in exact_ratios["trace"]), verdict(min(exact_ratios["trace"]) >= 5.0)))
    w("")

# ---------------------------------------------------------------- corridor
if os.path.exists(os.path.join(R, "corridor.json")):
    c = load("corridor.json")
    w("## Reference-image corridor on Dask (`gissar corridor`), 1 and 2 workers")
    w("")
    im = c["image"]
    w("`gissar.distributed.build_corridor` on an embedded LocalCluster (worker processes, one task thread")
    w("each, every simulation capped at one thread): %d poses %g m apart on Andorra (SRTM 3\"), heading 90," % (
        c["poses"], c["pose_step_m"]))
    w("%d × %d px at %g m, %g rays per cell, 3 bounces. Poses/s over the simulation phase (first task" % (
        im["width"], im["height"], im["range_spacing_m"], im["rays_per_cell"]))
    w("submitted to the catalogue written); cluster start-up apart. Peak worker RSS: the largest ru_maxrss")
    w("of the worker processes. Task s per pose: wall time inside a task; task CPU s: the worker's user +")
    w("system time during it (below the wall time when other jobs share the cores). Load average when it")
    w("ended: %s (%d cores)." % (", ".join("%.2f" % x for x in c["load_average"]), c["cores"]))
    w("")
    w("| workers | poses/s | speed-up | simulation phase s | cluster start s | task s per pose | task CPU s per pose | peak worker RSS |")
    w("|---|---|---|---|---|---|---|---|")
    base = c["results"][0]["poses_per_s"]
    for r in c["results"]:
        w("| %d | %.3f | %.2f× | %.1f | %.1f | %.2f | %.2f | %.0f MiB |" % (
            r["workers"], r["poses_per_s"], r["poses_per_s"] / base, r["simulate_s"], r["startup_s"],
            r["task_s_per_pose"], r["cpu_s_per_pose"], r["peak_worker_rss_bytes"] / MIB))
    w("")
    # Load-independent view: the share of the phase the workers spent inside tasks (the rest is Dask's
    # scheduling and the submitting process), and the poses/s if every task had had a core to itself.
    est = []
    for r in c["results"]:
        busy = r["task_s_per_pose"] * r["poses"] / (r["workers"] * r["simulate_s"])
        est.append(r["workers"] * busy / r["cpu_s_per_pose"])
        w("- %d worker(s): busy in tasks %.1f %% of the phase; CPU share of a task %.0f %%; poses/s at one free "
          "core per worker %.3f." % (r["workers"], 100 * busy, 100 * r["cpu_s_per_pose"] / r["task_s_per_pose"],
                                    est[-1]))
    w("- speed-up at one free core per worker: %.2f×." % (est[-1] / est[0]))
    w("")
    w("Command: `PYTHONPATH=build/python python3 " + re.sub(r" --json \S+", "", commands["corridor"].split(" ", 1)[1])
      + "` (docs/distributed.md).")
    w("")
    speedup = c["results"][-1]["poses_per_s"] / base
    w("Target: ≥ 1.7× with 2 workers. Reached here: %.2f× measured (%s), %.2f× at one free core per worker." % (
        speedup, verdict(speedup >= 1.7), est[-1] / est[0]))
    w("")

if os.path.exists(os.path.join(R, "corridor_512.json")):
    c = load("corridor_512.json")
    im, r = c["image"], c["results"][-1]
    w("### 512 × 512 references, 2 workers")
    w("")
    w("The same corridor, %d poses of %d × %d px at %g m (%g rays per cell, 3 bounces), on %d workers: "
      "**%.2f poses/s** (task %.2f s and CPU %.2f s per pose, simulation phase %.1f s, peak worker RSS %.0f MiB; "
      "load average when it ended: %s)." % (
          c["poses"], im["width"], im["height"], im["range_spacing_m"], im["rays_per_cell"], r["workers"],
          r["poses_per_s"], r["task_s_per_pose"], r["cpu_s_per_pose"], r["simulate_s"],
          r["peak_worker_rss_bytes"] / MIB, ", ".join("%.2f" % x for x in c["load_average"])))
    w("")
    w("Command: `PYTHONPATH=build/python python3 "
      + re.sub(r" --json \S+", "", commands["corridor_512"].split(" ", 1)[1]) + "`.")
    w("")
    w("Target (issue 47): ≥ 4 poses/s. Reached here: %.2f poses/s (%s)." % (
        r["poses_per_s"], verdict(r["poses_per_s"] >= 4.0)))
    w("")

# ---------------------------------------------------------------- pose fixes, pinned command
if os.path.exists(os.path.join(R, "evaluate_andorra.json")):
    e = load("evaluate_andorra.json")
    sp, err = e["seconds_per_fix"], e["position_error_cells"]
    wall, rss = wall_rss("evaluate_andorra")
    w("## Pose fixes on the Andorra pinned command (`evaluate`)")
    w("")
    w("The scene as `make demo` builds it (%s), then the pinned command of docs/navigation.md: %s. "
      "Load average when it started: %s." % (cmd("andorra_scene"), cmd("evaluate_andorra"),
                                              read("evaluate_load.txt").split("load average:")[-1].strip()))
    w("")
    w("| trials | success | median error (cells) | p95 error (cells) | s per fix median | s per fix p95 | run wall s | peak RSS MiB |")
    w("|---|---|---|---|---|---|---|---|")
    w("| %d | %.1f %% | %.2f | %.2f | %.3f | %.3f | %.1f | %.0f |" % (
        e["trials"], 100 * e["success_rate"], err["median"], err["p95"], sp["median"], sp["p95"], wall, rss / MIB))
    w("")
    w("Target (issue 47): ≤ 0.3 s per fix with success unchanged (200/200 before): %.3f s, %.1f %% (%s)." % (
        sp["median"], 100 * e["success_rate"], verdict(sp["median"] <= 0.3 and e["success_rate"] >= 0.995)))
    w("")

# ---------------------------------------------------------------- gissar view
if os.path.exists(os.path.join(R, "view.json")):
    v = load("view.json")
    w("## `gissar view`: a %d-pose corridor in headless Chromium" % v["poses"])
    w("")
    w("bench/view_bench.py: a real corridor catalogue (`%s`, %.1f s), shown by `gissar view CATALOG "
      "--no-browser` in headless Chromium %s (selenium, window %s), each time with a cold render cache. First "
      "paint: navigation start to the map's first complete render with every footprint and the hillshade "
      "(the page's `data-ready-ms`; warm: the same page loaded again). Click to image: a real click at a "
      "footprint's centre to the complete render with that pose's image on the map (`data-image-ms`; "
      "selenium's view in the last column). On demand: the pose has no geocoded image, the viewer geocodes it "
      "(gissar's geocode, cached); stored: after `%s` (%.1f s, no pose simulated again)." % (
          v["corridor_command"], v["corridor_s"], v["chromium"], v["window"], v["geocode_command"],
          v["geocode_s"]))
    w("Load average when it ended: %s (%d cores, %s)." % (
        ", ".join("%.2f" % x for x in v["load_average"]), v["cores"], v["machine"]))
    w("")
    w("| geocoded images | footprints drawn | first paint cold s | first paint warm s | click to image median s | max s | selenium median s |")
    w("|---|---|---|---|---|---|---|")
    import statistics as _st
    for label, key in (("on demand", "on_demand"), ("stored (`--geocode`)", "stored")):
        m = v[key]
        w("| %s | %d | %.2f | %.2f | %.2f | %.2f | %.2f |" % (
            label, m["footprints"], m["first_paint_cold_s"], m["first_paint_warm_s"],
            _st.median(m["click_to_image_s"]), max(m["click_to_image_s"]),
            _st.median(m["click_to_image_selenium_s"])))
    w("")
    w("Command: `PYTHONPATH=build/python python3 " + re.sub(r" --json \S+", "", commands["view_bench"].split(" ", 1)[1])
      + "` (docs/view.md).")
    w("")
    worst_paint = max(v[k]["first_paint_cold_s"] for k in ("on_demand", "stored"))
    worst_click = max(max(v[k]["click_to_image_s"]) for k in ("on_demand", "stored"))
    w("Targets: first paint ≤ 2 s: worst %.2f s (%s); image ≤ 1 s after a click: worst %.2f s (%s)." % (
        worst_paint, verdict(worst_paint <= 2.0), worst_click, verdict(worst_click <= 1.0)))
    w("")

# ---------------------------------------------------------------- reference database
if os.path.exists(os.path.join(R, "database.json")):
    d = load("database.json")
    w("## Pose fixes from stored references against rendered ones (`evaluate --database`)")
    w("")
    w("bench/database_bench.py: the database of docs/navigation.md (`%s`: %d of %d poses done, %.1f s), then "
      "`gissar evaluate --database PREFIX_catalog.json --no-compare` with the same seed twice: the stored "
      "references and `--database-fixes render` (on the fly), so the same observed images and priors in both "
      "rows. Seconds per fix: the evaluation's `seconds_per_fix` (terrain and references loaded once, "
      "excluded). Load average when it ended: %s (%d cores)." % (
          d["corridor_command"], d["done"], d["poses"], d["corridor_s"],
          ", ".join("%.2f" % x for x in d["load_average"]), d["cores"]))
    w("")
    w("| fixes | trials | success | median error (cells) | p95 error (cells) | s per fix median | s per fix p95 | run wall s |")
    w("|---|---|---|---|---|---|---|---|")
    for r in d["rows"]:
        e, sp = r["position_error_cells"], r["seconds_per_fix"]
        w("| %s | %d | %.1f %% | %.2f | %.2f | %.3f | %.3f | %.1f |" % (
            "stored references" if r["fixes"] == "stored" else "on the fly (`--database-fixes render`)",
            r["trials"], 100 * r["success_rate"], e["median"], e["p95"], sp["median"], sp["p95"], r["wall_s"]))
    w("")
    ratio = d["ratio_render_over_stored"]
    w("Commands: " + "; ".join("`%s`" % r["command"] for r in d["rows"]) + ".")
    w("")
    w("Target (issue 45): ≥ 10× fewer seconds per fix from stored references: median %.1f×, p95 %.1f× (%s)." % (
        ratio["median"], ratio["p95"], verdict(ratio["median"] >= 10.0)))
    w("")

# ---------------------------------------------------------------- profiles
notes = os.path.join(ROOT, "bench", "PROFILES.md")
if os.path.exists(notes):
    with open(notes) as f:
        w(f.read().rstrip())
    w("")
print("\n".join(out))
