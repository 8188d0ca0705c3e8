"""The Python package as a Python user meets it (issue 20): rasters in as paths, GDAL datasets, NumPy arrays
with a transform and a CRS or rioxarray DataArrays; xarray out with coordinates in metres, band names, units
and masks with flag names; pickling through a process pool; read-only scene attributes; Ctrl-C; tqdm."""
import concurrent.futures
import inspect
import multiprocessing
import os
import pathlib
import pickle
import shutil
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import gissar

ROOT = os.environ.get("GISSAR_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
DEM = os.path.join(ROOT, "data", "andorra", "andorra_srtm3_dem_filled.tif")
COARSE = dict(heading_deg=30.0, depression_deg=40.0, range_spacing_m=250.0, azimuth_spacing_m=250.0)
WINDOW = (150, 70, 120, 100)


@pytest.fixture(scope="module")
def utm_dem():
    """The Andorra DEM resampled to UTM 31N (EPSG:32631), 200 m posts, as an array + GDAL transform."""
    from osgeo import gdal
    ds = gdal.Warp("", DEM, format="MEM", dstSRS="EPSG:32631", xRes=200, yRes=200, resampleAlg="bilinear",
                   outputType=gdal.GDT_Float32, dstNodata=np.nan)
    return ds.GetRasterBand(1).ReadAsArray(), ds.GetGeoTransform()


def test_numpy_dem_in_utm_equals_the_cli_with_metre_coordinates(utm_dem, tmp_path):
    from osgeo import gdal, osr
    heights, transform = utm_dem
    # The warp leaves no-data corners (NaN): filled, as --fill-nodata does.
    da = gissar.simulate(heights, transform=transform, crs=32631, heading_deg=0, depression_deg=40,
                         range_spacing_m=200, azimuth_spacing_m=200, fill_nodata=True)
    assert da.dims == ("band", "along_track_m", "slant_range_m")
    assert list(da["band"].values) == ["total", "single", "double", "triple"]  # three bounces traced
    assert da.attrs["units"] == "1" and da.attrs["radiometry"] == "sigma0"
    assert da["slant_range_m"].attrs["units"] == "m" and da["along_track_m"].attrs["units"] == "m"
    np.testing.assert_allclose(np.diff(da["slant_range_m"].values), 200.0)
    np.testing.assert_allclose(np.diff(da["along_track_m"].values), 200.0)
    g = da.gissar.geometry
    # The scene centre (u0, v0) is at the slant range of the geometry and 0 m along track.
    assert np.interp(g.u0, np.arange(da.sizes["slant_range_m"]), da["slant_range_m"].values) == \
        pytest.approx(g.slant_range_m)
    assert np.interp(g.v0, np.arange(da.sizes["along_track_m"]), da["along_track_m"].values) == \
        pytest.approx(0.0, abs=1e-9)
    assert da["mask"].attrs["flag_meanings"].split() == ["none", "layover", "shadow", "layover_and_shadow",
                                                         "outside_footprint"]
    assert list(da["mask"].attrs["flag_values"]) == [0, 1, 2, 3, 255]
    assert da.attrs["gissar_version"] == gissar.__version__ and '"heading_deg": 0' in da.attrs["options"]
    # The CLI on the same heights written to a GeoTIFF with the same transform and CRS.
    path = str(tmp_path / "utm.tif")
    out = gdal.GetDriverByName("GTiff").Create(path, heights.shape[1], heights.shape[0], 1, gdal.GDT_Float32)
    out.SetGeoTransform(transform)
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32631)
    out.SetSpatialRef(srs)
    out.GetRasterBand(1).WriteArray(heights)
    out = None
    subprocess.run([os.environ["GISSAR_CLI"], "simulate", "--dem", path, "--heading", "0", "--depression", "40",
                    "--range-spacing", "200", "--azimuth-spacing", "200", "--fill-nodata", "--out", str(tmp_path / "cli"),
                    "--quiet"], check=True, stdout=subprocess.DEVNULL)
    tif = gdal.Open(str(tmp_path / "cli.tif"))
    assert tif.RasterCount == da.sizes["band"] == 4
    for b in range(1, tif.RasterCount + 1):
        name = tif.GetRasterBand(b).GetDescription()
        assert np.array_equal(tif.GetRasterBand(b).ReadAsArray(), da.sel(band=name).values, equal_nan=True), name


