"""gissar.open_product on the bundled Sentinel-1 SAFE folders (data/sentinel1, PROVENANCE.md) and NISAR-format
RSLC chips. The Sentinel-1 measurement TIFFs are real-format, full-size images whose pixels are constant
placeholders (IW1 VV SLC: 2 + 0i, GRD VV: 1, S3 VH SLC: 0), so the values checked here are coordinates and
calibration arithmetic, never image statistics. Expected values come from the annotation XML, read here with
ElementTree and interpolated by this file's own bilinear code (ESA's rule), independently of the library."""
import json
import os
import pickle
import shutil
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest

import gissar

ROOT = os.environ.get("GISSAR_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
S1 = os.path.join(ROOT, "data", "sentinel1")
IW_SLC = os.path.join(S1, "S1B_IW_SLC__1SDV_20210401T052622_20210401T052650_026269_032297_EFA4.SAFE")
IW_GRD = os.path.join(S1, "S1B_IW_GRDH_1SDV_20210401T052623_20210401T052648_026269_032297_ECC8.SAFE")
SM = os.path.join(S1, "S1A_S3_SLC__1SDV_20210401T152855_20210401T152914_037258_04638E_6001.SAFE")
IW1_VV = "s1b-iw1-slc-vv-20210401t052624-20210401t052649-026269-032297-004"
GRD_VV = "s1b-iw-grd-vv-20210401t052623-20210401t052648-026269-032297-001"
ALOS = os.path.join(ROOT, "data", "alos_rio_branco", "calib_RSLC_ALPSRP025826990_RIO_BRANCO_CR.h5")
UAVSAR = os.path.join(ROOT, "data", "uavsar", "winnipeg.h5")
C = 299792458.0


def _xml(safe, *parts):
    return ET.parse(os.path.join(safe, "annotation", *parts)).getroot()


def _ns(text):
    return np.datetime64(text, "ns")


def _lut(safe, name, field, vector="calibrationVector", listname="calibrationVectorList"):
    """[(line, pixels, values)] of one LUT of a calibration or noise annotation."""
    root = _xml(safe, "calibration", name)
    return [(int(v.find("line").text), np.array(v.find("pixel").text.split(), float),
             np.array(v.find(field).text.split(), float)) for v in root.find(listname).findall(vector)]


def _bilinear(vectors, line, pixel):
    """ESA's rule: linear in pixel along the two vectors bracketing the line, then linear in line."""
    lines = [v[0] for v in vectors]
    k = int(np.searchsorted(lines, line, side="right"))
    if k == 0 or k == len(lines):
        _, px, val = vectors[0 if k == 0 else -1]
        return float(np.interp(pixel, px, val))
    (l0, p0, v0), (l1, p1, v1) = vectors[k - 1], vectors[k]
    w = (line - l0) / (l1 - l0)
    return (1 - w) * float(np.interp(pixel, p0, v0)) + w * float(np.interp(pixel, p1, v1))


# ---------------------------------------------------------------- coordinates and attributes

def test_iw_slc_burst_coordinates_follow_the_annotation():
    ds = gissar.open_product(IW_SLC, swath="IW1", polarization="VV", burst=2)
    ann = _xml(IW_SLC, IW1_VV + ".xml")
    info = ann.find("imageAnnotation/imageInformation")
    dt = float(info.find("azimuthTimeInterval").text)                 # 2.055556299999998e-03 s
    tau0 = float(info.find("slantRangeTime").text)                    # 5.343035814454385e-03 s
    spacing = float(info.find("rangePixelSpacing").text)              # 2.329562 m
    fs = float(ann.find("generalAnnotation/productInformation/rangeSamplingRate").text)
    lines_per_burst = int(ann.find("swathTiming/linesPerBurst").text)  # 1501
    burst2 = ann.findall("swathTiming/burstList/burst")[1]

    assert ds.slc.dims == ("azimuth_time", "slant_range")
    assert ds.slc.shape == (1501, 21632)
    assert ds.slc.dtype == np.complex64
    t = ds.azimuth_time.values
    assert t.dtype == np.dtype("datetime64[ns]")
    assert t[0] == _ns(burst2.find("azimuthTime").text) == _ns("2021-04-01T05:26:26.966491")
    steps = np.diff(t).astype(np.int64)  # ns; the interval is 2055556.3 ns, so each step rounds to ...6 or ...7
    assert np.all(np.abs(steps - dt * 1e9) <= 1.0)
    assert abs((t[-1] - t[0]).astype(np.int64) - 1500 * dt * 1e9) <= 1.0
    r = ds.slant_range.values
    assert ds.slant_range.attrs["units"] == "m"
    assert r[0] == pytest.approx(tau0 * C / 2, abs=1e-6)              # 800942.3 m
    j = np.arange(r.size)
    np.testing.assert_allclose(r - r[0], j * C / (2 * fs), atol=1e-6)  # the sampling: c / (2 fs)
    np.testing.assert_allclose(r - r[0], j * spacing, atol=0.02)      # rangePixelSpacing, rounded to 1 um
    np.testing.assert_array_equal(ds.line.values, np.arange(1501, 3002))  # burst 2: lines 1501-3001
    assert int(ds.line[0]) == lines_per_burst
    np.testing.assert_array_equal(ds.pixel.values, j)

    a = ds.attrs
    assert a["sensor"] == "Sentinel-1B" and a["mission"] == "S1B"
    assert a["product"] == os.path.basename(IW_SLC)
    assert (a["product_type"], a["mode"], a["swath"], a["burst"], a["polarization"]) == ("SLC", "IW", "IW1", 2, "VV")
    radar_frequency = float(ann.find("generalAnnotation/productInformation/radarFrequency").text)
    assert a["wavelength_m"] == pytest.approx(C / radar_frequency, rel=1e-15)
    assert a["look_side"] == "right" and a["orbit_pass"] == "Descending"
    assert a["radiometry"] == "none" and a["noise_removal"] == 0
    assert a["azimuth_time_interval_s"] == dt
    assert a["range_spacing_m"] == pytest.approx(C / (2 * fs), rel=1e-15)
    assert a["source_files"][1].endswith("measurement/" + IW1_VV + ".tiff")
    assert json.loads(a["options"])["burst"] == 2
    assert a["gissar_version"] == gissar.__version__
    assert ds.slc.attrs["units"] == "1"


def test_a_swath_of_bursts_is_indexed_by_line_and_pixel():
    ds = gissar.open_product(IW_SLC, swath="iw1", polarization="vv")
    assert ds.slc.dims == ("line", "pixel")
    assert ds.slc.shape == (13509, 21632)  # 9 bursts of 1501 lines
    ann = _xml(IW_SLC, IW1_VV + ".xml")
    bursts = ann.findall("swathTiming/burstList/burst")
    # Each burst's first line is at its azimuthTime; consecutive bursts overlap in time.
    for b, burst in enumerate(bursts):
        assert ds.azimuth_time.values[b * 1501] == _ns(burst.find("azimuthTime").text)
    assert ds.azimuth_time.values[1500] > ds.azimuth_time.values[1501]
    assert "burst" not in ds.attrs


def test_grd_has_ground_range_coordinates():
    ds = gissar.open_product(IW_GRD, polarization="VV")  # the VH measurement is not bundled
    info = _xml(IW_GRD, GRD_VV + ".xml").find("imageAnnotation/imageInformation")
    dt = float(info.find("azimuthTimeInterval").text)  # 1.498376640333055e-03 s
    assert ds.amplitude.dims == ("azimuth_time", "ground_range")
    assert ds.amplitude.shape == (16685, 25788)
    assert ds.amplitude.dtype == np.float32
    assert "slant_range" not in ds.coords
    np.testing.assert_array_equal(ds.ground_range.values, np.arange(25788) * 10.0)  # rangePixelSpacing 10 m
    assert ds.ground_range.attrs["units"] == "m"
    t = ds.azimuth_time.values
    assert t[0] == _ns(info.find("productFirstLineUtcTime").text) == _ns("2021-04-01T05:26:23.794457")
    assert np.all(np.abs(np.diff(t[:1000]).astype(np.int64) - dt * 1e9) <= 1.0)
    assert abs((t[-1] - t[0]).astype(np.int64) - 16684 * dt * 1e9) <= 1.0
    assert ds.attrs["product_type"] == "GRD" and ds.attrs["swath"] == "IW"
    assert ds.attrs["ground_range_spacing_m"] == 10.0
    # The placeholder DN is 1: amplitude 1, read lazily (a strided and a reversed selection).
    assert float(ds.amplitude[8000, 12000]) == 1.0
    sub = ds.amplitude[::4000, ::-6000].values
    assert sub.shape == (5, 5) and np.all(sub == 1.0)
    np.testing.assert_array_equal(ds.amplitude[::4000, ::-6000].ground_range.values,
                                  np.arange(25787, -1, -6000) * 10.0)
    picked = ds.amplitude.isel(azimuth_time=[10, 0, 5000], ground_range=slice(-3, None))
    assert picked.shape == (3, 3) and np.all(picked.values == 1.0)
    np.testing.assert_array_equal(picked.ground_range.values, [257850.0, 257860.0, 257870.0])


def test_stripmap_dn_zero_is_nodata():
    ds = gissar.open_product(SM)
    info = _xml(SM, "s1a-s3-slc-vh-20210401t152855-20210401t152914-037258-04638e-001.xml").find(
        "imageAnnotation/imageInformation")
    assert ds.slc.dims == ("azimuth_time", "slant_range")
    assert ds.slc.shape == (36895, 18998)
    assert ds.azimuth_time.values[0] == _ns(info.find("productFirstLineUtcTime").text)
    assert ds.slant_range.values[0] == pytest.approx(float(info.find("slantRangeTime").text) * C / 2, abs=1e-6)
    assert (ds.attrs["swath"], ds.attrs["mode"], ds.attrs["polarization"]) == ("S3", "SM", "VH")
    block = ds.slc[100:102, 200:203].values  # the placeholder stores 0 + 0i: ESA's fill value
    assert block.shape == (2, 3) and np.all(np.isnan(block.real)) and np.all(np.isnan(block.imag))


# ---------------------------------------------------------------- values and calibration

def test_slc_dn_and_the_bursts_valid_window():
    ds = gissar.open_product(IW_SLC, swath="IW1", polarization="VV", burst=1)
    assert complex(ds.slc[700, 10000]) == 2 + 0j
    # Burst 1 lines 0-18 have no valid sample (firstValidSample -1); line 19 is valid on 529-20935.
    first = ds.slc[19, 527:531].values
    assert np.isnan(first[:2]).all() and np.all(first[2:] == 2)
    assert np.isnan(complex(ds.slc[18, 10000]))
    assert np.isnan(complex(ds.slc[19, 20936])) and complex(ds.slc[19, 20935]) == 2


@pytest.mark.parametrize("radiometry, field", [("sigma0", "sigmaNought"), ("beta0", "betaNought"),
                                               ("gamma0", "gamma")])
def test_calibrated_value_is_dn_squared_over_the_bilinear_lut_squared(radiometry, field):
    ds = gissar.open_product(IW_SLC, swath="IW1", polarization="VV", burst=1, radiometry=radiometry)
    v = ds[radiometry]
    assert v.dtype == np.float32 and v.attrs["units"] == "1" and v.attrs["radiometry"] == radiometry
    assert ds.attrs["radiometry"] == radiometry and field in ds.attrs["calibration"]
    lut = _lut(IW_SLC, "calibration-" + IW1_VV + ".xml", field)
    dn2 = abs(2 + 0j) ** 2
    # A grid node (vector at line 577, pixel 560), half-way between nodes, and a quarter of the way.
    for line, pixel in ((577, 560), (334, 540), (213, 530), (1000, 12345)):
        a = _bilinear(lut, line, pixel)
        assert float(v[line, pixel]) == pytest.approx(dn2 / a ** 2, rel=2e-7), (line, pixel)
    # The same figures written out: sigmaNought at lines 91 / 577, pixels 520 and 560 (the XML by eye).
    if radiometry == "sigma0":
        assert float(v[577, 560]) == pytest.approx(4 / 330.6192 ** 2, rel=2e-7)
        mid = (330.7431 + 330.6816 + 330.6806 + 330.6192) / 4
        assert float(v[334, 540]) == pytest.approx(4 / mid ** 2, rel=2e-7)
    if radiometry == "beta0":
        assert float(v[700, 12345]) == pytest.approx(4 / 236.9867 ** 2, rel=2e-7)  # betaNought is constant
    # The whole swath gives the same value at the same measurement line and pixel.
    swath = gissar.open_product(IW_SLC, swath="IW1", polarization="VV", radiometry=radiometry)
    assert float(swath[radiometry].sel(line=334, pixel=540)) == float(v[334, 540])


def test_lazy_indexing_matches_a_block_read():
    # sigma0 varies along lines and pixels with the LUT, so a wrong index shows.
    v = gissar.open_product(IW_SLC, swath="IW1", polarization="VV", burst=1, radiometry="sigma0").sigma0
    sub = v[300:340, 560:620]
    ref = sub.values
    assert ref.shape == (40, 60) and len(np.unique(ref)) > 100
    np.testing.assert_array_equal(sub[::-3, ::7].values, ref[::-3, ::7])
    np.testing.assert_array_equal(sub[5, ::-1].values, ref[5, ::-1])
    np.testing.assert_array_equal(sub[-1, -2].values, ref[-1, -2])
    np.testing.assert_array_equal(sub.isel(azimuth_time=[5, 0, 39, 5], slant_range=[59, 1]).values,
                                  ref[np.ix_([5, 0, 39, 5], [59, 1])])
    np.testing.assert_array_equal(sub[::20, 3:4].values, ref[::20, 3:4])
    assert sub[10:10, :].values.shape == (0, 60)


def test_noise_removal_subtracts_the_noise_power_and_clips_to_nan():
    ds = gissar.open_product(IW_SLC, swath="IW1", polarization="VV", burst=1, radiometry="sigma0",
                             noise_removal=True)
    assert ds.attrs["noise_removal"] == 1
    assert "noise-" + IW1_VV + ".xml" in ds.attrs["calibration"]
    assert any(f.endswith("noise-" + IW1_VV + ".xml") for f in ds.attrs["source_files"])
    noise_range = _lut(IW_SLC, "noise-" + IW1_VV + ".xml", "noiseRangeLut", "noiseRangeVector",
                       "noiseRangeVectorList")
    block = _xml(IW_SLC, "calibration", "noise-" + IW1_VV + ".xml").find("noiseAzimuthVectorList")[0]
    az_lines = np.array(block.find("line").text.split(), float)
    az_values = np.array(block.find("noiseAzimuthLut").text.split(), float)
    n = _bilinear(noise_range, 334, 540) * float(np.interp(334, az_lines, az_values))
    assert n == pytest.approx(498.053, abs=1e-3)  # |DN|^2 = 4 of the placeholder is far below it
    assert np.isnan(float(ds.sigma0[334, 540]))  # 4 - N < 0: NaN, not 0
    assert np.isnan(ds.sigma0[100:110, 1000:1010].values).all()


# ---------------------------------------------------------------- other forms and products

def test_a_zipped_safe_is_read_in_place(tmp_path):
    path = tmp_path / "S1B_IW_GRDH_test.zip"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as z:
        for folder, _, files in os.walk(IW_GRD):
            for f in files:
                full = os.path.join(folder, f)
                z.write(full, os.path.join(os.path.basename(IW_GRD), os.path.relpath(full, IW_GRD)))
    ds = gissar.open_product(path, swath="IW", polarization="VV")
    assert ds.amplitude.shape == (16685, 25788) and float(ds.amplitude[0, 0]) == 1.0


def test_a_lazy_dataset_pickles_by_its_arguments():
    ds = gissar.open_product(IW_SLC, swath="IW1", polarization="VV", burst=1, radiometry="sigma0")
    back = pickle.loads(pickle.dumps(ds))
    assert float(back.sigma0[577, 560]) == float(ds.sigma0[577, 560])


def test_nisar_rslc_complex_and_beta0():
    ds = gissar.open_product(ALOS, polarization="HH")
    assert ds.slc.dims == ("azimuth_time", "slant_range") and ds.slc.shape == (100, 50)
    assert complex(ds.slc[0, 0]) == complex(-122.5625, -411.5)  # as rslc_product_test reads it
    assert complex(ds.slc[50, 25]) == complex(7356.0, 20448.0)  # the corner reflector
    assert ds.attrs["product_type"] == "RSLC" and ds.attrs["frequency"] == "A"
    assert ds.azimuth_time.values.dtype == np.dtype("datetime64[ns]")
    assert np.all(np.diff(ds.slant_range.values) > 0)
    b = gissar.open_product(ALOS, polarization="HH", radiometry="beta0")  # the chip's beta0 LUT is 1
    assert float(b.beta0[50, 25]) == pytest.approx(7356.0 ** 2 + 20448.0 ** 2, rel=1e-7)
    assert "calibrationInformation/geometry/beta0" in b.attrs["calibration"]
    with pytest.raises(ValueError, match="beta0 only"):
        gissar.open_product(ALOS, radiometry="sigma0")
    with pytest.raises(ValueError, match="states no beta0 calibration"):
        gissar.open_product(UAVSAR, radiometry="beta0")
    with pytest.raises(ValueError, match="no bursts"):
        gissar.open_product(ALOS, burst=1)


# ---------------------------------------------------------------- errors

@pytest.mark.parametrize("kwargs, message", [
    (dict(swath="IW4"), "swath IW4 does not exist"),
    (dict(swath="IW1", polarization="HH"), "polarisation HH does not exist"),
    (dict(swath="IW1", polarization="VV", burst=10), "burst 10 does not exist; swath IW1 has bursts 1-9"),
    (dict(swath="IW1", polarization="VV", burst=0), "must be 1 or more"),
    (dict(swath="IW1", polarization="VV", burst="1"), "must be a burst number"),
    (dict(swath="IW1", polarization="VV", radiometry="sigma_0"), "unknown radiometry 'sigma_0'"),
    (dict(swath="IW1", polarization="VV", noise_removal=True), "noise removal needs a radiometry"),
    (dict(swath="IW1", polarization="VV", frequency="A"), "no frequency bands"),
])
def test_bad_arguments_are_value_errors(kwargs, message):
    with pytest.raises(gissar.ConfigError, match=message) as e:
        gissar.open_product(IW_SLC, **kwargs)
    assert isinstance(e.value, ValueError) and not isinstance(e.value, OSError)
    name = next(iter(k for k in kwargs if k in str(e.value)), None)
    assert name is not None, str(e.value)  # the message names the parameter


def test_a_burst_of_a_grd_is_a_value_error():
    with pytest.raises(ValueError, match="a GRD product has no bursts"):
        gissar.open_product(IW_GRD, polarization="VV", burst=1)


def test_missing_files_are_os_errors(tmp_path):
    with pytest.raises(OSError, match="product does not exist"):
        gissar.open_product(tmp_path / "S1A_nothing.SAFE")
    with pytest.raises(FileNotFoundError, match="product does not exist"):
        gissar.open_product(tmp_path / "nothing.h5")
    # A SAFE without its measurement/ folder.
    safe = tmp_path / os.path.basename(IW_SLC)
    shutil.copytree(IW_SLC, safe, ignore=shutil.ignore_patterns("*.tiff"))
    with pytest.raises(OSError, match="measurement file does not exist") as e:
        gissar.open_product(safe, swath="IW1", polarization="VV")
    assert "measurement/" + IW1_VV + ".tiff" in str(e.value)
    # The GRD's calibration annotation is listed by its manifest but not bundled.
    with pytest.raises(OSError, match="calibration annotation does not exist") as e:
        gissar.open_product(IW_GRD, polarization="VV", radiometry="sigma0")
    assert "calibration-" + GRD_VV + ".xml" in str(e.value)
