"""A new user's first hour at the Python door: a mistyped keyword gets a suggestion, simulate needs the same
arguments as `gissar simulate`, and warnings and errors about a DEM array name the argument, not GDAL's in-memory
path (ctest python_first_hour; also part of python_tests' directory)."""
import inspect
import os
import subprocess
import warnings

import numpy as np
import pytest

import gissar

ROOT = os.environ.get("GISSAR_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
DEM = os.path.join(ROOT, "data", "andorra", "andorra_srtm3_dem_filled.tif")
COARSE = dict(range_spacing_m=250.0, azimuth_spacing_m=250.0)
UTM = dict(transform=(400000.0, 30.0, 0.0, 4700000.0, 0.0, -30.0), crs=32631)


# ---------------------------------------------------------------- did you mean

def test_a_mistyped_keyword_gets_a_suggestion():
    with pytest.raises(gissar.ConfigError, match=r"unknown key 'depresion_deg'; did you mean depression_deg\?"):
        gissar.simulate(DEM, heading_deg=30, depresion_deg=40)
    # The command line's spelling (the flag without its unit suffix) points at the keyword.
    with pytest.raises(gissar.ConfigError, match=r"unknown key 'heading'; did you mean heading_deg\?"):
        gissar.simulate(DEM, heading=30, depression_deg=40)
    with pytest.raises(gissar.ConfigError, match=r"unknown key 'range_spacing'; did you mean range_spacing_m\?"):
        gissar.raw.simulate(DEM, heading_deg=30, depression_deg=40, range_spacing=30)
    # Nothing close: no suggestion.
    with pytest.raises(gissar.ConfigError, match=r"unknown key 'colour' \(gissar.simulate keyword\)$"):
        gissar.simulate(DEM, heading_deg=30, depression_deg=40, colour="red")


def test_unknown_key_message_rules():
    known = list(gissar.simulate_request_defaults())
    assert gissar.unknown_key_message("headin_deg", known) == "unknown key 'headin_deg'; did you mean heading_deg?"
    assert gissar.unknown_key_message("Heading_Deg", known).endswith("did you mean heading_deg?")
    assert gissar.unknown_key_message("range-spacing-m", known).endswith("did you mean range_spacing_m?")
    assert gissar.unknown_key_message("center", known).endswith("did you mean center_lonlat?")
    assert gissar.unknown_key_message("depresion", known).endswith("did you mean depression_deg?")
    assert gissar.unknown_key_message("x", ["db"]) == "unknown key 'x'"
    assert gissar.unknown_key_message("speed_of_light", known) == "unknown key 'speed_of_light'"


def test_every_request_door_suggests():
    # SequenceRequest (a simulate request), LocateRequest and EvaluateRequest.
    with pytest.raises(gissar.ConfigError, match=r"did you mean range_spacing_m\?"):
        gissar.sequence("/nonexistent/q", 0, 60, frames=3, dem=DEM, depression_deg=40, range_spacing_mm=250)
    with pytest.raises(gissar.ConfigError, match=r"unknown key 'prodcut'; did you mean product\?"):
        gissar.locate_product(prodcut="x.h5")
    with pytest.raises(gissar.ConfigError, match=r"unknown key 'seeed'; did you mean seed\?"):
        gissar.evaluate_trials(seeed=3)
    # gissar.locate's keywords (a ConfigError, not pybind11's TypeError listing the signature).
    with pytest.raises(gissar.ConfigError, match=r"unknown key 'search'; did you mean search_px\? \(gissar.locate\)"):
        gissar.locate("/nonexistent.gscene", np.zeros((8, 8)), {}, 30, 30, search=20)


@pytest.fixture(scope="module")
def tiny_scene(tmp_path_factory):
    return gissar.Scene.build(DEM, str(tmp_path_factory.mktemp("scene") / "s"), window=(150, 70, 40, 40))


def test_locate_prior_and_view_3d_suggest(tiny_scene):
    prior = {"heading_dg": 30, "slant_range_m": 10000, "depression_deg": 40, "centre_enu_m": [0, 0, 0]}
    with pytest.raises(gissar.ConfigError, match=r"unknown key 'heading_dg'; did you mean heading_deg\?"):
        gissar.locate(tiny_scene, np.ones((16, 16), np.float32), prior, 30, 30)
    with pytest.raises(gissar.ConfigError, match=r"unknown option 'view_azimuth'; did you mean view_azimuth_deg\?"):
        tiny_scene.view_3d(view_azimuth=30)


# ---------------------------------------------------------------- required, as on the command line

def test_simulate_requires_heading_and_depression_as_the_cli_does():
    with pytest.raises(gissar.ConfigError, match=r"^is required \(heading_deg\)$"):
        gissar.simulate(DEM)
    with pytest.raises(gissar.ConfigError, match=r"^is required \(depression_deg\)$"):
        gissar.simulate(DEM, heading_deg=30)
    with pytest.raises(ValueError, match=r"is required \(heading_deg\)"):
        gissar.raw.simulate(DEM, depression_deg=40)
    with pytest.raises(gissar.ConfigError, match=r"is required \(heading_deg\)"):
        gissar._core.simulate(dem=DEM, depression_deg=40)
    if os.environ.get("GISSAR_CLI"):  # the command line says the same of its flags
        cli = subprocess.run([os.environ["GISSAR_CLI"], "simulate", "--dem", DEM, "--out", "/nonexistent/x"],
                             capture_output=True, text=True)
        assert cli.returncode != 0 and "--heading" in cli.stderr and "required" in cli.stderr, cli.stderr
    # total, then single, double and triple: the default three bounces (no four-or-more band)
    assert gissar.simulate(DEM, heading_deg=30, depression_deg=40, **COARSE).sizes["band"] == 4


def test_the_signatures_show_them_required():
    params = inspect.signature(gissar.simulate).parameters
    for name in ("heading_deg", "depression_deg"):
        assert params[name].default is inspect.Parameter.empty and params[name].kind is params[name].KEYWORD_ONLY
        assert f"{name}: required" in gissar.simulate.__doc__
    assert params["slant_range_m"].default == gissar.simulate_request_defaults()["slant_range_m"]
    scene_params = inspect.signature(gissar.Scene.simulate).parameters
    assert scene_params["heading_deg"].default is inspect.Parameter.empty
    sequence_params = inspect.signature(gissar.sequence).parameters
    assert sequence_params["depression_deg"].default is inspect.Parameter.empty
    assert sequence_params["frames"].default == 7


def test_scene_simulate_and_sequence_require_them(tiny_scene, tmp_path):
    with pytest.raises(gissar.ConfigError, match=r"is required \(depression_deg\)"):
        tiny_scene.simulate(heading_deg=0)
    with pytest.raises(gissar.ConfigError, match=r"is required \(depression_deg\)"):
        gissar.sequence(tmp_path / "q", 0, 60, frames=2, dem=DEM, **COARSE)
    assert not list(tmp_path.iterdir())


# ---------------------------------------------------------------- what the user gave, not /vsimem/

def _gissar_warnings(call):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    return [str(w.message) for w in caught if issubclass(w.category, gissar.GissarWarning)]


def test_warnings_about_a_dem_array_name_the_argument():
    dem = np.full((48, 48), 100.0, np.float32)
    for call, given in [
            (lambda: gissar.simulate(dem, heading_deg=0, depression_deg=40, **UTM), "the `dem` array"),
            (lambda: gissar.raw.simulate(dem=dem, heading_deg=0, depression_deg=40, **UTM), "the `dem` array"),
            # The compiled core's own array path (gissar._core.simulate takes the array itself).
            (lambda: gissar._core.simulate(dem=dem, heading_deg=0, depression_deg=40, **UTM), "the `dem` array")]:
        texts = [t for t in _gissar_warnings(call) if "vertical datum" in t]
        assert len(texts) == 1 and texts[0].startswith(given + ": the DEM names no vertical datum"), texts
        assert "/vsimem/" not in texts[0] and "vertical_datum" in texts[0]


def test_warnings_about_a_dataarray_or_dataset_name_the_argument():
    from osgeo import gdal, osr
    ds = gdal.GetDriverByName("MEM").Create("", 48, 48, 1, gdal.GDT_Float32)
    ds.SetGeoTransform(UTM["transform"])
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32631)
    ds.SetSpatialRef(srs)
    ds.GetRasterBand(1).Fill(100.0)
    texts = _gissar_warnings(lambda: gissar.simulate(ds, heading_deg=0, depression_deg=40))
    assert any(t.startswith("the `dem` GDAL dataset:") for t in texts) and not any("/vsimem/" in t for t in texts)
    rioxarray = pytest.importorskip("rioxarray")
    import xarray as xr
    da = xr.DataArray(np.full((48, 48), 100.0, np.float32), dims=("y", "x"),
                      coords={"y": 4700000.0 - 15.0 - 30.0 * np.arange(48), "x": 400015.0 + 30.0 * np.arange(48)})
    da = da.rio.write_crs(32631)
    assert rioxarray is not None
    texts = _gissar_warnings(lambda: gissar.simulate(da, heading_deg=0, depression_deg=40))
    assert any(t.startswith("the `dem` DataArray:") for t in texts) and not any("/vsimem/" in t for t in texts)


def test_errors_about_a_dem_array_name_the_argument():
    dem = np.full((48, 48), 100.0, np.float32)
    dem[20, 20] = np.nan  # an interior no-data cell
    for simulate in (gissar.simulate, gissar.raw.simulate, lambda d, **k: gissar._core.simulate(dem=d, **k)):
        with pytest.raises(gissar.InputError, match="no-data cells") as error:
            simulate(dem, heading_deg=0, depression_deg=40, vertical_datum="ellipsoid", **UTM)
        assert "/vsimem/" not in str(error.value) and "the `dem` array" in str(error.value), str(error.value)
        assert "fill_nodata" in str(error.value)


# ---------------------------------------------------------------- the help table

def test_simulate_request_help_is_a_dict_of_the_request_fields():
    help_ = gissar._core.simulate_request_help()
    defaults = gissar.simulate_request_defaults()
    assert isinstance(help_, dict) and "heading_deg" in help_ and "depression_deg" in help_
    assert all(isinstance(v, str) and v and "\n" not in v for v in help_.values())
    assert not [k for k in help_ if k not in defaults], "help for a field simulate does not take"