def test_every_raster_form_gives_the_same_image(tmp_path):
    import rioxarray
    from osgeo import gdal
    from pyproj import CRS
    reference = gissar.simulate(DEM, **COARSE).values
    ds = gdal.Open(DEM)
    heights = ds.GetRasterBand(1).ReadAsArray()
    before = set(os.listdir(tmp_path))
    os.chdir(tmp_path)
    forms = {
        "pathlib.Path": dict(dem=pathlib.Path(DEM)),
        "gdal.Dataset": dict(dem=ds),
        "rioxarray DataArray": dict(dem=rioxarray.open_rasterio(DEM)),
        "array + WKT": dict(dem=heights, transform=ds.GetGeoTransform(), crs=ds.GetProjection()),
        "array + pyproj CRS": dict(dem=heights, transform=ds.GetGeoTransform(), crs=CRS.from_wkt(ds.GetProjection())),
    }
    for name, dem in forms.items():
        assert np.array_equal(gissar.simulate(**dem, **COARSE).values, reference, equal_nan=True), name
    assert set(os.listdir(tmp_path)) == before  # nothing written to disk
    with pytest.raises(gissar.ConfigError, match=r"needs transform= and crs= \(dem\)"):
        gissar.simulate(heights, **COARSE)
    with pytest.raises(gissar.ConfigError, match="must be a path, a GDAL dataset"):
        gissar.simulate(dem=3.5, **COARSE)
    with pytest.raises(gissar.ConfigError, match="a DataArray carries its own transform"):
        gissar.simulate(rioxarray.open_rasterio(DEM), crs=4326, **COARSE)


def test_a_scene_builds_from_an_array_and_a_dataarray_is_an_image(tmp_path):
    import rioxarray
    from osgeo import gdal
    ds = gdal.Open(DEM)
    heights = ds.GetRasterBand(1).ReadAsArray()
    a = gissar.Scene.build(heights, tmp_path / "a", window=WINDOW, transform=ds.GetGeoTransform(),
                           crs=ds.GetProjection())
    b = gissar.Scene.build(rioxarray.open_rasterio(DEM), str(tmp_path / "b"), window=WINDOW)
    c = gissar.Scene.build(DEM, str(tmp_path / "c"), window=WINDOW)
    assert np.array_equal(a.vertices_enu_m, c.vertices_enu_m) and np.array_equal(b.vertices_enu_m, c.vertices_enu_m)
    sim = c.simulate(heading_deg=0, depression_deg=40, range_spacing_m=60, azimuth_spacing_m=60)
    grey, _ = gissar.quicklook(sim)  # the DataArray's total band
    assert np.array_equal(grey, gissar.quicklook(sim.sel(band="total").values)[0])


