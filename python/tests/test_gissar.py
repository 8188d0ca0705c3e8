"""pytest suite of the gissar Python module (run by `make test`)."""
import json
import os
import subprocess

import numpy as np
import pytest

import gissar

ROOT = os.environ.get("GISSAR_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
DEM = os.path.join(ROOT, "data", "andorra", "andorra_srtm3_dem_filled.tif")
TESTDATA = os.path.join(ROOT, "..", "shared", "testdata", "affine")


def test_version():
    assert gissar.version().startswith("gissar 0.")


def test_geometry_projects_reference_case_pixels():
    ref = json.load(open(os.path.join(TESTDATA, "case2_thesis_dpsi30_dep40_noisefree.json")))
    pts = np.genfromtxt(os.path.join(TESTDATA, "case2_thesis_dpsi30_dep40_noisefree_points.csv"),
                        delimiter=",", names=True)
    world = np.column_stack([pts["X"], pts["Y"], pts["Z"]])
    g1 = gissar.SarGeometry(heading_deg=0, depression_deg=40, u0=512, v0=512)
    g2 = gissar.SarGeometry(heading_deg=30, depression_deg=40, u0=512, v0=512)
    np.testing.assert_allclose(g1.project(world), np.column_stack([pts["x1_true"], pts["y1_true"]]), atol=1e-9)
    np.testing.assert_allclose(g2.project(world), np.column_stack([pts["x2_true"], pts["y2_true"]]), atol=1e-9)
    assert ref["geometry"]["heading_change_deg"] == 30


def test_fmatrix_heading_change_and_resection():
    pts = np.genfromtxt(os.path.join(TESTDATA, "case2_thesis_dpsi30_dep40_noisefree_points.csv"),
                        delimiter=",", names=True)
    x1 = np.column_stack([pts["x1"], pts["y1"]])
    x2 = np.column_stack([pts["x2"], pts["y2"]])
    out = gissar.fmatrix(x1, x2, res1=(1, 1), res2=(1, 1), depressions_deg=(40, 40))
    assert out["F"].shape == (3, 3)
    assert abs(out["heading_change_deg"] - 30.0) < 1e-6
    assert abs(out["kvd"]["theta_deg"] - 23.198952052312735) < 1e-7
    world = np.column_stack([pts["X"], pts["Y"], pts["Z"]])
    pose = gissar.resect(world, x2)
    assert abs(pose["heading_deg"] - 30.0) < 1e-6
    assert abs(pose["depression_deg"] - 40.0) < 1e-6


def test_simulate_equals_the_cli_geotiff_bit_for_bit(tmp_path):
    from osgeo import gdal
    options = dict(dem=DEM, heading_deg=30.0, depression_deg=40.0, range_spacing_m=250.0,
                   azimuth_spacing_m=250.0, speckle_looks=4.0, seed=9)
    result = gissar.simulate(**options)
    image = result["image"]
    assert image.dtype == np.float32 and image.ndim == 2
    assert result["bounces"].shape == (4,) + image.shape
    assert result["mask"].dtype == np.uint8
    prefix = str(tmp_path / "sim")
    subprocess.run([os.environ["GISSAR_CLI"], "simulate", "--dem", DEM, "--heading", "30", "--depression", "40",
                    "--range-res", "250", "--azimuth-res", "250", "--speckle-looks", "4", "--seed", "9",
                    "--out", prefix, "--quiet"], check=True, stdout=subprocess.DEVNULL)
    tif = gdal.Open(prefix + ".tif")  # keep the dataset alive while reading its bands
    assert np.array_equal(tif.GetRasterBand(1).ReadAsArray(), image)
    assert np.array_equal(tif.GetRasterBand(3).ReadAsArray(), result["bounces"][1])
    mask_ds = gdal.Open(prefix + "_mask.tif")
    assert np.array_equal(mask_ds.GetRasterBand(1).ReadAsArray(), result["mask"])


def test_errors_become_python_exceptions():
    with pytest.raises(gissar.ConfigError, match="unknown option 'headin_deg'"):
        gissar.simulate(dem=DEM, headin_deg=0, depression_deg=40)
    with pytest.raises(gissar.InputError, match="DEM file does not exist"):
        gissar.simulate(dem="/nonexistent.tif", heading_deg=0, depression_deg=40)
    with pytest.raises(gissar.ConfigError, match="depression must be in"):
        gissar.simulate(dem=DEM, heading_deg=0, depression_deg=95)
    assert issubclass(gissar.InputError, gissar.Error)
    with pytest.raises(gissar.InputError):
        gissar.fmatrix(np.zeros((3, 2)), np.zeros((3, 2)))


def test_scene_round_trip(tmp_path):
    summary = gissar.build_scene(DEM, str(tmp_path / "a"), vectors=[os.path.join(ROOT, "data", "andorra",
                                                                                "andorra_osm.gpkg")])
    scene = gissar.load_scene(str(tmp_path / "a.gscene"))
    assert scene["triangles"].shape[0] == summary["stats"]["triangles"]
    assert scene["vertices_enu_m"].shape[1] == 3
    assert scene["class_names"][1] == "water"
    assert int((scene["classes"] == 1).sum()) == summary["stats"]["classes"]["water"]["triangles"]
