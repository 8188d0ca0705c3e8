"""gissar.distributed / `gissar corridor`: reference-image databases along a route on Dask (docs/distributed.md).

A 2-worker LocalCluster (worker processes, loopback) shared by the module: a corridor of >= 20 poses over the
bundled Andorra DEM whose images equal the single-process gissar.simulate bit for bit, a run that loses a
worker (SIGKILL) mid-way and still equals it, a re-run that simulates nothing, the catalogue against the STAC
schemas, and the command line.
"""
import csv
import glob
import json
import os
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import gissar
from gissar import distributed as gd

distributed = pytest.importorskip("distributed")

ROOT = os.environ.get("GISSAR_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
DEM = os.path.join(ROOT, "data", "andorra", "andorra_srtm3_dem_filled.tif")
SCHEMAS = os.path.join(ROOT, "tests", "data", "stac_schemas")
# The DEM covers lon 1.3996..1.7996, lat 42.4204..42.6704. Along lat 42.60 the scene centres of a right-looking
# sensor at headings 80/100 deg lie ~7.66 km south (slant range 10 km, depression 40 deg): the first and last
# poses' 64 x 64 px footprints (90 m pixels: 7.5 km across, 5.8 km along) leave the DEM.
ROUTE = [(1.42, 42.60), (1.61, 42.60), (1.80, 42.60)]
STEP_M = 2000.0
HEADINGS = [80.0, 100.0]
IMAGE = dict(width=64, height=64, range_spacing_m=90.0, azimuth_spacing_m=90.0, rays_per_cell=1.0, depression_deg=40.0)


@pytest.fixture(scope="module")
def reference(client, tmp_path_factory):
    """The undisturbed corridor: (prefix, catalogue)."""
    prefix = str(tmp_path_factory.mktemp("corridor") / "ref")
    catalog = gd.build_corridor(ROUTE, dem=DEM, pose_step_m=STEP_M, headings_deg=HEADINGS, out_prefix=prefix,
                                client=client, threads=1, progress=None, **IMAGE)
    return prefix, catalog


def bands(path):
    """{band name: array} of a simulation's GeoTIFF, plus its mask."""
    from osgeo import gdal
    ds = gdal.Open(path + ".tif")
    out = {ds.GetRasterBand(b).GetDescription(): ds.GetRasterBand(b).ReadAsArray() for b in range(1, ds.RasterCount + 1)}
    mask = gdal.Open(path + "_mask.tif")  # keep the dataset alive while reading its band
    out["mask"] = mask.GetRasterBand(1).ReadAsArray()
    return out


def done_ids(catalog):
    return [p["id"] for p in catalog["gissar:poses"] if p["status"] == "done"]


def test_poses_ids_and_scene_centres():
    poses = gd.corridor_poses(ROUTE, pose_step_m=STEP_M, headings_deg=HEADINGS)
    # 2 x ~15.6 km of route: poses at 0, 2, ..., 30 km (16) times 2 headings, ids in route order.
    assert len(poses) == 32
    assert [p["id"] for p in poses[:3]] == ["p0000_h080", "p0000_h100", "p0001_h080"]
    assert poses[2]["distance_m"] == STEP_M
    # The scene centre: the ground range 10 km * cos(40 deg) = 7660.44 m to the right of the heading.
    from pyproj import Geod
    az, _, dist = Geod(ellps="WGS84").inv(poses[0]["lon_deg"], poses[0]["lat_deg"], poses[0]["center_lon_deg"],
                                          poses[0]["center_lat_deg"])
    assert abs(dist - 7660.444431) < 1e-3 and abs(az - 170.0) < 1e-6
    left = gd.corridor_poses(ROUTE, pose_step_m=STEP_M, headings_deg=[80.0], look_side="left")
    az, _, _ = Geod(ellps="WGS84").inv(left[0]["lon_deg"], left[0]["lat_deg"], left[0]["center_lon_deg"],
                                       left[0]["center_lat_deg"])
    assert abs(az - (-10.0)) < 1e-6
    assert gd.pose_id(7, 90) == "p0007_h090" and gd.pose_id(7, 22.5) == "p0007_h022p5"
    assert gd.pose_id(3, -90) == "p0003_h270"


def test_corridor_images_equal_the_single_process_simulation(reference):
    prefix, catalog = reference
    s = catalog["gissar:summary"]
    assert s["poses"] == 32 and s["failed"] == 0 and s["done"] >= 20 and s["skipped"] >= 2, s
    assert s["done"] + s["skipped"] == s["poses"] and s["workers"] == 2
    for pose in catalog["gissar:poses"]:
        if pose["status"] != "done":
            assert pose["status"] == "skipped" and pose["reason"].startswith(
                ("footprint leaves the DEM", "scene centre outside the DEM")), pose
            assert not os.path.exists(f"{prefix}_{pose['id']}.tif")
            continue
        mine = gissar.simulate(DEM, center_lonlat=pose["center_lonlat_deg"], heading_deg=pose["heading_deg"],
                               **IMAGE)
        theirs = bands(f"{prefix}_{pose['id']}")
        # Three bounces traced: total, single, double, triple (no four-or-more band), as the GeoTIFF.
        assert list(mine["band"].values) == ["total", "single", "double", "triple"]
        assert sorted(theirs) == sorted(list(mine["band"].values) + ["mask"])
        for name in mine["band"].values:
            assert np.array_equal(theirs[name], mine.sel(band=name).values, equal_nan=True), (pose["id"], name)
        assert np.array_equal(theirs["mask"], mine["mask"].values), pose["id"]
        # The references keep the GCP lattice (tps_gcps off by default: no refinement for gdalwarp -tps).
        with open(f"{prefix}_{pose['id']}.json", encoding="utf-8") as f:
            georeference = json.load(f)["georeference"]
        assert georeference["tps_refinement"]["enabled"] is False and georeference["tps_refinement"]["added_gcps"] == 0
        assert 100 <= georeference["gcps"] <= 40 * 40, georeference
    # The first and last poses are the skipped ones (their footprints cross the DEM's west and east edges).
    skipped = [p["id"] for p in catalog["gissar:poses"] if p["status"] == "skipped"]
    assert "p0000_h080" in skipped and "p0015_h100" in skipped


def load_store():
    store = {}
    for base, _, names in os.walk(SCHEMAS):
        for name in names:
            if name.endswith(".json"):
                with open(os.path.join(base, name)) as f:
                    schema = json.load(f)
                uri = schema["$id"].rstrip("#")
                store[uri] = store[uri + "#"] = schema
    return store


ITEM_SCHEMA = "https://schemas.stacspec.org/v1.0.0/item-spec/json-schema/item.json"
COLLECTION_SCHEMA = "https://schemas.stacspec.org/v1.0.0/collection-spec/json-schema/collection.json"


def validate_stac(document, schema, store):
    """Validates a STAC Item or Collection against the published core schema and its extensions' schemas."""
    import jsonschema
    for uri in [schema] + document.get("stac_extensions", []):
        assert uri in store, uri
        try:
            import referencing
            import referencing.jsonschema
            registry = referencing.Registry().with_resources(
                (u, referencing.Resource.from_contents(s, default_specification=referencing.jsonschema.DRAFT7))
                for u, s in store.items())
            validator = jsonschema.Draft7Validator(store[uri], registry=registry)
        except ImportError:  # Debian bookworm's jsonschema 4.10
            validator = jsonschema.Draft7Validator(
                store[uri], resolver=jsonschema.RefResolver(base_uri=uri, referrer=store[uri], store=store))
        validator.validate(document)


def test_catalogue_is_a_stac_collection_of_valid_items_and_a_csv_index(reference):
    from osgeo import ogr
    prefix, catalog = reference
    with open(prefix + "_catalog.json") as f:
        assert json.load(f) == json.loads(json.dumps(catalog))
    # A valid STAC 1.0.0 Collection (the published collection-spec schema).
    store = load_store()
    validate_stac(catalog, COLLECTION_SCHEMA, store)
    assert catalog["type"] == "Collection" and catalog["stac_version"] == "1.0.0"
    lon0, lat0, lon1, lat1 = catalog["extent"]["spatial"]["bbox"][0]
    assert 1.39 < lon0 < lon1 < 1.81 and 42.42 < lat0 < lat1 < 42.61
    assert len(catalog["extent"]["temporal"]["interval"][0]) == 2
    items = [link["href"] for link in catalog["links"] if link["rel"] == "item"]
    assert len(items) == catalog["gissar:summary"]["done"]
    directory = os.path.dirname(prefix)
    for href in items:
        with open(os.path.join(directory, href)) as f:
            item = json.load(f)
        validate_stac(item, ITEM_SCHEMA, store)
        p = item["properties"]
        assert item["collection"] == catalog["id"] == "ref"
        assert p["gissar:heading_deg"] in HEADINGS and p["gissar:depression_deg"] == 40.0
        assert p["gissar:slant_range_m"] == 10000.0 and len(p["gissar:options_sha256"]) == 64
        assert abs(p["gissar:pose_lat_deg"] - 42.60) < 1e-4  # the geodesic bulges ~2 m north of the parallel
        for asset in item["assets"].values():
            assert os.path.exists(os.path.join(directory, asset["href"])), asset
        # The footprint (the product's georeferencing) lies around the scene centre, south of the route.
        ring = item["geometry"]["coordinates"][0]
        clon, clat = p["gissar:center_lonlat_deg"]
        assert min(x for x, _ in ring) < clon < max(x for x, _ in ring)
        assert min(y for _, y in ring) < clat < max(y for _, y in ring) < 42.60
    with open(prefix + "_index.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["id"] for r in rows] == [p["id"] for p in catalog["gissar:poses"]]
    assert list(rows[0]) == ["id", "lon", "lat", "heading_deg", "status", "footprint_wkt", "files", "reason"]
    for r in rows:
        polygon = ogr.CreateGeometryFromWkt(r["footprint_wkt"])
        assert polygon is not None and polygon.GetGeometryName() == "POLYGON" and polygon.GetArea() > 0
        if r["status"] == "done":
            assert f"ref_{r['id']}.tif" in r["files"].split() and f"ref_{r['id']}_done.json" in r["files"].split()
        else:
            assert r["status"] == "skipped" and r["files"] == "" and r["reason"].startswith(
                ("footprint leaves the DEM", "scene centre outside the DEM"))


def test_rerun_of_a_finished_database_does_no_work(reference):
    prefix, catalog = reference
    stamps = {path: os.stat(path).st_mtime_ns for path in glob.glob(prefix + "_p*")}
    started = time.perf_counter()
    # No client and no cluster: nothing to simulate, so none is started.
    again = gd.build_corridor(ROUTE, dem=DEM, pose_step_m=STEP_M, headings_deg=HEADINGS, out_prefix=prefix,
                              workers=2, threads=1, progress=None, **IMAGE)
    assert time.perf_counter() - started < 20.0
    s = again["gissar:summary"]
    assert s["tasks_submitted"] == 0 and s["simulated"] == 0 and s["workers"] == 0
    assert s["cached"] == s["done"] == catalog["gissar:summary"]["done"]
    assert {path: os.stat(path).st_mtime_ns for path in glob.glob(prefix + "_p*")} == stamps
    assert done_ids(again) == done_ids(catalog)


def test_changed_options_or_inputs_are_simulated_again(client, tmp_path):
    import shutil
    dem = str(tmp_path / "dem.tif")
    shutil.copyfile(DEM, dem)
    route = [(1.55, 42.60), (1.56, 42.60)]  # 0.82 km: one pose at 500 m steps, and the start
    args = dict(dem=dem, pose_step_m=500.0, headings_deg=[90.0], out_prefix=str(tmp_path / "c"), client=client,
                threads=1, progress=None, **IMAGE)
    assert gd.build_corridor(route, **args)["gissar:summary"]["simulated"] == 2
    assert gd.build_corridor(route, **args)["gissar:summary"]["simulated"] == 0
    assert gd.build_corridor(route, seed=2, **args)["gissar:summary"]["simulated"] == 2
    # The DEM's contents (sha256): a rewritten identical file is the same input, a changed one is not.
    shutil.copyfile(DEM, dem)
    assert gd.build_corridor(route, seed=2, **args)["gissar:summary"]["simulated"] == 0
    with open(dem, "r+b") as f:
        f.seek(os.path.getsize(dem) - 1)
        last = f.read(1)
        f.seek(-1, os.SEEK_END)
        f.write(bytes([last[0] ^ 1]))
    assert gd.build_corridor(route, seed=2, **args)["gissar:summary"]["simulated"] == 2
    # A done-marker whose file went missing: that pose again.
    os.unlink(str(tmp_path / "c_p0001_h090_mask.tif"))
    assert gd.build_corridor(route, seed=2, **args)["gissar:summary"]["simulated"] == 1


def test_killed_worker_is_retried_and_the_database_equals_the_undisturbed_one(client, reference, tmp_path):
    ref_prefix, ref_catalog = reference
    prefix = str(tmp_path / "ref")
    outcome = {}

    def run():
        try:
            outcome["catalog"] = gd.build_corridor(ROUTE, dem=DEM, pose_step_m=STEP_M, headings_deg=HEADINGS,
                                                   out_prefix=prefix, client=client, threads=1, progress=None,
                                                   **IMAGE)
        except BaseException as e:  # noqa: B902 (reported below)
            outcome["error"] = e

    thread = threading.Thread(target=run)
    thread.start()
    deadline = time.time() + 120
    while len(glob.glob(prefix + "_*_done.json")) < 3 and time.time() < deadline and thread.is_alive():
        time.sleep(0.05)
    pids = client.run(os.getpid)
    busy = [w for w, keys in client.processing().items() if keys]
    assert busy, "no worker is running a pose"
    os.kill(pids[busy[0]], signal.SIGKILL)
    thread.join(timeout=300)
    assert not thread.is_alive() and "error" not in outcome, outcome.get("error")
    catalog = outcome["catalog"]
    s = catalog["gissar:summary"]
    assert s["failed"] == 0 and s["done"] == ref_catalog["gissar:summary"]["done"], s
    assert len(glob.glob(prefix + "_*_done.json")) < s["done"] + 1
    assert done_ids(catalog) == done_ids(ref_catalog)
    for pose_id in done_ids(catalog):
        a, b = bands(f"{prefix}_{pose_id}"), bands(f"{ref_prefix}_{pose_id}")
        assert a.keys() == b.keys()
        for name in a:
            assert np.array_equal(a[name], b[name], equal_nan=True), (pose_id, name)
    # No temporaries left behind by the killed simulation once its pose was redone.
    leftovers = [n for n in os.listdir(tmp_path) if n.startswith(".gs-") and not n.endswith(".lock")]
    assert leftovers == [], leftovers
    client.wait_for_workers(2, timeout=120)  # the nanny restarted the worker


def test_a_killed_writers_temporaries_are_swept_for_its_file_only(tmp_path):
    # What a worker killed between writing a pose's marker and renaming it leaves behind, for this pose and
    # for another whose name starts the same: the retry of this pose removes its own only.
    ours = str(tmp_path / "ref_p0001_h080_done.json")
    other = str(tmp_path / "ref_p0001_h080_x_done.json")
    for path in (ours, other):
        leftover = gd._temporary_for(path)
        assert os.path.basename(leftover).startswith(".gs-" + os.path.basename(path) + "-")
        with open(leftover, "w") as f:
            f.write("{")
    gd._sweep_temporaries(ours)
    left = sorted(os.listdir(tmp_path))
    assert len(left) == 1 and left[0].startswith(".gs-ref_p0001_h080_x_done.json-"), left
    # A completed write leaves only its file.
    gd._write_atomic(ours, "{}\n")
    assert sorted(os.listdir(tmp_path)) == sorted(left + ["ref_p0001_h080_done.json"])


def test_route_and_keyword_errors(tmp_path):
    one = tmp_path / "one.csv"
    one.write_text("lon,lat\n1.5,42.5\n1.5,42.5\n")
    with pytest.raises(gissar.InputError, match=r"at least two distinct points, got 1 \(.*one.csv\)"):
        gd.read_route(str(one))
    with pytest.raises(gissar.InputError, match="at least two"):
        gd.build_corridor([(1.5, 42.5)], dem=DEM, pose_step_m=100, headings_deg=[0], out_prefix=str(tmp_path / "x"))
    geo = tmp_path / "r.geojson"
    geo.write_text(json.dumps({"type": "Feature", "geometry": {"type": "LineString",
                                                              "coordinates": [[1.5, 42.5], [1.6, 42.5]]}}))
    assert gd.read_route(str(geo)) == [(1.5, 42.5), (1.6, 42.5)]
    swapped = tmp_path / "r.csv"
    swapped.write_text("name,lat,lon\na,42.5,1.5\nb,42.6,1.5\n")
    assert gd.read_route(str(swapped)) == [(1.5, 42.5), (1.5, 42.6)]
    headerless = tmp_path / "h.csv"
    headerless.write_text("1.5,42.5\n1.5,42.6\n")
    assert gd.read_route(str(headerless)) == [(1.5, 42.5), (1.5, 42.6)]
    with pytest.raises(gissar.InputError, match="not a number"):
        headerless.write_text("1.5,42.5\n1.5,north\n")
        gd.read_route(str(headerless))
    with pytest.raises(gissar.MissingFileError):
        gd.read_route(str(tmp_path / "missing.csv"))
    common = dict(pose_step_m=100, headings_deg=[0], out_prefix=str(tmp_path / "x"))
    with pytest.raises(gissar.ConfigError, match="unknown keyword 'headin_deg'"):
        gd.build_corridor(ROUTE, dem=DEM, headin_deg=3, **common)
    with pytest.raises(gissar.ConfigError, match="did you mean depression_deg"):
        gd.build_corridor(ROUTE, dem=DEM, depresion_deg=40, **common)
    with pytest.raises(gissar.ConfigError, match="sets heading_deg"):
        gd.build_corridor(ROUTE, dem=DEM, heading_deg=3, **common)
    with pytest.raises(gissar.ConfigError, match="dem or scene"):
        gd.build_corridor(ROUTE, **common)
    with pytest.raises(gissar.ConfigError, match="pose_step_m"):
        gd.build_corridor(ROUTE, dem=DEM, **dict(common, pose_step_m=0))
    with pytest.raises(gissar.ConfigError, match="headings repeat"):
        gd.build_corridor(ROUTE, dem=DEM, **dict(common, headings_deg=[0, 360]))
    assert not list(tmp_path.glob("x*"))


def cli(*args, env=None):
    return subprocess.run([os.environ["GISSAR_CLI"], "corridor", *args], capture_output=True, text=True, env=env,
                          timeout=300)


@pytest.mark.skipif("GISSAR_CLI" not in os.environ, reason="needs the gissar executable (GISSAR_CLI)")
def test_command_line(client, tmp_path):
    help_run = cli("--help")
    assert help_run.returncode == 0 and "--pose-step" in help_run.stdout and "--scheduler" in help_run.stdout
    route = tmp_path / "route.csv"
    route.write_text("lon,lat\n1.55,42.55\n1.57,42.55\n")
    flags = ["--dem", DEM, "--pose-step", "1000", "--headings", "90,270", "--width", "32", "--height", "32",
             "--range-spacing", "90", "--azimuth-spacing", "90", "--rays-per-cell", "1"]
    # A running cluster, by its scheduler's address.
    out = str(tmp_path / "db")
    run = cli("--route", str(route), *flags, "--scheduler", client.scheduler.address, "--threads", "1",
              "--quiet", "--out", out)
    assert run.returncode == 0, run.stderr
    # The files, then the run's result line (on stdout even with --quiet).
    lines = run.stdout.splitlines()
    assert lines[:2] == [out + "_catalog.json", out + "_index.csv"] and run.stderr == ""
    assert len(lines) == 3 and lines[2].startswith("corridor: 4 poses: 4 done (0 already complete), 0 skipped, 0 failed")
    with open(out + "_catalog.json") as f:
        catalog = json.load(f)
    s = catalog["gissar:summary"]
    # 1.64 km of route: poses at 0 and 1000 m, two headings (scene centres 7.7 km south, then north: inside).
    assert s["poses"] == 4 and s["done"] == 4 and s["failed"] == 0, s
    assert {p["id"] for p in catalog["gissar:poses"]} == {"p0000_h090", "p0000_h270", "p0001_h090", "p0001_h270"}
    # The same database again: nothing simulated.
    again = cli("--route", str(route), *flags, "--scheduler", client.scheduler.address, "--quiet", "--out", out)
    assert again.returncode == 0, again.stderr
    with open(out + "_catalog.json") as f:
        assert json.load(f)["gissar:summary"]["simulated"] == 0
    # Errors: exit 2 with one line, nothing written.
    one = tmp_path / "one.csv"
    one.write_text("lon,lat\n1.55,42.55\n")
    for args, needle in [(["--route", str(one), *flags, "--out", str(tmp_path / "e")], "at least two distinct points"),
                         (["--route", str(route), *flags, "--pose-stepp", "3", "--out", str(tmp_path / "e")],
                          "did you mean --pose-step?"),
                         (["--route", str(route), "--dem", DEM, "--pose-step", "1000", "--out", str(tmp_path / "e")],
                          "required: --headings"),
                         (["--route", str(route), *flags, "--depression", "95", "--out", str(tmp_path / "e")],
                          "depression")]:
        bad = cli(*args)
        assert bad.returncode == 2, (args, bad.stderr)
        assert bad.stderr.startswith("gissar: error: ") and bad.stderr.count("\n") == 1, bad.stderr
        assert needle in bad.stderr, bad.stderr
    assert not list(tmp_path.glob("e*"))


@pytest.mark.skipif("GISSAR_CLI" not in os.environ, reason="needs the gissar executable (GISSAR_CLI)")
def test_defaults_fit_the_dem_and_a_route_off_the_dem_is_no_result(client, tmp_path):
    """A 13 km route across the bundled DEM with only --route --dem --pose-step --headings --out: every pose gets
    an image (the size is chosen to fit, <= 512 px); a route off the DEM: exit 3, the reason and the fix."""
    route = tmp_path / "route.csv"
    route.write_text("lon,lat\n1.45,42.545\n1.61,42.545\n")  # 13.1 km east along the DEM's middle latitude
    out = str(tmp_path / "db")
    run = cli("--route", str(route), "--dem", DEM, "--pose-step", "2000", "--headings", "0,90", "--out", out,
              "--scheduler", client.scheduler.address, "--quiet")
    assert run.returncode == 0, run.stderr
    with open(out + "_catalog.json") as f:
        catalog = json.load(f)
    s = catalog["gissar:summary"]
    assert s["poses"] == 14 and s["done"] == 14 and s["skipped"] == 0 and s["failed"] == 0, s
    size = catalog["gissar:image_size"]
    # By hand: heading 90 puts the first pose's scene centre 4.13 km east of the DEM's west edge (lon 1.45 vs
    # 1.3996, 82.0 km per degree of longitude at 42.5 deg): along track the image may span 2 x 4.13 km at the
    # DEM's mean 80.5 m posts, 102 px at most; every other pose leaves more room.
    assert 64 <= size["width"] == size["height"] <= 110 and size["rule"].startswith("auto"), size
    assert run.stdout.splitlines()[-1].startswith("corridor: 14 poses: 14 done"), run.stdout
    for pose in catalog["gissar:poses"]:
        assert os.path.exists(f"{out}_{pose['id']}.tif"), pose
    # Entirely off the DEM (40 km east of it): nothing to do is no result, with the reason and the flags.
    far = tmp_path / "far.csv"
    far.write_text("lon,lat\n2.30,42.545\n2.46,42.545\n")
    none = cli("--route", str(far), "--dem", DEM, "--pose-step", "2000", "--headings", "0,90",
               "--out", str(tmp_path / "far"), "--scheduler", client.scheduler.address, "--quiet")
    assert none.returncode == 3, (none.returncode, none.stderr)
    reasons = [line for line in none.stderr.splitlines() if line.startswith("gissar: no result: ")]
    assert len(reasons) == 1, none.stderr
    assert "14 of 14 poses skipped: their scene centre" in reasons[0] and "outside the DEM (32.8 x 27.8 km)" in \
        reasons[0] and "--route" in reasons[0], reasons
    assert "corridor: 14 poses: 0 done (0 already complete), 14 skipped" in none.stdout
    # A size the DEM cannot hold: skipped poses name the footprint, the DEM and the flags that fix it.
    big = cli("--route", str(route), "--dem", DEM, "--pose-step", "2000", "--headings", "0,90", "--width", "600",
              "--height", "600", "--out", str(tmp_path / "big"), "--scheduler", client.scheduler.address, "--quiet")
    assert big.returncode == 3, big.stderr
    assert "600 x 600 px footprint" in big.stderr and "give a smaller --width/--height" in big.stderr, big.stderr


@pytest.mark.skipif("GISSAR_CLI" not in os.environ, reason="needs the gissar executable (GISSAR_CLI)")
def test_corridor_flags_read_as_simulates(tmp_path):
    """Every flag the corridor shares with `gissar simulate` has the same help text and default, switches are
    --X/--no-X with their real default, and --no-overviews is accepted."""
    def options(text):
        rows, current = {}, None
        for line in text.splitlines():
            if line.startswith("  -"):
                # CLI11's layout: names in a 30-column left column, or alone on their line when longer.
                if "  " in line[2:30]:
                    names, _, description = line[2:].partition("  ")
                elif len(line) > 30 and line[29] == " ":
                    names, description = line[:30], line[30:]
                else:
                    names, description = line, ""
                current = names.split(",")[0].split()[0]
                rows[current] = (names.strip(), description.strip())
            elif current and line.startswith(" " * 30) and line.strip():
                names, description = rows[current]
                rows[current] = (names, (description + " " + line.strip()).strip())
        return rows
    simulate = subprocess.run([os.environ["GISSAR_CLI"], "simulate", "--help"], capture_output=True, text=True)
    corridor = cli("--help")
    assert simulate.returncode == 0 and corridor.returncode == 0
    ours, theirs = options(corridor.stdout), options(simulate.stdout)
    # Not compared: flags whose meaning differs (the corridor's size rule, per-pose outputs, the terrain every
    # worker must open, threads per simulation) and --depression (required by simulate, 40 by default here).
    shared = sorted(set(ours) & set(theirs) - {"--help", "--width", "--height", "--out", "--dem", "--scene",
                                                "--threads", "--options", "--depression"})
    assert len(shared) >= 25, shared
    for flag in shared:
        assert ours[flag] == theirs[flag], (flag, ours[flag], theirs[flag])
    assert ours["--overviews"][0].startswith("--overviews, --no-overviews") and "(default: on)" in ours["--overviews"][1]
    assert "{false}" not in simulate.stdout and "{false}" not in corridor.stdout
    parsed = __import__("gissar.corridor", fromlist=["make_parser"]).make_parser().parse_args(
        ["--route", "r", "--pose-step", "1", "--headings", "0", "--out", "o", "--no-overviews", "--fixed-sampling"])
    assert parsed.overviews is False and parsed.adaptive_sampling is False


@pytest.mark.skipif("GISSAR_CLI" not in os.environ, reason="needs the gissar executable (GISSAR_CLI)")
def test_command_line_embedded_cluster_geojson_route_and_options_file(tmp_path):
    route = tmp_path / "route.geojson"
    route.write_text(json.dumps({"type": "LineString", "coordinates": [[1.55, 42.60], [1.56, 42.60]]}))
    options = tmp_path / "job.json"
    options.write_text(json.dumps({"headings_deg": [90], "width": 32, "height": 32, "range_spacing_m": 90,
                                   "azimuth_spacing_m": 90, "rays_per_cell": 1, "seed": 3}))
    out = str(tmp_path / "db")
    run = cli("--route", str(route), "--dem", DEM, "--pose-step", "5000", "--options", str(options), "--workers", "1",
              "--out", out)
    assert run.returncode == 0, run.stderr
    assert "corridor: 1 poses: 1 done" in run.stdout  # the result line, on stdout
    with open(out + "_p0000_h090.json") as f:
        options_used = json.load(f)["options"]
    assert options_used["seed"] == 3 and options_used["width"] == 32 and options_used["heading_deg"] == 90.0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"headin_deg": 3}))
    run = cli("--route", str(route), "--dem", DEM, "--pose-step", "5000", "--headings", "0", "--options", str(bad),
              "--out", str(tmp_path / "e"))
    assert run.returncode == 2 and "unknown key 'headin_deg'; did you mean headings_deg?" in run.stderr
    assert run.stderr.count("\n") == 1