def test_map_geometry_result_round_trips_through_rio_to_raster(tmp_path):
    """simulate(out_prefix=) writes the CLI's files; geocode makes the map product: a DataArray with x/y in
    metres and .rio.crs, which rio.to_raster writes and GDAL reads back with the same CRS and values."""
    from osgeo import gdal
    sim = gissar.simulate(DEM, out_prefix=tmp_path / "s", **COARSE)
    assert sim.attrs["outputs"] and all(os.path.exists(p) for p in sim.attrs["outputs"])
    tif = gdal.Open(str(tmp_path / "s.tif"))
    assert np.array_equal(tif.GetRasterBand(1).ReadAsArray(), sim.sel(band="total").values, equal_nan=True)
    assert np.array_equal(sim.values, gissar.simulate(DEM, **COARSE).values, equal_nan=True)
    m = gissar.geocode(sim, tmp_path / "m", crs=32631, pixel_size_m=250)
    assert m.dims == ("band", "y", "x") and list(m["band"].values)[0] == "total"
    assert m.rio.crs.to_epsg() == 32631
    np.testing.assert_allclose(np.diff(m.x.values), 250.0)
    np.testing.assert_allclose(np.diff(m.y.values), -250.0)
    assert m["layover_shadow"].attrs["flag_meanings"].startswith("none layover")
    inc = m["local_incidence_deg"].values  # > 90 deg: slopes facing away from the radar (shadow)
    assert 0 <= np.nanmin(inc) and np.nanmax(inc) <= 180 and np.nanmedian(inc) < 90
    assert np.isfinite(m.sel(band="total").values).mean() > 0.3
    m.rio.to_raster(str(tmp_path / "round.tif"))
    back = gdal.Open(str(tmp_path / "round.tif"))
    assert back.GetSpatialRef().GetAuthorityCode(None) == "32631"
    assert back.GetGeoTransform() == pytest.approx(gdal.Open(str(tmp_path / "m.tif")).GetGeoTransform())
    assert np.array_equal(back.GetRasterBand(1).ReadAsArray(), m.sel(band="total").values, equal_nan=True)


# ---------------------------------------------------------------- pickling

def _project_in_worker(g):
    return g.project(np.array([[100.0, 50.0, 20.0]]))


def _triangles_in_worker(scene):
    return len(scene.triangles), scene.sha256


def _mean_in_worker(da):
    return float(da.sel(band="total").mean()), da.gissar.geometry.u0


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return gissar.Scene.build(DEM, str(tmp_path_factory.mktemp("pickle") / "s"), window=WINDOW)


def test_objects_pickle_through_a_process_pool(scene):
    g = gissar.SarGeometry(heading_deg=33.3, depression_deg=41.1, range_spacing_m=1.7, azimuth_spacing_m=2.9,
                           look_side="left", mode="exact", slant_range_m=12345.6, scene_centre_enu_m=(1.5, -2.5, 300.25),
                           u0=100.5, v0=90.25, width=201, height=181)
    again = pickle.loads(pickle.dumps(g))
    for name in ("heading_deg", "depression_deg", "range_spacing_m", "azimuth_spacing_m", "look_side", "mode",
                 "slant_range_m", "scene_centre_enu_m", "u0", "v0", "width", "height"):
        assert getattr(again, name) == getattr(g, name), name
    sim = scene.simulate(heading_deg=0, depression_deg=40, range_spacing_m=90, azimuth_spacing_m=90)
    # Scenes travel as path + hash (+ the build summary): a pickle is small whatever the mesh.
    assert len(pickle.dumps(scene)) < 0.05 * scene.vertices_enu_m.nbytes
    with concurrent.futures.ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork")) as pool:
        projected = pool.submit(_project_in_worker, g).result()
        triangles, sha = pool.submit(_triangles_in_worker, scene).result()
        mean, u0 = pool.submit(_mean_in_worker, sim).result()
    np.testing.assert_array_equal(projected, g.project(np.array([[100.0, 50.0, 20.0]])))
    assert triangles == len(scene.triangles) and sha == scene.sha256
    assert mean == pytest.approx(float(sim.sel(band="total").mean())) and u0 == sim.gissar.geometry.u0
    for error in (gissar.Error, gissar.ConfigError, gissar.MissingFileError, gissar.Cancelled):
        assert type(pickle.loads(pickle.dumps(error("x")))) is error


def test_a_pickled_scene_refuses_a_missing_or_changed_file(scene, tmp_path):
    copy = str(tmp_path / "copy.gscene")
    shutil.copyfile(scene.path, copy)
    blob = pickle.dumps(gissar.Scene(copy))
    assert len(pickle.loads(blob).triangles) == len(scene.triangles)
    with open(copy, "ab") as f:
        f.write(b"\0")
    with pytest.raises(gissar.InputError, match="changed since the Scene was pickled"):
        pickle.loads(blob)
    os.remove(copy)
    with pytest.raises(FileNotFoundError, match="scene file does not exist here"):
        pickle.loads(blob)


