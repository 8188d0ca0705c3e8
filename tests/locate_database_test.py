"""Pose fixes from a reference database (issue 45, item 2; docs/navigation.md "Fixes from a reference database"):
`gissar corridor` builds a small database on the bundled Andorra DEM (3 poses x 2 headings, 96 x 96 px at 60 m),
then `gissar locate --database PREFIX_catalog.json`:
- an observed image simulated near a stored pose (speckled, another heading and depression) is fixed within
  2 cells from the stored reference, which the result JSON names, with no rendering;
- a database built from another DEM (the raw Andorra DEM) is refused naming both SHA-256 hashes (exit 2);
- a prior outside every stored footprint is no fix (exit 3) with the reason in the result JSON, and
  `--database-fallback render` then renders on the fly;
- a corrupted catalogue is exit 2 naming the file;
and `gissar evaluate --database` runs trials around the stored poses.

Usage: locate_database_test.py GISSAR_BINARY SOURCE_DIR (needs the Python package beside the binary, as
`gissar corridor` does). About 40 s on 2 cores.
"""
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

failures = []
checks = [0]


def check(condition, what):
    checks[0] += 1
    if not condition:
        failures.append(what)
        print("FAIL:", what, file=sys.stderr)


def run(args, cwd):
    return subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=600)


def ecef(lon, lat, h):
    """WGS84 geocentric coordinates (PROJ) of a geodetic point."""
    from pyproj import Transformer
    return Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True).transform(lon, lat, h)


def ecef_of_enu(origin, enu):
    """Geocentric coordinates of a point of the ENU tangent frame at origin (PROJ's topocentric conversion)."""
    from pyproj import Transformer
    from pyproj.enums import TransformDirection
    topocentric = Transformer.from_pipeline(
        f"+proj=topocentric +ellps=WGS84 +lon_0={origin[0]!r} +lat_0={origin[1]!r} +h_0={origin[2]!r}")
    return topocentric.transform(*enu, direction=TransformDirection.INVERSE)


def true_sensor(sidecar):
    """ECEF of the sensor of a simulation (its sidecar JSON)."""
    with open(sidecar, encoding="utf-8") as f:
        s = json.load(f)
    frame = s["frame"]
    return ecef_of_enu((frame["origin_lon_deg"], frame["origin_lat_deg"], frame["origin_height_m"]),
                       s["geometry"]["sensor_enu_m_at_centre"])


def corridor(gissar, work, dem, prefix, route, headings, extra=()):
    r = run([gissar, "corridor", *extra, "--route", route, "--dem", dem, "--pose-step", "2000", "--headings", headings,
             "--width", "96", "--height", "96", "--range-spacing", "60", "--azimuth-spacing", "60",
             "--rays-per-cell", "1", "--workers", "2", "--quiet", "--out", prefix], work)
    check(r.returncode == 0, f"corridor {prefix} exits 0 ({r.returncode}: {r.stderr.strip()[-400:]})")
    return prefix + "_catalog.json"