def test_scene_corridor_skips_poses_outside_the_scene(client, tmp_path):
    # A scene of DEM columns 150..270, rows 70..170: lon 1.5246..1.6246, lat 42.5288..42.6121.
    gissar.Scene.build(DEM, str(tmp_path / "s"), window=(150, 70, 120, 100))
    catalog = gd.build_corridor([(1.50, 42.62), (1.60, 42.62)], scene=str(tmp_path / "s.gscene"), pose_step_m=2000,
                                headings_deg=[90], out_prefix=str(tmp_path / "c"), width=32, height=32,
                                range_spacing_m=60.0, azimuth_spacing_m=60.0, rays_per_cell=1.0, client=client,
                                threads=1, progress=None)
    status = {p["id"]: p["status"] for p in catalog["gissar:poses"]}
    # Poses every 2 km from 1.50 E (0.0244 deg); footprints 1.9 km along track (+-0.0117 deg): the first two
    # reach west of the scene's 1.5249 E.
    assert status == {"p0000_h090": "skipped", "p0001_h090": "skipped", "p0002_h090": "done",
                      "p0003_h090": "done", "p0004_h090": "done"}, status
    reason = next(p["reason"] for p in catalog["gissar:poses"] if p["id"] == "p0000_h090")
    # Heading 90 puts the scene centres due south of the route points: lon 1.50 and 1.5244 are both west of the
    # scene's 1.5249 E, so these two are skipped for their centre, not only their footprint.
    assert reason.startswith("scene centre outside the scene"), reason
    reason = next(p["reason"] for p in catalog["gissar:poses"] if p["id"] == "p0001_h090")
    assert reason.startswith("scene centre outside the scene at lon 1.52438"), reason
    with pytest.raises(gissar.ConfigError, match="pixel spacings of a scene corridor"):
        gd.build_corridor([(1.50, 42.62), (1.56, 42.62)], scene=str(tmp_path / "s.gscene"), pose_step_m=1000,
                          headings_deg=[90], out_prefix=str(tmp_path / "d"), client=client)


