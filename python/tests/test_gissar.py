"""pytest suite of the gissar Python module (run by `make test`)."""
import json
import os
import warnings
import subprocess

import numpy as np
import pytest

import gissar

ROOT = os.environ.get("GISSAR_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
DEM = os.path.join(ROOT, "data", "andorra", "andorra_srtm3_dem_filled.tif")
TESTDATA = os.path.join(ROOT, "tests", "data", "affine")


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
    out = gissar.fmatrix(x1, x2, range_spacing_m=(1, 1), azimuth_spacing_m=(1, 1), depressions_deg=(40, 40))
    assert out["F"].shape == (3, 3)
    assert abs(out["heading_change_deg"] - 30.0) < 1e-6
    assert abs(out["kvd"]["theta_deg"] - 23.198952052312735) < 1e-7
    world = np.column_stack([pts["X"], pts["Y"], pts["Z"]])
    pose = gissar.resect(world, x2)
    assert abs(pose["heading_deg"] - 30.0) < 1e-6
    assert abs(pose["depression_deg"] - 40.0) < 1e-6
    assert gissar.resect(world, x2, center_enu_m=(0, 0, 0))["heading_deg"] == pose["heading_deg"]


def test_old_keyword_spellings_still_work_with_a_deprecation_warning():
    pts = np.genfromtxt(os.path.join(TESTDATA, "case2_thesis_dpsi30_dep40_noisefree_points.csv"),
                        delimiter=",", names=True)
    x1 = np.column_stack([pts["x1"], pts["y1"]])
    x2 = np.column_stack([pts["x2"], pts["y2"]])
    new = gissar.fmatrix(x1, x2, range_spacing_m=(1, 1), azimuth_spacing_m=(1, 1), depressions_deg=(40, 40))
    with pytest.warns(DeprecationWarning, match="res1 is deprecated.*range_spacing_m"):
        old = gissar.fmatrix(x1, x2, res1=(1, 1), res2=(1, 1), depressions_deg=(40, 40))
    np.testing.assert_array_equal(old["F"], new["F"])
    with pytest.raises(gissar.ConfigError):
        gissar.fmatrix(x1, x2, range_spacing_m=(1, 1))
    world = np.column_stack([pts["X"], pts["Y"], pts["Z"]])
    with pytest.warns(DeprecationWarning, match="scene_centre_enu_m is deprecated.*center_enu_m"):
        old_pose = gissar.resect(world, x2, scene_centre_enu_m=(0, 0, 0))
    assert old_pose["heading_deg"] == gissar.resect(world, x2, center_enu_m=(0, 0, 0))["heading_deg"]


def test_simulate_equals_the_cli_geotiff_bit_for_bit(tmp_path):
    from osgeo import gdal
    options = dict(dem=DEM, heading_deg=30.0, depression_deg=40.0, range_spacing_m=250.0,
                   azimuth_spacing_m=250.0, speckle_looks=4.0, seed=9)
    result = gissar.simulate(**options)
    image = result.sel(band="total").values
    assert image.dtype == np.float32 and image.ndim == 2
    # The default three bounces: single, double, triple (no four-or-more band), as the GeoTIFF holds them.
    assert result.shape == (4,) + image.shape and list(result["band"].values)[1:] == ["single", "double", "triple"]
    assert result["mask"].dtype == np.uint8
    prefix = str(tmp_path / "sim")
    subprocess.run([os.environ["GISSAR_CLI"], "simulate", "--dem", DEM, "--heading", "30", "--depression", "40",
                    "--range-spacing", "250", "--azimuth-spacing", "250", "--speckle-looks", "4", "--seed", "9",
                    "--out", prefix, "--quiet"], check=True, stdout=subprocess.DEVNULL)
    tif = gdal.Open(prefix + ".tif")  # keep the dataset alive while reading its bands
    assert np.array_equal(tif.GetRasterBand(1).ReadAsArray(), image, equal_nan=True)
    assert np.array_equal(tif.GetRasterBand(3).ReadAsArray(), result.sel(band="double").values, equal_nan=True)
    # The DataArray's bands are the GeoTIFF's bands, by name.
    assert tif.RasterCount == 4
    for b in range(1, 5):
        name = tif.GetRasterBand(b).GetDescription()
        assert np.array_equal(tif.GetRasterBand(b).ReadAsArray(), result.sel(band=name).values, equal_nan=True), name
    # No-data (NaN, declared) exactly where the mask says "outside the footprint" (255).
    assert np.isnan(tif.GetRasterBand(1).GetNoDataValue())
    assert np.array_equal(np.isnan(image), result["mask"].values == 255)
    assert 0 < np.isnan(image).sum() < image.size
    mask_ds = gdal.Open(prefix + "_mask.tif")
    assert np.array_equal(mask_ds.GetRasterBand(1).ReadAsArray(), result["mask"].values)
    # The dict of the 0.1 API, through gissar.raw.
    raw = gissar.raw.simulate(**options)
    assert np.array_equal(raw["image"], image, equal_nan=True)


def test_simulate_quad_gives_the_geotiff_bands_by_channel(tmp_path):
    from osgeo import gdal
    prefix = str(tmp_path / "quad")
    result = gissar.simulate(dem=DEM, heading_deg=30.0, depression_deg=40.0, range_spacing_m=300.0,
                             azimuth_spacing_m=300.0, polarization="quad", out_prefix=prefix)
    names = list(result["band"].values)
    # Four totals, then each channel's single, double and triple bands (three bounces traced).
    assert names[:4] == ["HH", "HV", "VH", "VV"] and names[4:7] == ["HH_single", "HH_double", "HH_triple"]
    assert len(names) == 16
    tif = gdal.Open(prefix + ".tif")
    assert tif.RasterCount == 16
    for b in range(1, 17):
        name = tif.GetRasterBand(b).GetDescription()
        assert np.array_equal(tif.GetRasterBand(b).ReadAsArray(), result.sel(band=name).values, equal_nan=True), name
    # Reciprocity: VH is the HV pass; bare soil's cross-polarised return is weaker than its co-polarised ones.
    assert np.array_equal(result.sel(band="HV").values, result.sel(band="VH").values, equal_nan=True)
    assert np.nanmean(result.sel(band="HV").values) < np.nanmean(result.sel(band="HH").values)
    with pytest.raises(gissar.ConfigError, match="unknown channel 'XX'"):
        gissar.simulate(dem=DEM, heading_deg=0, depression_deg=40, polarization="HH,XX")


def test_pta_and_polsar_on_the_real_alos_quad_pol_chip(tmp_path):
    alos = os.path.join(ROOT, "data", "alos_rio_branco")
    product = os.path.join(alos, "calib_RSLC_ALPSRP025826990_RIO_BRANCO_CR.h5")
    report = gissar.pta(os.path.join(alos, "rio_branco_reflector.csv"), tmp_path / "pta", product=product)
    assert report["converged"] is True
    (cr,) = report["reflectors"]
    # The surveyed trihedral within 1 px of its prediction (the CLI's figures, docs/radiometry.md).
    assert abs(cr["location_error_px"]["range"]) < 1.0 and abs(cr["location_error_px"]["azimuth"]) < 1.0
    assert "hh_vv_phase_deg" in cr and "cross_pol_isolation_db" in cr
    assert sorted(os.path.basename(p) for p in report["outputs"]) == ["pta.json", "pta_irf.png"]
    decomposition = gissar.polsar(tmp_path / "pol", product=product, multilook=[5, 5])
    assert all(os.path.exists(p) for p in decomposition["outputs"])
    with pytest.raises(gissar.ConfigError, match="unknown key"):
        gissar.pta(os.path.join(alos, "rio_branco_reflector.csv"), tmp_path / "x", product=product, upsample=4)


def test_errors_become_python_exceptions():
    with pytest.raises(gissar.ConfigError, match="unknown key 'headin_deg'"):
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


WINDOW = (150, 70, 120, 100)  # a ~8 x 9 km corner of Andorra: builds in about a second


def test_vertical_datum_keyword(tmp_path):
    # The bundled SRTM DEM is tagged EPSG:4326+5773: egm96 from the file; the keyword takes the flag's values.
    s = gissar.Scene.build(DEM, str(tmp_path / "s"), window=WINDOW)
    assert s.summary["vertical_datum"] == {"datum": "egm96", "source": "file"}
    e = gissar.Scene.build(DEM, str(tmp_path / "e"), window=WINDOW, vertical_datum="EPSG:4979")
    assert e.summary["vertical_datum"] == {"datum": "ellipsoid", "source": "flag"}
    with pytest.raises(gissar.ConfigError, match="got .egm97. \\(vertical_datum\\)"):
        gissar.Scene.build(DEM, str(tmp_path / "x"), window=WINDOW, vertical_datum="egm97")
    with pytest.raises(gissar.InputError, match="us_nga_egm08_25.tif"):
        gissar.simulate(dem=DEM, heading_deg=0, depression_deg=40, vertical_datum="egm2008")


@pytest.fixture(scope="module")
def small_scene(tmp_path_factory):
    out = tmp_path_factory.mktemp("scene")
    return gissar.Scene.build(DEM, str(out / "s"), vectors=[os.path.join(ROOT, "data", "andorra", "andorra_osm.gpkg")],
                              window=WINDOW, export_obj=True)


def test_scene_class_arrays_pictures_and_obj(small_scene, tmp_path):
    s = small_scene
    assert s.summary["stats"]["triangles"] == len(s.triangles) == len(s.classes)
    assert s.vertices_enu_m.shape == (s.summary["stats"]["vertices"], 3)
    assert int(s.triangles.max()) < len(s.vertices_enu_m)
    assert s.class_names[:3] == ["default", "water", "forest"]
    # The build wrote the class map, the 3-D view and OBJ + MTL next to the scene.
    prefix = s.path[:-len(".gscene")]
    for suffix in ("_classes.png", "_3d.png", ".obj", ".mtl", ".ply", ".json"):
        assert os.path.getsize(prefix + suffix) > 0, suffix
    cmap = s.class_map(max_side_px=300)
    assert cmap.dtype == np.uint8 and cmap.ndim == 3 and max(cmap.shape[:2]) == 300
    view = s.view_3d(width=200, height=120, view_elevation_deg=60)
    assert view.shape == (120, 200, 3)
    with pytest.raises(gissar.ConfigError, match="unknown option 'elevation'"):
        s.view_3d(elevation=3)
    s.export_obj(str(tmp_path / "m.obj"))
    lines = open(tmp_path / "m.obj").read().splitlines()
    assert lines[1] == "mtllib m.mtl"
    assert sum(line.startswith("f ") for line in lines) == len(s.triangles)
    assert "newmtl water" in open(tmp_path / "m.mtl").read()
    # A loaded scene is the same scene.
    again = gissar.Scene(s.path)
    assert np.array_equal(again.triangles, s.triangles) and np.array_equal(again.classes, s.classes)


def test_scene_simulate_returns_geometry_and_masks(small_scene):
    sim = small_scene.simulate(heading_deg=20, depression_deg=35, range_spacing_m=60, azimuth_spacing_m=60)
    g = sim.gissar.geometry
    assert isinstance(g, gissar.SarGeometry)
    assert (g.height, g.width) == sim.gissar.image.shape
    assert g.heading_deg == 20 and g.depression_deg == 35 and g.range_spacing_m == 60
    assert sim.attrs["GISSAR_HEADING_DEG"] == "20"
    mask = sim["mask"].values
    inside = mask != 255  # 255: outside the imaged footprint
    assert np.array_equal(sim["layover"].values, ((mask & 1) == 1) & inside)
    assert np.array_equal(sim["shadow"].values, ((mask & 2) == 2) & inside)
    # The scene centre projects to (u0, v0) and the sensor is R away along the line of sight.
    c = np.array(g.scene_centre_enu_m)
    np.testing.assert_allclose(g.project(c[None, :])[0], [g.u0, g.v0], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(np.array(g.sensor_position()) - c), g.slant_range_m, rtol=1e-12)
    same = gissar.simulate(scene=small_scene.path, heading_deg=20, depression_deg=35, range_spacing_m=60,
                           azimuth_spacing_m=60)
    assert np.array_equal(same.values, sim.values, equal_nan=True)
    with pytest.raises(gissar.ConfigError):
        small_scene.simulate(dem=DEM, heading_deg=0, depression_deg=40)


def test_kvd_of_the_reference_f():
    ref = json.load(open(os.path.join(TESTDATA, "case2_thesis_dpsi30_dep40_noisefree.json")))
    k = gissar.kvd(np.array(ref["F_true"]))
    assert abs(k["theta_deg"] - 23.198952052312735) < 1e-7
    assert k["rho_recoverable"] is False
    # By hand from F = [0 0 a; 0 0 b; c d e]: s = |(c, d)| / |(a, b)|, phi = atan2(b, a).
    f = np.array([[0, 0, 3.0], [0, 0, 4.0], [6.0, 8.0, 1.0]])
    k = gissar.kvd(f)
    assert abs(k["s"] - 2.0) < 1e-12
    assert abs(k["phi_deg"] - np.degrees(np.arctan2(4, 3))) < 1e-12
    with pytest.raises(gissar.InputError):
        gissar.kvd(np.eye(2))


def test_match_images_finds_a_known_shift_through_a_warp():
    rng = np.random.default_rng(4)
    base = rng.gamma(1.0, 1.0, size=(200, 220)).astype(np.float32)
    # Smooth texture that NCC can lock onto: box-blurred noise.
    k = np.ones(7) / 7
    base = np.apply_along_axis(lambda r: np.convolve(r, k, "same"), 1, base)
    base = np.apply_along_axis(lambda c: np.convolve(c, k, "same"), 0, base).astype(np.float32) ** 4
    observed = np.roll(base, (-5, 7), axis=(0, 1))  # observed(x, y) = base(x - 7, y + 5)
    m = gissar.match_images(base, observed, patch_px=21, step_px=20, search_px=10, filter_px=1)
    assert len(m["score"]) > 20
    d = m["x_observed"] - m["x_reference"]
    assert np.median(np.abs(d - [7, -5]), axis=0).max() < 0.05
    # The same through an exact prediction (a translation by (6, -4)): the matcher only sees the rest.
    warp = np.array([[1.0, 0, 6.0], [0, 1.0, -4.0]])
    m = gissar.match_images(base, observed, warp=warp, patch_px=21, step_px=20, search_px=4, filter_px=1)
    d = m["x_observed"] - m["x_reference"]
    assert len(d) > 20 and np.median(np.abs(d - [7, -5]), axis=0).max() < 0.05
    with pytest.raises(gissar.InputError, match="differ in size"):
        gissar.match_images(base, observed[:100])
    with pytest.raises(gissar.ConfigError):
        gissar.match_images(base, observed, matcher="sift")


def test_register_images_recovers_a_shift():
    yy, xx = np.mgrid[0:80, 0:90]
    fixed = (2 + np.sin(xx / 5.0) * np.cos(yy / 7.0)).astype(np.float32)
    moving = (2 + np.sin((xx + 3) / 5.0) * np.cos((yy - 2) / 7.0)).astype(np.float32)  # moving(x, y) = fixed(x+3, y-2)
    pts_fixed = np.array([[10, 10], [70, 12], [20, 60], [75, 65], [40, 40]], float)
    pts_moving = pts_fixed - [3, -2]
    r = gissar.register_images(fixed, moving, pts_fixed, pts_moving, transform="affine")
    assert r["rms_px"] < 1e-9
    inner = (slice(10, 70), slice(10, 80))
    assert np.abs(r["warped"][inner] - fixed[inner]).max() < 1e-3


def test_pictures_as_arrays_and_files(tmp_path):
    from osgeo import gdal
    intensity = np.outer(np.linspace(1, 100, 50), np.ones(70)).astype(np.float32)
    grey, (low_db, high_db) = gissar.quicklook(intensity, 0, 100)
    assert grey.shape == (50, 70) and grey[0, 0] == 1 and grey[-1, 0] == 255
    assert abs(low_db - 0.0) < 1e-4 and abs(high_db - 20.0) < 1e-4
    ann = gissar.annotated_quicklook(intensity, 30.0, 15.0, "ramp")
    assert ann.shape == (50 + 44 + 50, 70 + 70 + 90 + 20, 3)
    assert np.array_equal(ann[44:94, 70:140, 0], gissar.quicklook(intensity)[0])
    # True slant range (column 0 at 9.5 km) and along track from the scene centre: the picture is the
    # same size, the image itself unchanged, the axis labels differ.
    true_axes = gissar.annotated_quicklook(intensity, 30.0, 15.0, "ramp", near_range_m=9500.0,
                                           azimuth_origin_m=-25 * 15.0)
    assert true_axes.shape == ann.shape
    assert np.array_equal(true_axes[44:94, 70:140], ann[44:94, 70:140])
    assert not np.array_equal(true_axes[94:], ann[94:])
    comp = gissar.composite(intensity, 3.0 * intensity)  # a gain only: grey everywhere
    assert np.abs(comp[..., 0].astype(int) - comp[..., 1]).max() <= 1 and np.array_equal(comp[..., 0], comp[..., 2])
    kvd = gissar.kvd_diagram(1.0, 23.2, 11.6, 30.0)
    assert kvd.shape == (460, 420, 3)
    sheet = gissar.side_by_side([comp, kvd], ["a", "b"])
    assert sheet.shape[1] == 8 + 70 + 8 + 420 + 8
    x1 = np.array([[10.0, 10], [60, 12], [15, 40], [55, 45], [30, 25]])
    f = np.array([[0, 0, 0.6], [0, 0, 0.8], [-0.6, -0.8, 0.0]])  # x2 = x1: every point on its line
    epi = gissar.epipolar_plot(intensity, intensity, x1, x1, f, inliers=[0, 1, 2])
    assert epi.shape == (50, 2 * 70 + 10, 3)
    gissar.write_png(str(tmp_path / "a.png"), ann)
    ds = gdal.Open(str(tmp_path / "a.png"))
    assert (ds.RasterXSize, ds.RasterYSize, ds.RasterCount) == (ann.shape[1], ann.shape[0], 3)
    assert np.array_equal(ds.GetRasterBand(2).ReadAsArray(), ann[..., 1])
    gissar.write_gif(str(tmp_path / "a.gif"), [grey, 255 - grey], delay_cs=20)
    assert open(tmp_path / "a.gif", "rb").read(6) == b"GIF89a"
    with pytest.raises(gissar.InputError):
        gissar.write_png(str(tmp_path / "b.png"), np.zeros((4, 4, 2), np.uint8))
    with pytest.raises(gissar.InputError):
        gissar.write_gif(str(tmp_path / "b.gif"), [grey, grey[:10]])
    with pytest.raises(gissar.IoError):
        gissar.write_png("/nonexistent/dir/a.png", grey)
    assert not os.path.exists(tmp_path / "b.png")


def test_locate_fixes_a_drifted_prior(small_scene):
    sim = small_scene.simulate(heading_deg=30, depression_deg=40, slant_range_m=10000, range_spacing_m=30,
                               azimuth_spacing_m=30, width=160, height=160, speckle_looks=4, seed=3)
    truth = np.array(sim.gissar.geometry.sensor_position())
    prior = {"heading_deg": 31.5, "slant_range_m": 10000.0, "sensor_enu_m": list(truth + [120.0, -90.0, 30.0])}
    fix = gissar.locate(small_scene, sim, prior, range_spacing_m=30, azimuth_spacing_m=30)  # a DataArray image
    assert fix["converged"]
    assert abs(fix["pose"]["heading_deg"] - 30.0) < 0.2
    error = np.linalg.norm(np.array(fix["pose"]["sensor_enu_m"]) - truth)
    assert error < 3 * 30.0, error  # within 3 resolution cells (docs/navigation.md's success criterion)
    assert fix["reference_at_fix"].shape == sim.gissar.image.shape
    with pytest.raises(gissar.ConfigError, match="headng_deg"):
        gissar.locate(small_scene.path, sim.gissar.image.values, {"headng_deg": 3}, range_spacing_m=30,
                      azimuth_spacing_m=30)


def test_locate_product_fixes_a_real_chip_and_evaluates(tmp_path):
    sanand = os.path.join(ROOT, "data", "uavsar", "SanAnd_129.h5")
    dem = os.path.join(ROOT, "data", "uavsar", "SanAnd_dem.tif")
    fix = gissar.locate_product(product=sanand, dem=dem, dem_oversample=4, prior_offset_track=(-60, 30, 0))
    assert fix["converged"], fix["reason"]
    error = fix["fix"]["error_against_annotated_track"]
    assert error["prior_position_error_m"] > 60.0
    assert error["position_error_m"] <= 2 * fix["cell_m"]  # docs/conventions.md's success rule
    assert not list(tmp_path.iterdir())  # nothing written without out
    summary = gissar.evaluate(product=sanand, dem=dem, dem_oversample=4, trials=2, seed=1)
    assert summary["trials"] == 2 and len(summary["trial_records"]) == 2
    assert "position_error_cells" in summary
    with pytest.raises(gissar.ConfigError, match="prior_ofset_track"):
        gissar.locate_product(product=sanand, dem=dem, prior_ofset_track=(0, 0, 0))
    with pytest.raises(gissar.ConfigError, match="--image"):
        gissar.locate_product(orbit="track.csv", radar_grid="grid.json", dem=dem)


def test_simulate_product_matches_the_cli_and_the_reference_geolocation(tmp_path):
    """The Winnipeg UAVSAR chip: the product grid, the CLI's bands bit for bit, ISCE's lon/lat."""
    from osgeo import gdal
    product = os.path.join(ROOT, "data", "uavsar", "winnipeg.h5")
    dem = os.path.join(ROOT, "data", "uavsar", "winnipeg_dem.tif")
    result = gissar.simulate_product(product, dem=dem, seed=3)
    image = result.sel(band="total").values
    rows, cols = len(result["zero_doppler_time_s"]), len(result["slant_range_m"])
    assert image.shape == (rows, cols)
    assert result.dims == ("band", "zero_doppler_time_s", "slant_range_m")
    assert result["slant_range_m"].attrs["units"] == "m" and np.all(np.diff(result["slant_range_m"].values) > 0)
    assert result["real_amplitude"].shape == (rows, cols)
    assert result.attrs["look_side"] in ("left", "right") and result.attrs["wavelength_m"] > 0.1  # L band
    result = {name: result.coords[name].values for name in ("lon_deg", "lat_deg")}
    prefix = str(tmp_path / "w")
    subprocess.run([os.environ["GISSAR_CLI"], "simulate", "--product", product, "--dem", dem, "--seed", "3",
                    "--out", prefix, "--quiet"], check=True, stdout=subprocess.DEVNULL)
    tif = gdal.Open(prefix + ".tif")
    assert np.array_equal(tif.GetRasterBand(1).ReadAsArray(), image, equal_nan=True)
    assert np.array_equal(tif.GetRasterBand(6).ReadAsArray(), result["lon_deg"])
    # ISCE's per-pixel longitude/latitude of the same chip (float64 ENVI rasters).
    topo = os.path.join(ROOT, "data", "uavsar", "topo_winnipeg")
    x_ds = gdal.Open(os.path.join(topo, "x.rdr"))  # keep the datasets alive while reading their bands
    y_ds = gdal.Open(os.path.join(topo, "y.rdr"))
    lon_ref = x_ds.GetRasterBand(1).ReadAsArray()
    lat_ref = y_ds.GetRasterBand(1).ReadAsArray()
    ok = np.isfinite(result["lon_deg"])
    assert ok.mean() > 0.99
    east_m = (result["lon_deg"][ok] - lon_ref[ok]) * 111320.0 * np.cos(np.radians(lat_ref[ok]))
    north_m = (result["lat_deg"][ok] - lat_ref[ok]) * 110540.0
    # float32 degrees carry ~0.5 m of rounding at these longitudes; the double-precision check is in C++.
    assert np.sqrt(np.mean(east_m ** 2 + north_m ** 2)) < 1.0


def test_simulate_takes_a_dem_array_with_transform_and_crs(tmp_path):
    """The same DEM as an array (transform, CRS) and as a file give the same image."""
    from osgeo import gdal
    ds = gdal.Open(DEM)
    heights = ds.GetRasterBand(1).ReadAsArray()
    common = dict(heading_deg=30.0, depression_deg=40.0, range_spacing_m=250.0, azimuth_spacing_m=250.0)
    from_file = gissar.simulate(dem=DEM, **common)
    from_array = gissar.simulate(dem=heights, transform=ds.GetGeoTransform(), crs=ds.GetProjection(), **common)
    assert np.array_equal(from_file.values, from_array.values, equal_nan=True)
    with pytest.raises(gissar.ConfigError, match="needs transform= and crs="):
        gissar.simulate(dem=heights, **common)
    with pytest.raises(gissar.ConfigError, match="not a CRS"):
        gissar.simulate(dem=heights, transform=ds.GetGeoTransform(), crs="EPSG:999999", **common)


def test_progress_callback_sees_the_stages_and_can_cancel():
    common = dict(dem=DEM, heading_deg=0.0, depression_deg=40.0, range_spacing_m=120.0, azimuth_spacing_m=120.0)
    seen = []
    gissar.simulate(progress=lambda stage, done, total: seen.append((stage, done, total)), **common)
    assert seen and seen[-1][1] == seen[-1][2]          # the last call: the stage complete
    assert all(0 < d <= t for _, d, t in seen)
    with pytest.raises(gissar.Cancelled):
        gissar.simulate(progress=lambda stage, done, total: False, **common)


def test_library_warnings_are_python_warnings(tmp_path):
    """A scene build whose layer has features outside the DEM warns through `warnings`."""
    with pytest.warns(gissar.GissarWarning, match="outside the DEM"):
        gissar.Scene.build(dem=DEM, vectors=[os.path.join(ROOT, "data", "andorra", "andorra_osm.gpkg")],
                           window=(150, 70, 60, 60), out_prefix=str(tmp_path / "w"))


def test_warnings_name_python_parameters_and_point_at_the_caller():
    """A DEM without a vertical datum warns once: the text names `vertical_datum` (not the command line's
    --vertical-datum) and the warning is attributed to this file, not to gissar's own modules."""
    dem = np.full((48, 48), 100.0, np.float32)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gissar.simulate(dem, transform=(400000.0, 30.0, 0.0, 4700000.0, 0.0, -30.0), crs=32631, heading_deg=0,
                        depression_deg=40)
    datum = [w for w in caught if issubclass(w.category, gissar.GissarWarning) and "vertical datum" in str(w.message)]
    assert len(datum) == 1, [str(w.message) for w in caught]
    assert "vertical_datum" in str(datum[0].message) and "--vertical-datum" not in str(datum[0].message)
    assert os.path.abspath(datum[0].filename) == os.path.abspath(__file__)


def test_errors_are_python_errors_naming_python_parameters():
    assert issubclass(gissar.ConfigError, ValueError) and issubclass(gissar.InputError, ValueError)
    assert issubclass(gissar.IoError, OSError) and issubclass(gissar.Cancelled, RuntimeError)
    with pytest.raises(FileNotFoundError, match="DEM file does not exist"):
        gissar.simulate(dem="/nonexistent/dem.tif", heading_deg=0, depression_deg=40)
    # The message names the Python parameter, not the command-line flag.
    with pytest.raises(ValueError, match=r"\(depression_deg\)$"):
        gissar.simulate(dem=DEM, heading_deg=0, depression_deg=95)
    with pytest.raises(ValueError, match=r"\(range_spacing_m\)$"):
        gissar.simulate(dem=DEM, heading_deg=0, depression_deg=40, range_spacing_m=-3)


def test_simulate_has_a_real_signature():
    import inspect
    params = inspect.signature(gissar.simulate).parameters
    assert list(params)[0] == "dem"
    for name in ("heading_deg", "depression_deg", "range_spacing_m", "slant_range_m", "transform", "crs",
                 "progress"):
        assert name in params, name
    assert params["rays_per_cell"].default == 4.0
    assert "heading_deg: required (degrees)" in gissar.simulate.__doc__
    assert "slant_range_m: default" in gissar.simulate.__doc__ and "(metres)" in gissar.simulate.__doc__
    assert gissar.__version__ == gissar.version().split()[1]