def test_scene_attributes_are_read_only(scene):
    for name, value in (("path", "x.gscene"), ("triangles", np.zeros((1, 3))), ("class_names", []),
                        ("centre_enu_m", (0, 0, 0)), ("summary", {}), ("heading_deg", 3)):
        with pytest.raises(AttributeError):
            setattr(scene, name, value)
    g = gissar.SarGeometry(heading_deg=0, depression_deg=40)
    with pytest.raises(AttributeError):
        g.heading_deg = 10


# ---------------------------------------------------------------- Ctrl-C and progress

# A stop within this many seconds of Ctrl-C, where finishing would take minutes.
CTRL_C_STOP_S = 15.0


def _seconds_from_ctrl_c_to_stop(call):
    """Runs `call` on this (main) thread, sends it SIGINT after 1 s from a timer thread, checks that it ends
    with KeyboardInterrupt and returns the seconds from the signal to that end."""
    main = threading.get_ident()
    started = {}

    def interrupt():
        time.sleep(1.0)
        started["t"] = time.perf_counter()
        signal.pthread_kill(main, signal.SIGINT)

    timer = threading.Thread(target=interrupt)
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        call()
    stopped = time.perf_counter()
    timer.join()
    return stopped - started["t"]


def test_ctrl_c_interrupts_a_long_simulation():
    # Minutes of tracing at this size: stopped within seconds of Ctrl-C (the bound leaves room for a loaded
    # machine: the stages before tracing check for cancellation between steps, not inside them).
    assert _seconds_from_ctrl_c_to_stop(
        lambda: gissar.simulate(DEM, heading_deg=0, depression_deg=40, range_spacing_m=10, azimuth_spacing_m=10,
                                rays_per_cell=16)) < CTRL_C_STOP_S


def test_scene_build_and_sequence_report_progress_and_stop_on_request(tmp_path):
    """Scene.build reports its steps as stage "scene build" (the last with done == total); a progress callback
    returning False (what Ctrl-C does through the same hook) stops it with gissar.Cancelled, and so does a
    sequence, before its first frame is written."""
    osm = os.path.join(ROOT, "data", "andorra", "andorra_osm.gpkg")
    seen = []
    gissar.Scene.build(DEM, tmp_path / "s", vectors=[osm], window=WINDOW,
                       progress=lambda stage, done, total: seen.append((stage, done, total)))
    steps = [(d, t) for stage, d, t in seen if stage == "scene build"]
    assert steps and steps[-1][0] == steps[-1][1] and all(0 < d <= t for d, t in steps), seen
    with pytest.raises(gissar.Cancelled):
        gissar.Scene.build(DEM, tmp_path / "c", vectors=[osm], window=WINDOW,
                           progress=lambda stage, done, total: False)
    assert not (tmp_path / "c.gscene").exists()
    with pytest.raises(gissar.Cancelled):
        gissar.sequence(tmp_path / "q", 0, 60, frames=3, dem=DEM, depression_deg=40, range_spacing_m=250,
                        azimuth_spacing_m=250, progress=lambda stage, done, total: False)
    assert not list(tmp_path.glob("q_f*.tif"))


def test_ctrl_c_interrupts_a_sequence(tmp_path):
    # Minutes of tracing per frame at this size: stopped within seconds of Ctrl-C.
    assert _seconds_from_ctrl_c_to_stop(
        lambda: gissar.sequence(tmp_path / "seq", 0, 90, frames=4, dem=DEM, depression_deg=40, range_spacing_m=10,
                                azimuth_spacing_m=10, rays_per_cell=16)) < CTRL_C_STOP_S