def test_large_dem_corridor_runs_on_workers_with_less_memory_than_one_whole_dem_simulation(tmp_path):
    """Issue 21: a 4096 x 4096 DEM (30 m posts, 123 km square) that one simulation of the whole DEM could not
    hold in 1 GiB. The whole-DEM run (--dem-window off) is refused by the 1 GiB memory budget before it reads
    anything; the corridor's workers, limited to 1 GiB by Dask (the nanny restarts a worker above it) and by the
    same budget, read only the window under each 128 x 128 px image and finish every pose, and their images
    equal those of the whole DEM simulated without the budget."""
    from distributed import Client, LocalCluster
    from osgeo import gdal, osr
    n = 4096
    y, x = np.mgrid[0:n, 0:n].astype(np.float32)
    heights = (300.0 + 200.0 * np.sin(x / 300.0) * np.cos(y / 410.0) + 0.02 * x).astype(np.float32)
    path = str(tmp_path / "big.tif")
    ds = gdal.GetDriverByName("GTiff").Create(path, n, n, 1, gdal.GDT_Float32, ["TILED=YES"])
    ds.SetGeoTransform([400000.0, 30.0, 0.0, 4800000.0, 0.0, -30.0])
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32631)
    ds.SetProjection(srs.ExportToWkt())
    ds.GetRasterBand(1).WriteArray(heights)
    ds = None
    del heights, x, y
    budget = 1 << 30
    # The route crosses the middle of the DEM (lon/lat of its centre row, 20 km apart).
    from pyproj import Transformer
    to_lonlat = Transformer.from_crs(32631, 4326, always_xy=True)
    route = [to_lonlat.transform(400000.0 + 30.0 * n * f, 4800000.0 - 15.0 * n) for f in (0.4, 0.56)]
    image = dict(width=128, height=128, range_spacing_m=30.0, azimuth_spacing_m=30.0, rays_per_cell=1.0,
                 depression_deg=40.0, slant_range_m=10000.0, vertical_datum="ellipsoid", max_memory_bytes=budget)
    whole = dict(image, dem_window="off", center_lonlat=route[0], heading_deg=0.0)
    with pytest.raises((gissar.ConfigError, gissar.InputError), match="over the memory limit"):
        gissar.simulate(path, **whole)
    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, memory_limit=budget)
    try:
        with Client(cluster) as c:
            catalog = gd.build_corridor(route, dem=path, pose_step_m=5000.0, headings_deg=[0.0],
                                        out_prefix=str(tmp_path / "big"), client=c, threads=1, progress=None,
                                        **image)
            peak = max(c.run(lambda: __import__("resource").getrusage(0).ru_maxrss * 1024).values())
    finally:
        cluster.close()
    s = catalog["gissar:summary"]
    assert s["done"] >= 4 and s["failed"] == 0 and s["skipped"] == 0, s
    assert peak < budget, peak
    print(f"[ measured ] 4096^2 DEM corridor: {s['done']} poses on a 1 GiB worker, peak worker RSS "
          f"{peak / 2 ** 20:.0f} MiB")
    for pose in done_ids(catalog):
        with open(str(tmp_path / f"big_{pose}.json")) as f:
            record = json.load(f)["dem_window"]
        assert record["read"] == "window", record
        assert record["cols"] * record["rows"] < n * n / 20, record
    # The windowed images equal the monolithic run's (the whole DEM, no memory budget), bit for bit, for the
    # first and the last pose (each monolithic run meshes 16.8 M quads: ~20 s and ~3 GiB).
    done = [p for p in catalog["gissar:poses"] if p["status"] == "done"]
    monolithic = {k: v for k, v in image.items() if k != "max_memory_bytes"}
    for pose in (done[0], done[-1]):
        mine = gissar.simulate(path, dem_window="off", center_lonlat=pose["center_lonlat_deg"],
                               heading_deg=pose["heading_deg"], **monolithic)
        theirs = bands(str(tmp_path / f"big_{pose['id']}"))
        assert sorted(theirs) == sorted(list(mine["band"].values) + ["mask"])
        for name in mine["band"].values:
            assert np.array_equal(theirs[name], mine.sel(band=name).values, equal_nan=True), (pose["id"], name)
        assert np.array_equal(theirs["mask"], mine["mask"].values), pose["id"]