def main(gissar, source):
    work = tempfile.mkdtemp(prefix="gissar-locate-database-")
    dem = os.path.join(source, "data", "andorra", "andorra_srtm3_dem_filled.tif")
    other_dem = os.path.join(source, "data", "andorra", "andorra_srtm3_dem_raw.tif")
    with open(os.path.join(work, "route.csv"), "w", encoding="utf-8") as f:
        f.write("lon,lat\n1.50,42.55\n1.56,42.55\n")
    catalog = corridor(gissar, work, dem, "db", "route.csv", "80,100")
    with open(os.path.join(work, catalog), encoding="utf-8") as f:
        cat = json.load(f)
    database = cat.get("gissar:database", {})
    check(database.get("terrain") == "dem" and len(database.get("terrain_sha256") or "") == 64,
          f"the catalogue states the DEM's SHA-256 ({database})")
    done = [p for p in cat["gissar:poses"] if p["status"] == "done"]
    check(len(done) == 6 and all("reference" in p for p in done), "6 done poses, each with its reference entry")
    ref = done[0].get("reference", {})
    for key in ("image", "mask", "heading_deg", "depression_deg", "slant_range_m", "sensor_lon_lat_h",
                "centre_lon_lat_h", "look_direction_enu", "flight_direction_enu", "u0", "v0", "range_spacing_m"):
        check(key in ref, f"a reference entry holds {key}")

    # The observed image: near the stored pose p0000_h080 (its centre about 300 m away, heading +2 deg,
    # depression +1 deg), speckled, rendered with more rays than the database.
    r = run([gissar, "simulate", "--dem", dem, "--center", "1.5200,42.4850", "--heading", "82", "--depression", "41",
             "--width", "96", "--height", "96", "--range-spacing", "60", "--azimuth-spacing", "60",
             "--speckle-looks", "4", "--rays-per-cell", "2", "--seed", "3", "--quiet", "--out", "obs"], work)
    check(r.returncode == 0, f"simulate the observed image ({r.stderr.strip()[-300:]})")
    truth = true_sensor(os.path.join(work, "obs.json"))
    with open(os.path.join(work, "prior.json"), "w", encoding="utf-8") as f:
        json.dump({"heading_deg": 80.5, "depression_deg": 40.5, "slant_range_m": 10000,
                   "centre_lonlat": [1.518, 42.4835]}, f)
    locate = [gissar, "locate", "--image", "obs.tif", "--dem", dem, "--prior", "prior.json"]

    r = run(locate + ["--database", catalog, "--out", "fix_db"], work)
    check(r.returncode == 0, f"locate --database exits 0 ({r.returncode}: {r.stderr.strip()[-300:]})")
    if r.returncode == 0:
        with open(os.path.join(work, "fix_db.json"), encoding="utf-8") as f:
            fix = json.load(f)
        error_m = math.dist(ecef(*fix["pose"]["sensor_lon_lat_h"]), truth)
        print(f"locate --database: {error_m:.1f} m from the true sensor ({error_m / 60:.2f} cells), "
              f"{fix['seconds']:.2f} s, used {[u['id'] for u in fix['database']['used']]}")
        check(fix["converged"], "the database fix converged")
        check(error_m <= 2 * 60.0, f"the database fix is within 2 cells of the truth ({error_m:.1f} m)")
        check(abs(fix["pose"]["heading_deg"] - 82.0) <= 0.2, f"heading within 0.2 deg ({fix['pose']['heading_deg']})")
        check(fix["renders"] == 0 and fix["database"]["stored_reference_warps"] > 0, "no rendering in the fix")
        check(fix["database"]["used"] and fix["database"]["used"][0]["id"] == "p0000_h080",
              f"the result names the stored reference used ({fix['database']['used']})")

    # A database of another DEM: refused with both hashes.
    other = corridor(gissar, work, other_dem, "other", "route.csv", "80", ["--fill-nodata"])
    r = run(locate + ["--database", other, "--out", "fix_other"], work)
    check(r.returncode == 2, f"another DEM's database: exit 2 ({r.returncode})")
    check("SHA-256" in r.stderr and "another DEM" in r.stderr and other in r.stderr,
          f"the refusal names the hashes and the catalogue ({r.stderr.strip()})")
    check(not os.path.exists(os.path.join(work, "fix_other.json")), "nothing written on a refusal")

    # A prior outside every stored footprint: no fix, with the reason.
    with open(os.path.join(work, "far.json"), "w", encoding="utf-8") as f:
        json.dump({"heading_deg": 80.5, "depression_deg": 40.5, "slant_range_m": 10000,
                   "centre_lonlat": [1.70, 42.45]}, f)
    far = [gissar, "locate", "--image", "obs.tif", "--dem", dem, "--prior", "far.json", "--database", catalog]
    r = run(far + ["--out", "fix_far"], work)
    check(r.returncode == 3, f"a prior outside the database: exit 3 ({r.returncode}: {r.stderr.strip()[-300:]})")
    if os.path.exists(os.path.join(work, "fix_far.json")):
        with open(os.path.join(work, "fix_far.json"), encoding="utf-8") as f:
            fix = json.load(f)
        check(not fix["converged"] and "no stored reference covers the prior" in (fix["reason"] or ""),
              f"the no-fix result says why ({fix.get('reason')})")
    else:
        check(False, "the no-fix result JSON is written")
    check("no stored reference covers the prior" in r.stderr, "stderr states the reason")

    # No covering reference (heading tolerance 0.1 deg: the prior is 0.4 deg off the nearest) with the fallback:
    # the fix renders on the fly.
    r = run(locate + ["--database", catalog, "--database-heading-tolerance", "0.1", "--database-fallback", "render",
                      "--out", "fix_fallback"], work)
    check(r.returncode == 0, f"fallback render: exit 0 ({r.returncode}: {r.stderr.strip()[-300:]})")
    if r.returncode == 0:
        with open(os.path.join(work, "fix_fallback.json"), encoding="utf-8") as f:
            fix = json.load(f)
        check(fix["database"]["fallback"] == "render" and fix["renders"] > 0 and not fix["database"]["used"],
              "the fallback fix rendered and says so")

    # A corrupted catalogue: exit 2 naming the file.
    with open(os.path.join(work, catalog), encoding="utf-8") as f:
        text = f.read()
    with open(os.path.join(work, "broken_catalog.json"), "w", encoding="utf-8") as f:
        f.write(text[: len(text) // 2])
    r = run(locate + ["--database", "broken_catalog.json", "--out", "fix_broken"], work)
    check(r.returncode == 2 and "broken_catalog.json" in r.stderr and "not JSON" in r.stderr,
          f"a corrupted catalogue: exit 2 naming it ({r.returncode}: {r.stderr.strip()})")

    # evaluate --database: trials around the stored poses, fixed from the stored references.
    r = run([gissar, "evaluate", "--dem", dem, "--database", catalog, "--trials", "4", "--no-compare", "--quiet",
             "--out", "eval_db"], work)
    check(r.returncode == 0, f"evaluate --database exits 0 ({r.returncode}: {r.stderr.strip()[-300:]})")
    if r.returncode == 0:
        with open(os.path.join(work, "eval_db.json"), encoding="utf-8") as f:
            summary = json.load(f)
        print(f"evaluate --database: success {summary['success_rate']:.2f}, "
              f"{summary['seconds_per_fix']['median']:.3f} s per fix")
        check(summary["database"]["fixes"] == "stored" and summary["resolution_cell_m"] == 60.0,
              "the summary records the database and its cell")
        check(summary["success_rate"] >= 0.75, f"evaluate --database succeeds ({summary['success_rate']})")

    if failures:
        print(f"{len(failures)} of {checks[0]} checks failed (inputs kept in {work})", file=sys.stderr)
        return 1
    shutil.rmtree(work, ignore_errors=True)
    print(f"{checks[0]} checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main(os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])))
