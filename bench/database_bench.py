#!/usr/bin/env python3
"""Pose fixes from stored references against fixes rendered on the fly (issue 45; docs/navigation.md, "Fixes
from a reference database").

Builds the reference database of docs/navigation.md with the real binary: `gissar corridor` on the bundled
Andorra DEM along lat 42.55 N from lon 1.45 to 1.70 E, a pose every 2 km, headings 80 and 100 deg, 96 x 96 px
at 60 m, 1 ray per cell (2 workers, 1 thread each). Then `gissar evaluate --database PREFIX_catalog.json
--no-compare` twice with the same seed, so the same observed images and priors in both rows: the stored
references (default `--database-fixes stored`) and `--database-fixes render` (on the fly). Reports seconds per
fix (median / p95, the evaluation's `seconds_per_fix`: loading the terrain and the references excluded), their
ratio, success rate and median / p95 position error in cells, and each run's wall time.

usage: python3 bench/database_bench.py [--gissar build/bin/gissar] [--trials 200] [--seed 7] [--out DIR]
                                       [--json F]
Prints a Markdown table; --json writes the figures (scripts/bench.sh, scripts/bench_report.py).
"""
import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
DEM = os.path.join(ROOT, "data", "andorra", "andorra_srtm3_dem_filled.tif")


def gissar(binary, *args):
    start = time.perf_counter()
    r = subprocess.run([binary, *args], capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if r.returncode not in (0, 3):
        sys.exit(f"database_bench: gissar {args[0]} failed ({r.returncode}): {r.stderr.strip()}")
    return seconds, r


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--gissar", default=os.environ.get("GISSAR_CLI") or os.path.join(ROOT, "build", "bin", "gissar"))
    p.add_argument("--trials", type=int, default=200)
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--out", default=None, help="work directory (default: a temporary one, removed)")
    p.add_argument("--json", default=None)
    args = p.parse_args()
    work = args.out or tempfile.mkdtemp(prefix="gissar-database-bench-")
    os.makedirs(work, exist_ok=True)

    def shown(cmd):
        """The command as the report prints it: paths relative to the source tree and the work directory."""
        return "gissar " + " ".join(cmd).replace(work + "/", "").replace(ROOT + "/", "")
    try:
        route = os.path.join(work, "route.csv")
        with open(route, "w") as f:
            f.write("lon,lat\n1.45,42.55\n1.70,42.55\n")
        prefix = os.path.join(work, "db")
        corridor_cmd = ["corridor", "--route", route, "--dem", DEM, "--pose-step", "2000", "--headings", "80,100",
                        "--width", "96", "--height", "96", "--range-spacing", "60", "--azimuth-spacing", "60",
                        "--rays-per-cell", "1", "--workers", "2", "--threads", "1", "--quiet", "--out", prefix]
        corridor_s, _ = gissar(args.gissar, *corridor_cmd)
        with open(prefix + "_catalog.json") as f:
            summary = json.load(f)["gissar:summary"]
        rows = []
        for label, extra in (("stored", []), ("render", ["--database-fixes", "render"])):
            out = os.path.join(work, "ev_" + label)
            cmd = ["evaluate", "--dem", DEM, "--database", prefix + "_catalog.json", "--no-compare",
                   "--trials", str(args.trials), "--seed", str(args.seed), "--threads", "2", "--quiet",
                   "--out", out, *extra]
            wall, _ = gissar(args.gissar, *cmd)
            with open(out + ".json") as f:
                ev = json.load(f)
            rows.append({"fixes": label, "command": shown(cmd),
                         "wall_s": wall, "trials": ev.get("trials"), "success_rate": ev.get("success_rate"),
                         "converged_rate": ev.get("converged_rate"),
                         "position_error_cells": ev.get("position_error_cells"),
                         "heading_error_deg": ev.get("heading_error_deg"),
                         "seconds_per_fix": ev.get("seconds_per_fix")})
        stored, render = rows
        ratio = {k: render["seconds_per_fix"][k] / stored["seconds_per_fix"][k] for k in ("median", "p95")}
        result = {"corridor_command": shown(corridor_cmd),
                  "corridor_s": corridor_s, "poses": summary["poses"], "done": summary["done"], "rows": rows,
                  "ratio_render_over_stored": ratio, "load_average": list(os.getloadavg()),
                  "cores": os.cpu_count(), "machine": platform.machine(), "date": time.strftime("%Y-%m-%d")}
    finally:
        if args.out is None:
            shutil.rmtree(work, ignore_errors=True)
    print(f"corridor: {result['done']} of {result['poses']} poses done in {corridor_s:.1f} s")
    print("| fixes | trials | success | median error (cells) | p95 error (cells) | s per fix median "
          "| s per fix p95 | run wall s |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        e, s = r["position_error_cells"] or {}, r["seconds_per_fix"] or {}
        nan = float("nan")
        print(f"| {r['fixes']} | {r['trials']} | {100 * (r['success_rate'] or 0):.1f} % "
              f"| {e.get('median', nan):.2f} | {e.get('p95', nan):.2f} | {s.get('median', nan):.3f} "
              f"| {s.get('p95', nan):.3f} | {r['wall_s']:.1f} |")
    print(f"render / stored seconds per fix: median {ratio['median']:.1f}x, p95 {ratio['p95']:.1f}x; "
          f"load average {', '.join(f'{x:.2f}' for x in result['load_average'])} ({result['cores']} cores)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