def test_geocode_writes_one_georeferenced_image_per_done_pose(client, tmp_path):
    """`gissar corridor --geocode` (build_corridor(geocode=True)): every done pose names its geocoded image
    (PREFIX_<id>_geocoded.tif, gissar's geocode), which exists, is georeferenced in a projected CRS and carries
    the layover/shadow band; the Item lists it. A --geocode re-run of a database built without it geocodes
    the complete poses without simulating them again; a second re-run does nothing."""
    from osgeo import gdal, osr
    route = [(1.55, 42.55), (1.57, 42.55)]
    args = dict(dem=DEM, pose_step_m=1000.0, headings_deg=[90.0, 270.0], out_prefix=str(tmp_path / "g"),
                client=client, threads=1, progress=None, width=32, height=32, range_spacing_m=90.0,
                azimuth_spacing_m=90.0, rays_per_cell=1.0)
    plain = gd.build_corridor(route, **args)
    assert all("geocoded" not in p for p in plain["gissar:poses"])
    stamps = {p: os.stat(p).st_mtime_ns for p in glob.glob(str(tmp_path / "g_p*.tif"))}
    catalog = gd.build_corridor(route, geocode=True, **args)
    s = catalog["gissar:summary"]
    assert s["simulated"] == 0 and s["done"] == 4 and s["cached"] == 4, s
    assert {p: os.stat(p).st_mtime_ns for p in stamps} == stamps, "no pose simulated again"
    for pose in catalog["gissar:poses"]:
        assert pose["status"] == "done"
        name = pose["geocoded"]
        assert name == f"g_{pose['id']}_geocoded.tif" and name in pose["files"]
        ds = gdal.Open(str(tmp_path / name))
        assert ds is not None and ds.RasterXSize > 0
        srs = osr.SpatialReference(wkt=ds.GetProjection())
        assert srs.IsProjected() and srs.GetAuthorityCode(None) == "32631"
        gt = ds.GetGeoTransform()
        assert gt[1] > 0 and gt[5] < 0 and gt[2] == gt[4] == 0
        names = [ds.GetRasterBand(b).GetDescription() for b in range(1, ds.RasterCount + 1)]
        assert names[0] == "total" and "layover_shadow" in names
        total = ds.GetRasterBand(1).ReadAsArray()
        assert np.isfinite(total).sum() > 0.3 * total.size
        with open(tmp_path / f"g_{pose['id']}_stac.json") as f:
            assert json.load(f)["assets"]["geocoded"]["href"] == name
    again = gd.build_corridor(route, geocode=True, **args)
    assert again["gissar:summary"]["tasks_submitted"] == 0
    assert [p.get("geocoded") for p in again["gissar:poses"]] == [p["geocoded"] for p in catalog["gissar:poses"]]
    # From the start with --geocode (the command line): simulated and geocoded in one task per pose.
    if "GISSAR_CLI" not in os.environ:
        return
    route_csv = tmp_path / "route.csv"
    route_csv.write_text("lon,lat\n1.55,42.55\n1.57,42.55\n")
    run = cli("--route", str(route_csv), "--dem", DEM, "--pose-step", "1000", "--headings", "90", "--width", "32",
              "--height", "32", "--range-spacing", "90", "--azimuth-spacing", "90", "--rays-per-cell", "1",
              "--scheduler", client.scheduler.address, "--threads", "1", "--quiet", "--geocode",
              "--out", str(tmp_path / "c"))
    assert run.returncode == 0, run.stderr
    with open(tmp_path / "c_catalog.json") as f:
        poses = json.load(f)["gissar:poses"]
    assert poses and all(os.path.isfile(tmp_path / p["geocoded"]) for p in poses)