def test_progress_true_draws_a_tqdm_bar(monkeypatch):
    import tqdm.auto
    bars = []

    class Bar(tqdm.auto.tqdm):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            bars.append(self)

    monkeypatch.setattr(tqdm.auto, "tqdm", Bar)
    gissar.simulate(DEM, progress=True, **COARSE)
    assert bars and bars[-1].desc == "simulate: tracing" and bars[-1].n == bars[-1].total
    seen = []
    gissar.simulate(DEM, progress=lambda *a: seen.append(a), **COARSE)
    assert seen


def test_every_name_in_the_type_hints_exists():
    import ast
    hints = os.path.join(os.path.dirname(gissar.__file__), "__init__.pyi")
    tree = ast.parse(open(hints).read())
    names = [n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))]
    assert len(names) > 30
    missing = [n for n in names if not hasattr(gissar, n)]
    assert not missing, missing
    public = [n for n in dir(gissar) if not n.startswith("_") and callable(getattr(gissar, n))]
    assert not [n for n in public if n not in names], "not in the type hints (__init__.pyi)"


def test_simulate_type_hints_name_only_request_fields():
    """The .pyi's simulate keywords are fields of the request's table (a renamed or removed field fails here);
    the others reach it through **request, as gissar.simulate's signature lists them all."""
    import ast
    hints = os.path.join(os.path.dirname(gissar.__file__), "__init__.pyi")
    tree = ast.parse(open(hints).read())
    hinted = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "simulate")
    named = [a.arg for a in hinted.args.args + hinted.args.kwonlyargs]
    fields = {f["name"] for f in gissar._core.simulate_request_fields()}
    doors = {"dem", "scene", "transform", "crs", "nodata", "progress", "out_prefix"}
    assert hinted.args.kwarg is not None and hinted.args.kwarg.arg == "request"
    assert not [n for n in named if n not in fields | doors]
    signature = inspect.signature(gissar.simulate).parameters
    assert not [f for f in fields if f not in signature and f not in ("max_memory_bytes",)]


def test_request_fields_are_each_commands_table():
    """request_fields(command) gives each table in its order: simulate's as simulate_request_fields(); the
    geocode table's keys are gissar.geocode's keywords and its sidecar's options; the scene build table's flags
    are those of `gissar scene build --help`; another name is a ConfigError naming it."""
    assert gissar._core.request_fields("simulate") == gissar._core.simulate_request_fields()
    geocode = gissar._core.request_fields("geocode")
    assert [f["name"] for f in geocode] == ["image", "dem", "vertical_datum", "crs", "pixel_size_m", "resampling",
                                           "out_prefix"]
    assert set(inspect.signature(gissar.geocode).parameters) == {f["name"] for f in geocode}
    assert next(f for f in geocode if f["name"] == "resampling")["default"] == "bilinear"
    scene = {f["name"]: f for f in gissar._core.request_fields("scene_build")}
    assert scene["export_obj"]["flag"] == "--obj" and scene["window"]["default"] is None
    assert scene["vectors"]["default"] == [] and scene["max_memory_bytes"]["help"] == ""
    assert set(scene) == set(inspect.signature(gissar.Scene.build).parameters) - {
        "transform", "crs", "nodata", "progress"} | {"center_lonlat", "sea", "sea_level_m", "dem_oversample",
                                                     "vertical_units", "flat_shading", "reflectors",
                                                     "max_memory_bytes"}
    for command in ("evaluate", "locate"):
        assert {f["name"] for f in gissar._core.request_fields(command)} == set(
            getattr(gissar._core, command + "_request_defaults")())
    with pytest.raises(gissar.ConfigError, match="unknown request 'scene'"):
        gissar._core.request_fields("scene")
    with pytest.raises(gissar.ConfigError, match=r"unknown key 'pixel_size'; did you mean pixel_size_m\?"):
        gissar._core.geocode({"image": "a.tif", "out_prefix": "m", "pixel_size": 10})
