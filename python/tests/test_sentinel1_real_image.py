"""Sentinel-1 real images through `gissar pta` and `gissar validate --dem`, on copies of the bundled products
(whose bundled measurement TIFFs hold a constant DN 2 + 0i, no scene) with known content written into them.

pta: a point target written at a geolocation grid point is measured where the annotation alone puts that point.
Every expected figure is derived here from the annotation XML and the injected target, not from gissar: the pixel
from the grid point's azimuthTime and slantRangeTime, the sub-pixel offset as injected, the -3 dB width of a sinc
sampled at one sample per resolution cell (0.886 px) and beta0 = |DN|^2 / betaNought^2.

validate: a simulated beta0 image written as DN = sqrt(beta0) x betaNought into the burst (or GRD) window is
compared by `validate` with its own simulation of that window: the same pixels and the same level (r = 1 to the DN
rounding, 0 dB), while the same image written 3 lines off correlates far less (the comparison is pixel by pixel
on the product's grid, not a match)."""
import glob
import json
import math
import os
import shutil
import subprocess
import textwrap
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from osgeo import gdal, osr

import gissar

ROOT = os.environ.get("GISSAR_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
SAFE = os.path.join(ROOT, "data", "sentinel1",
                    "S1B_IW_SLC__1SDV_20210401T052622_20210401T052650_026269_032297_EFA4.SAFE")
GRD = os.path.join(ROOT, "data", "sentinel1",
                   "S1B_IW_GRDH_1SDV_20210401T052623_20210401T052648_026269_032297_ECC8.SAFE")
CLI = os.environ.get("GISSAR_CLI", "gissar")

AMPLITUDE = 3000.0          # DN of the injected target's peak
OFFSET = (0.30, -0.20)      # injected (range, azimuth) offset from the grid point's pixel, px
HALF = 40                   # half-size of the injected patch, px


def seconds(text):
    return np.datetime64(text, "ns").astype("int64") * 1e-9


def annotation(root, swath="iw1", pol="vv"):
    path = glob.glob(os.path.join(root, "annotation", f"s1b-{swath}-slc-{pol}-*.xml"))[0]
    return path, ET.parse(path).getroot()


def grid_point_in_a_burst(ann):
    """A geolocation grid point well inside one burst: (burst number, line in the burst, sample, lat, lon, h)."""
    info = ann.find("imageAnnotation/imageInformation")
    dt = float(info.find("azimuthTimeInterval").text)
    tau0 = float(info.find("slantRangeTime").text)
    fs = float(ann.find("generalAnnotation/productInformation/rangeSamplingRate").text)
    lines = int(ann.find("swathTiming/linesPerBurst").text)
    samples = int(ann.find("swathTiming/samplesPerBurst").text)
    starts = [seconds(b.find("azimuthTime").text) for b in ann.iter("burst")]
    for p in ann.iter("geolocationGridPoint"):
        t = seconds(p.find("azimuthTime").text)
        col = (float(p.find("slantRangeTime").text) - tau0) * fs
        for number, start in enumerate(starts, 1):
            row = (t - start) / dt
            if 100 <= row <= lines - 100 and 200 <= col <= samples - 200:
                return (number, row, col, float(p.find("latitude").text), float(p.find("longitude").text),
                        float(p.find("height").text), lines)
    raise AssertionError("no grid point inside a burst")


def inject_target(safe, line, sample):
    """Adds AMPLITUDE x sinc(i - line) sinc(j - sample) to the constant image over a (2 HALF + 1)^2 patch."""
    tiff = glob.glob(os.path.join(safe, "measurement", "s1b-iw1-slc-vv-*.tiff"))[0]
    ds = gdal.Open(tiff, gdal.GA_Update)
    band = ds.GetRasterBand(1)
    i0, j0 = int(round(line)) - HALF, int(round(sample)) - HALF
    patch = band.ReadAsArray(j0, i0, 2 * HALF + 1, 2 * HALF + 1).astype(np.complex64)
    rows = np.sinc(np.arange(i0, i0 + 2 * HALF + 1) - line)
    cols = np.sinc(np.arange(j0, j0 + 2 * HALF + 1) - sample)
    patch += AMPLITUDE * np.outer(rows, cols)
    band.WriteArray(np.round(patch.real) + 1j * np.round(patch.imag), j0, i0)
    ds = None


def first_beta_nought(safe):
    path = glob.glob(os.path.join(safe, "annotation", "calibration", "calibration-s1b-iw1-slc-vv-*.xml"))[0]
    values = [float(v) for v in ET.parse(path).getroot().find(".//betaNought").text.split()]
    assert max(values) - min(values) < 1e-6 * values[0]  # constant in this product
    return values[0]


def run(*args):
    return subprocess.run([CLI, *args], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def target(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("s1pta")
    safe = str(tmp / os.path.basename(SAFE))
    shutil.copytree(SAFE, safe)
    _, ann = annotation(safe)
    burst, row, col, lat, lon, h, lines = grid_point_in_a_burst(ann)
    line = (burst - 1) * lines + row + OFFSET[1]
    inject_target(safe, line, col + OFFSET[0])
    csv = tmp / "reflector.csv"
    csv.write_text("type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n"
                   f"trihedral,{lon!r},{lat!r},0,1.0,0,35.26439\n")
    return dict(tmp=tmp, safe=safe, burst=burst, row=row, col=col, height=h, lines=lines, csv=str(csv))


def test_pta_measures_a_target_in_a_sentinel1_burst_where_the_annotation_puts_it(target):
    t = target
    out = str(t["tmp"] / "pta")
    r = run("pta", "--product", t["safe"], "--swath", "IW1", "--burst", str(t["burst"]), "--polarization", "VV",
            "--reflectors", t["csv"], "--ground-height", repr(t["height"]), "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    report = json.load(open(out + ".json"))
    assert report["options"]["burst"] == t["burst"] and report["options"]["swath"] == "IW1"
    m = report["reflectors"][0]
    assert m["found"], m
    # The prediction is the annotation's pixel of the grid point (gissar's geo2rdr against ESA's grid: 0.001 px).
    pred = m["prediction"]
    assert abs(pred["measurement_line"] - ((t["burst"] - 1) * t["lines"] + t["row"])) < 0.01
    assert abs(pred["measurement_sample"] - t["col"]) < 0.01
    # The peak sits at the injected offset from it.
    assert m["location_error_px"]["range"] == pytest.approx(OFFSET[0], abs=0.03)
    assert m["location_error_px"]["azimuth"] == pytest.approx(OFFSET[1], abs=0.03)
    # A sinc sampled once per resolution cell: -3 dB width 0.886 px in both directions.
    assert m["resolution_px"]["range"] == pytest.approx(0.886, abs=0.03)
    assert m["resolution_px"]["azimuth"] == pytest.approx(0.886, abs=0.03)
    # RCS: the target's energy (AMPLITUDE^2 x the sinc^2 sums over the energy box, 0.975 for 33 x 33 samples
    # around the peak) / betaNought^2 x the pixel's area on the slant plane.
    box = 2 * 16 + 1
    share = 1.0
    for d in OFFSET:
        k = np.arange(box) - box // 2
        share *= float(np.sum(np.sinc(k - d) ** 2))
    a_beta = first_beta_nought(t["safe"])
    expected = 10 * math.log10(AMPLITUDE ** 2 * share / a_beta ** 2 * m["range_spacing_m"] * m["azimuth_spacing_m"])
    assert m["calibrated"] is True
    assert m["rcs_dbsm"] == pytest.approx(expected, abs=0.15)
    assert pred["beta_nought_lut"] == pytest.approx(a_beta, rel=1e-9)
    assert report["source"]["kind"] == "Sentinel-1 SLC"
    # Only the window around the prediction was read.
    window = report["source"]["window_read"]
    assert window["lines"] < 100 and window["samples"] < 100


def test_python_door_takes_the_same_selection(target):
    t = target
    report = gissar.pta(t["csv"], t["tmp"] / "py", product=t["safe"], swath="IW1", burst=t["burst"],
                        polarization="VV", ground_height_m=t["height"])
    assert report["measured"] == 1


@pytest.mark.parametrize("args, names", [
    (["--product", SAFE, "--swath", "IW1"], "--burst"),                     # an IW SLC needs its burst
    (["--product", SAFE, "--swath", "IW1", "--burst", "99"], "--burst"),    # a burst it does not have
    (["--product", SAFE, "--swath", "IW7", "--burst", "2"], "--swath"),     # a swath it does not have
    (["--product", GRD, "--burst", "2"], "--burst"),                         # a GRD has no bursts
    (["--product", GRD], "GRD"),                                             # and no phase
])
def test_bad_sentinel1_selections_are_errors_naming_the_flag(tmp_path, args, names):
    csv = tmp_path / "r.csv"
    csv.write_text("type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n"
                   "trihedral,-3.7,40.4,0,1.0,0,35.26439\n")
    r = run("pta", *args, "--reflectors", str(csv), "--out", str(tmp_path / "x"), "--quiet")
    assert r.returncode == 2, r.stderr
    assert names in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not os.path.exists(tmp_path / "x.json")


# ---------------------------------------------------------------------------------------------------------------
# validate --product S1.SAFE --dem: the real image (calibrated to beta0) against the simulation of its window

LINES, PIXELS = 120, 360   # the window compared


def write_ellipsoid_dem(path, z, lat, lon, step):
    """Heights z (n x n, metres above the WGS84 ellipsoid, EPSG:4979) as a GeoTIFF centred on (lat, lon)."""
    n = z.shape[0]
    ds = gdal.GetDriverByName("GTiff").Create(str(path), n, n, 1, gdal.GDT_Float32)
    ds.SetGeoTransform([lon - n / 2 * step, step, 0, lat + n / 2 * step, 0, -step])
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4979)
    ds.SetProjection(srs.ExportToWkt())
    ds.GetRasterBand(1).WriteArray(z.astype(np.float32))
    ds = None


def hills_dem(path, lat, lon, height):
    """Smooth hills (+-180 m) around (lat, lon) on the ellipsoid, 0.0003 deg posts, 0.078 deg a side."""
    n, step = 260, 0.0003
    yy, xx = np.mgrid[0:n, 0:n]
    x, y = xx * step * 85000.0, yy * step * 111000.0
    z = height + 120 * np.sin(x / 450.0) * np.cos(y / 650.0) + 60 * np.sin((x + y) / 300.0)
    write_ellipsoid_dem(path, z, lat, lon, step)


def read_band(path):
    ds = gdal.Open(str(path))
    values = ds.GetRasterBand(1).ReadAsArray()
    ds = None
    return values


def write_dn(tiff, dn, line, pixel):
    ds = gdal.Open(tiff, gdal.GA_Update)
    ds.GetRasterBand(1).WriteArray(dn, pixel, line)
    ds = None


def grd_calibration(safe, a_beta):
    """The bundled GRD lacks its calibration annotation: a LUT constant at a_beta over the whole image, at the path
    its manifest names (two vectors, first and last line, first and last pixel)."""
    _, ann = grd_annotation(safe)
    info = ann.find("imageAnnotation/imageInformation")
    lines, samples = int(info.find("numberOfLines").text), int(info.find("numberOfSamples").text)
    first, last = info.find("productFirstLineUtcTime").text, info.find("productLastLineUtcTime").text
    vectors = "".join(f"""
        <calibrationVector><azimuthTime>{t}</azimuthTime><line>{line}</line>
          <pixel count="2">0 {samples - 1}</pixel>
          <sigmaNought count="2">{a_beta} {a_beta}</sigmaNought><betaNought count="2">{a_beta} {a_beta}</betaNought>
          <gamma count="2">{a_beta} {a_beta}</gamma><dn count="2">{a_beta} {a_beta}</dn></calibrationVector>"""
                      for t, line in ((first, 0), (last, lines - 1)))
    xml = textwrap.dedent(f"""\
        <?xml version="1.0" encoding="UTF-8"?>
        <calibration><calibrationInformation><absoluteCalibrationConstant>1</absoluteCalibrationConstant>
        </calibrationInformation><calibrationVectorList count="2">{vectors}</calibrationVectorList></calibration>
        """)
    path = os.path.join(safe, "annotation", "calibration",
                        "calibration-" + os.path.basename(grd_annotation(safe)[0]))
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(xml)


def grd_annotation(safe):
    path = glob.glob(os.path.join(safe, "annotation", "s1b-iw-grd-vv-*.xml"))[0]
    return path, ET.parse(path).getroot()


def simulate_window(safe, selection, window, dem, out):
    r = run("simulate", "--product", safe, *selection, "--product-window", ",".join(map(str, window)),
            "--dem", str(dem), "--vertical-datum", "ellipsoid", "--radiometry", "beta0",
            "--range-resolution", "0", "--azimuth-resolution", "0", "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    return read_band(str(out) + ".tif")


def validate(safe, selection, window, dem, out):
    r = run("validate", "--product", safe, *selection, "--product-window", ",".join(map(str, window)),
            "--dem", str(dem), "--vertical-datum", "ellipsoid", "--looks", "1,3", "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    return json.load(open(str(out) + ".json"))


@pytest.fixture(scope="module")
def burst_scene(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("s1validate")
    _, ann = annotation(SAFE)
    burst, row, col, lat, lon, h, lines = grid_point_in_a_burst(ann)
    dem = tmp / "hills.tif"
    hills_dem(dem, lat, lon, h)
    window = (int(row) - LINES // 2, int(col) - PIXELS // 2, LINES, PIXELS)
    selection = ["--swath", "IW1", "--burst", str(burst), "--polarization", "VV"]
    beta0 = simulate_window(SAFE, selection, window, dem, tmp / "sim")
    dn = np.where(np.isfinite(beta0), np.round(np.sqrt(np.nan_to_num(beta0)) * first_beta_nought(SAFE)), 0)
    return dict(tmp=tmp, dem=dem, window=window, selection=selection, dn=dn.astype(np.complex64),
                first_line=(burst - 1) * lines + window[0])


def test_validate_compares_a_burst_with_its_real_image_pixel_for_pixel(burst_scene):
    s = burst_scene
    safe = str(s["tmp"] / "same.SAFE")
    shutil.copytree(SAFE, safe)
    tiff = glob.glob(os.path.join(safe, "measurement", "s1b-iw1-slc-vv-*.tiff"))[0]
    write_dn(tiff, s["dn"], s["first_line"], s["window"][1])
    report = validate(safe, s["selection"], s["window"], s["dem"], s["tmp"] / "same")
    one, three = report["correlation"]
    assert one["looks"] == 1 and one["r_db"] > 0.999 and one["r_intensity"] > 0.999
    assert three["r_db"] > 0.999
    assert report["level_difference_db"]["real_minus_simulated_median_db"] == pytest.approx(0.0, abs=0.02)
    assert report["pixels_geolocated"] > 0.98 * LINES * PIXELS
    assert report["real_image"].startswith("beta0 = |DN|^2 / betaNought^2")
    assert report["inputs"][0]["path"].endswith("same.SAFE")

    # The same image 3 lines off: the comparison is pixel for pixel, so it drops.
    shifted = str(s["tmp"] / "shifted.SAFE")
    shutil.copytree(SAFE, shifted)
    tiff = glob.glob(os.path.join(shifted, "measurement", "s1b-iw1-slc-vv-*.tiff"))[0]
    write_dn(tiff, s["dn"], s["first_line"] + 3, s["window"][1])
    off = validate(shifted, s["selection"], s["window"], s["dem"], s["tmp"] / "shifted")
    assert off["correlation"][0]["r_db"] < 0.99 * one["r_db"] - 0.02


def test_validate_compares_a_grd_on_its_ground_range_pixels(tmp_path):
    safe = str(tmp_path / os.path.basename(GRD))
    shutil.copytree(GRD, safe)
    a_beta = 474.0
    grd_calibration(safe, a_beta)
    # A geolocation grid point in the middle of the GRD and hills around it.
    _, ann = grd_annotation(safe)
    points = list(ann.iter("geolocationGridPoint"))
    p = points[len(points) // 2 + 3]
    line, pixel = int(p.find("line").text), int(p.find("pixel").text)
    dem = tmp_path / "hills.tif"
    hills_dem(dem, float(p.find("latitude").text), float(p.find("longitude").text), float(p.find("height").text))
    window = (line - 60, pixel - 60, 120, 120)
    beta0 = simulate_window(safe, ["--polarization", "VV"], window, dem, tmp_path / "sim")
    dn = np.where(np.isfinite(beta0), np.round(np.sqrt(np.nan_to_num(beta0)) * a_beta), 0).astype(np.uint16)
    write_dn(glob.glob(os.path.join(safe, "measurement", "s1b-iw-grd-vv-*.tiff"))[0], dn, window[0], window[1])
    report = validate(safe, ["--polarization", "VV"], window, dem, tmp_path / "grd")
    assert report["correlation"][0]["r_db"] > 0.999
    assert report["level_difference_db"]["real_minus_simulated_median_db"] == pytest.approx(0.0, abs=0.02)


def test_validate_of_a_grd_without_its_calibration_names_the_file(tmp_path):
    dem = tmp_path / "hills.tif"
    hills_dem(dem, 46.9, 12.3, 2000.0)
    r = run("validate", "--product", GRD, "--product-window", "100,100,20,20", "--dem", str(dem),
            "--out", str(tmp_path / "v"), "--quiet")
    assert r.returncode == 2
    assert "calibration" in r.stderr and "does not exist" in r.stderr
    assert not os.path.exists(tmp_path / "v.json")


# ---------------------------------------------------------------------------------------------------------------
# locate / evaluate --product S1.SAFE: the product's own track fixed from a displaced prior

def rough_dem(path, lat, lon, height, seed=3):
    """Twelve seeded sinusoidal ridges (wavelengths 150-900 m, amplitudes 20-70 m) around (lat, lon), on the
    ellipsoid, 0.0003 deg posts: relief at the scale of the multilooked cells in every direction."""
    n, step = 320, 0.0003
    yy, xx = np.mgrid[0:n, 0:n]
    x, y = xx * step * 76000.0, yy * step * 111000.0
    rng = np.random.default_rng(seed)
    z = np.full((n, n), height)
    for _ in range(12):
        wavelength, theta = rng.uniform(150, 900), rng.uniform(0, np.pi)
        phase, amplitude = rng.uniform(0, 2 * np.pi), rng.uniform(20, 70)
        z += amplitude * np.sin(2 * np.pi * (x * np.cos(theta) + y * np.sin(theta)) / wavelength + phase)
    write_ellipsoid_dem(path, z, lat, lon, step)


@pytest.fixture(scope="module")
def observed_burst(tmp_path_factory):
    """A copy of the IW SLC whose IW1 burst holds, in a 200 x 600 window, the simulation of that window on rough
    terrain (the observed image; the annotated track is the truth)."""
    tmp = tmp_path_factory.mktemp("s1locate")
    safe = str(tmp / os.path.basename(SAFE))
    shutil.copytree(SAFE, safe)
    _, ann = annotation(safe)
    burst, row, col, lat, lon, h, lines = grid_point_in_a_burst(ann)
    dem = tmp / "rough.tif"
    rough_dem(dem, lat, lon, h)
    window = (int(row) - 100, int(col) - 300, 200, 600)
    selection = ["--swath", "IW1", "--burst", str(burst), "--polarization", "VV"]
    beta0 = simulate_window(safe, selection, window, dem, tmp / "observed")
    dn = np.where(np.isfinite(beta0), np.round(np.sqrt(np.nan_to_num(beta0)) * first_beta_nought(safe)), 0)
    tiff = glob.glob(os.path.join(safe, "measurement", "s1b-iw1-slc-vv-*.tiff"))[0]
    write_dn(tiff, dn.astype(np.complex64), (burst - 1) * lines + window[0], window[1])
    common = [*selection, "--product-window", ",".join(map(str, window)), "--dem", str(dem),
              "--vertical-datum", "ellipsoid", "--looks-range", "6", "--looks-azimuth", "2"]
    return dict(tmp=tmp, safe=safe, common=common)


def test_locate_fixes_a_sentinel1_track_from_a_displaced_prior(observed_burst):
    o = observed_burst
    # A satellite's track angle is known to microradians; over a window seen from 800 km an along-track shift
    # and a heading turn move the image alike, so the heading is held at the prior (docs/sentinel1.md).
    out = str(o["tmp"] / "fix.json")
    r = run("locate", "--product", o["safe"], *o["common"], "--prior-offset-track", "60,30,0",
            "--prior-sigma-heading", "0.00001", "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    fix = json.load(open(out))
    assert fix["converged"] and fix["fix_source"] == "relief"
    correction = fix["fix"]["correction"]
    # The prior was 60 m ahead and 30 m right of the annotated track: the fix moves it back.
    assert correction["along_m"] == pytest.approx(-60.0, abs=10.0)
    assert correction["cross_m"] == pytest.approx(-30.0, abs=12.0)
    assert "error against the annotated track" in r.stdout
    error_m = float(r.stdout.split("error against the annotated track ")[1].split(" m")[0])
    assert error_m < 15.0 < 67.0  # the prior's error is 67.1 m
    assert fix["inputs"]["product"]["kind"] == "Sentinel-1 SAFE"


def test_evaluate_runs_seeded_trials_on_a_sentinel1_burst(observed_burst):
    o = observed_burst
    out = o["tmp"] / "trials"
    r = run("evaluate", "--product", o["safe"], *o["common"], "--prior-error-horizontal", "60",
            "--prior-error-vertical", "5", "--prior-error-heading", "0", "--trials", "4", "--seed", "1",
            "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    summary = json.load(open(str(out) + ".json"))
    assert summary["success_rate"] == 1.0
    assert summary["position_error_cells"]["median"] < 0.6


def test_locate_refuses_a_grd_and_a_selection_without_a_safe(tmp_path):
    dem = tmp_path / "rough.tif"
    rough_dem(dem, 46.9, 12.3, 2000.0)
    r = run("locate", "--product", GRD, "--polarization", "VV", "--dem", str(dem), "--out", str(tmp_path / "f.json"),
            "--quiet")
    assert r.returncode == 2 and "slant-range grid" in r.stderr and "GRDH" in r.stderr
    r = run("locate", "--product", os.path.join(ROOT, "data", "uavsar", "SanAnd_129.h5"), "--burst", "2",
            "--dem", str(dem), "--out", str(tmp_path / "f.json"), "--quiet")
    assert r.returncode == 2 and "--burst" in r.stderr


# ---------------------------------------------------------------------------------------------------------------
# validate --radiometry / --noise-removal: the real image calibrated with the LUT named, the simulation alike

def line_vectors_at(path, vector, tag, lines, pixels):
    """The LUT `tag` of the `vector` elements of an IW1 VV annotation at measurement `lines` x `pixels`, interpolated
    as the product specification says: linearly in pixel along the two vectors bracketing the line, then linearly
    in line; beyond the table the nearest edge value."""
    rows, along = [], []
    for v in ET.parse(path).getroot().iter(vector):
        rows.append(int(v.find("line").text))
        along.append(np.interp(pixels, [float(x) for x in v.find("pixel").text.split()],
                               [float(x) for x in v.find(tag).text.split()]))
    rows, along = np.array(rows), np.array(along)
    out = np.empty((len(lines), len(pixels)))
    for i, line in enumerate(lines):
        k = int(np.clip(np.searchsorted(rows, line, side="right") - 1, 0, len(rows) - 2))
        f = float(np.clip((line - rows[k]) / (rows[k + 1] - rows[k]), 0.0, 1.0))
        out[i] = (1.0 - f) * along[k] + f * along[k + 1]
    return out


def calibration_lut(safe, tag, lines, pixels):
    """ESA's calibration LUT `tag` (sigmaNought, betaNought, gamma) of IW1 VV."""
    path = glob.glob(os.path.join(safe, "annotation", "calibration", "calibration-s1b-iw1-slc-vv-*.xml"))[0]
    return line_vectors_at(path, "calibrationVector", tag, lines, pixels)


def noise_power(safe, lines, pixels):
    """IW1 VV's thermal noise power: noiseRangeLut (bilinear) x noiseAzimuthLut (linear in line). This product has
    one azimuth block, covering every line and sample (checked)."""
    path = glob.glob(os.path.join(safe, "annotation", "calibration", "noise-s1b-iw1-slc-vv-*.xml"))[0]
    blocks = list(ET.parse(path).getroot().iter("noiseAzimuthVector"))
    assert len(blocks) == 1 and int(blocks[0].find("firstRangeSample").text) == 0
    assert int(blocks[0].find("lastRangeSample").text) >= pixels[-1]
    azimuth = np.interp(lines, [float(x) for x in blocks[0].find("line").text.split()],
                        [float(x) for x in blocks[0].find("noiseAzimuthLut").text.split()])
    return line_vectors_at(path, "noiseRangeVector", "noiseRangeLut", lines, pixels) * azimuth[:, None]


def level_difference_db(simulated, real, height, k=3):
    """validate's level_difference_db as docs/sentinel1.md defines it: over the k x k blocks whose pixels all have a
    ground point and a positive real value, the median of 10 log10 of the real block sums minus that of the
    simulated ones (the element at index n // 2 of each sorted list, as the report takes it)."""
    valid = np.isfinite(height) & np.isfinite(real) & (np.nan_to_num(real) > 0)
    a, b = [], []
    for r0 in range(0, simulated.shape[0] - k + 1, k):
        for c0 in range(0, simulated.shape[1] - k + 1, k):
            if not valid[r0:r0 + k, c0:c0 + k].all():
                continue
            sa, sb = float(np.sum(simulated[r0:r0 + k, c0:c0 + k])), float(np.sum(real[r0:r0 + k, c0:c0 + k]))
            if sa > 0 and sb > 0:
                a.append(10 * math.log10(sa))
                b.append(10 * math.log10(sb))
    return sorted(b)[len(b) // 2] - sorted(a)[len(a) // 2], len(a)


def simulate_window_in(radiometry, safe, selection, window, dem, out):
    r = run("simulate", "--product", safe, *selection, "--product-window", ",".join(map(str, window)),
            "--dem", str(dem), "--vertical-datum", "ellipsoid", "--radiometry", radiometry,
            "--range-resolution", "0", "--azimuth-resolution", "0", "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    return read_band(str(out) + ".tif")


def validate_in(radiometry, safe, selection, window, dem, out):
    r = run("validate", "--product", safe, *selection, "--product-window", ",".join(map(str, window)),
            "--dem", str(dem), "--vertical-datum", "ellipsoid", "--looks", "1,3", "--radiometry", radiometry,
            "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    return json.load(open(str(out) + ".json"))


def test_validate_radiometry_calibrates_the_real_image_with_the_lut_it_names(burst_scene):
    s = burst_scene
    window = s["window"]
    lines = s["first_line"] + np.arange(window[2])
    pixels = window[1] + np.arange(window[3])
    a_sigma = calibration_lut(SAFE, "sigmaNought", lines, pixels)
    a_gamma = calibration_lut(SAFE, "gamma", lines, pixels)
    a_beta = first_beta_nought(SAFE)  # constant in this product (checked there)
    assert a_sigma.max() - a_sigma.min() > 0.1  # sigmaNought is not: it is interpolated per pixel
    # The real image: the simulation in sigma0 written as DN = round(sqrt(sigma0) x sigmaNought).
    sigma0 = simulate_window_in("sigma0", SAFE, s["selection"], window, s["dem"], s["tmp"] / "sim_sigma0")
    ds = gdal.Open(str(s["tmp"] / "sim_sigma0.tif"))
    height = ds.GetRasterBand(8).ReadAsArray()  # band 8: height_m, NaN where a pixel has no ground point
    ds = None
    beta0 = read_band(s["tmp"] / "sim.tif")  # the fixture's beta0 simulation of the same window
    dn = np.where(np.isfinite(sigma0), np.round(np.sqrt(np.nan_to_num(sigma0)) * a_sigma), 0)
    safe = str(s["tmp"] / "sigma.SAFE")
    shutil.copytree(SAFE, safe)
    tiff = glob.glob(os.path.join(safe, "measurement", "s1b-iw1-slc-vv-*.tiff"))[0]
    write_dn(tiff, dn.astype(np.complex64), s["first_line"], window[1])

    # Compared in sigma0: the same pixels at the same level.
    report = validate_in("sigma0", safe, s["selection"], window, s["dem"], s["tmp"] / "v_sigma0")
    one, three = report["correlation"]
    assert one["r_db"] > 0.999 and three["r_db"] > 0.999
    level_sigma0 = report["level_difference_db"]["real_minus_simulated_median_db"]
    assert level_sigma0 == pytest.approx(0.0, abs=0.02)
    assert report["radiometry"]["quantity"] == "sigma0" and report["radiometry"]["noise_removal"] is False
    assert report["real_image"].startswith("sigma0 = |DN|^2 / sigmaNought^2")
    assert report["options"]["radiometry"] == "sigma0"
    real = np.where(dn > 0, dn ** 2 / a_sigma ** 2, np.nan)
    expected, blocks = level_difference_db(sigma0, real, height)
    assert blocks == report["level_difference_db"]["blocks"]
    assert level_sigma0 == pytest.approx(expected, abs=0.001)

    # Compared in beta0 (and gamma0), the same real image: real beta0 = DN^2 / betaNought^2 = sigma0_sim x
    # sigmaNought^2 / betaNought^2 (to the DN rounding), against the simulated beta0_sim = sigma0_sim / sin(theta_i),
    # theta_i gissar's ellipsoid incidence of the pixel. Per pixel the ratio real / simulated is therefore
    # rho = sigmaNought^2 / betaNought^2 x sin(theta_i), with sin(theta_i) = sigma0_sim / beta0_sim read from the
    # two simulations; in gamma0 (gamma0_sim = sigma0_sim / cos(theta_i)) rho = sigmaNought^2 / gamma^2 x
    # cos(theta_i). The level difference (the median of the real 3 x 3 block means in dB minus the median of the
    # simulated ones) lies between the least and the largest 10 log10(rho) of the window (a block mean of
    # real = rho x simulated is within rho's range times the simulated mean, and shifting every value by at least
    # lo and at most hi dB shifts the median so), near its middle. ESA derives sigmaNought and gamma from betaNought
    # with its own ellipsoid incidence (sigmaNought^2 = betaNought^2 / sin(theta_ESA), gamma^2 = sigmaNought^2 x
    # cos(theta_ESA)), so rho is sin(theta_gissar) / sin(theta_ESA) (cos / cos in gamma0): near 1, and
    # 10 log10(rho) measures how well the two incidences agree (31.12 against 31.10 degrees here).
    ok = np.isfinite(beta0) & np.isfinite(sigma0) & (beta0 > 0) & (sigma0 > 0)
    sin_incidence = np.where(ok, sigma0 / np.where(ok, beta0, 1.0), np.nan)
    assert 0.2 < np.nanmedian(sin_incidence) < 0.8
    for quantity, rho in (("beta0", a_sigma ** 2 / a_beta ** 2 * sin_incidence),
                          ("gamma0", a_sigma ** 2 / a_gamma ** 2 * np.sqrt(1 - sin_incidence ** 2))):
        rho_db = 10 * np.log10(rho)
        lo, hi, middle = np.nanmin(rho_db), np.nanmax(rho_db), float(np.nanmedian(rho_db))
        assert hi - lo < 0.02
        report = validate_in(quantity, safe, s["selection"], window, s["dem"], s["tmp"] / ("v_" + quantity))
        level = report["level_difference_db"]["real_minus_simulated_median_db"]
        assert lo - 0.005 <= level <= hi + 0.005, (quantity, lo, hi, level)
        assert level == pytest.approx(middle, abs=0.01)
        assert report["correlation"][0]["r_db"] > 0.999
        assert report["radiometry"]["quantity"] == quantity
        lut = {"beta0": "betaNought", "gamma0": "gamma"}[quantity]
        assert report["real_image"].startswith(f"{quantity} = |DN|^2 / {lut}^2")
    # Had the beta0 real image been read with the sigmaNought LUT (or the simulation stayed in sigma0) the level
    # would be off by 10 log10(sin theta_i), about -2.9 dB here: the figures above tell the LUTs apart.
    assert 10 * np.log10(np.nanmedian(sin_incidence)) < -2.0

    # With --noise-removal the real image is (DN^2 - N) / sigmaNought^2, N the noise LUTs (about 500 against a
    # median DN^2 of about 6000): the level drops by the figure the test computes from the noise annotation.
    r = run("validate", "--product", safe, *s["selection"], "--product-window", ",".join(map(str, window)),
            "--dem", str(s["dem"]), "--vertical-datum", "ellipsoid", "--looks", "1,3", "--radiometry", "sigma0",
            "--noise-removal", "--out", str(s["tmp"] / "v_noise"), "--quiet")
    assert r.returncode == 0, r.stderr
    report = json.load(open(str(s["tmp"] / "v_noise") + ".json"))
    power = dn ** 2 - noise_power(SAFE, lines, pixels)
    real = np.where((dn > 0) & (power >= 0), power / a_sigma ** 2, np.nan)
    expected, blocks = level_difference_db(sigma0, real, height)
    level = report["level_difference_db"]["real_minus_simulated_median_db"]
    assert blocks == report["level_difference_db"]["blocks"]
    assert level == pytest.approx(expected, abs=0.001) and level < level_sigma0 - 0.1
    assert report["radiometry"]["noise_removal"] is True and report["options"]["noise_removal"] is True
    assert report["real_image"].startswith("sigma0 = (|DN|^2 - N) / sigmaNought^2")
    assert report["correlation"][1]["r_db"] > 0.99


def test_validate_noise_removal_on_the_constant_image_leaves_no_valid_pixel(burst_scene):
    """The bundled burst holds DN 2 (|DN|^2 = 4) under a thermal noise power of about 500: with --noise-removal
    every real pixel is negative, hence no-data; validate says so, naming the flag, and writes nothing."""
    s = burst_scene
    out = s["tmp"] / "noise"
    r = run("validate", "--product", SAFE, *s["selection"], "--product-window", ",".join(map(str, s["window"])),
            "--dem", str(s["dem"]), "--vertical-datum", "ellipsoid", "--noise-removal", "--out", str(out), "--quiet")
    assert r.returncode == 2, r.stderr
    assert "no valid real pixel after noise removal" in r.stderr and "--noise-removal" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not glob.glob(str(out) + "*")


def test_validate_radiometry_and_noise_removal_with_a_nisar_product_are_refused(tmp_path):
    dem = tmp_path / "hills.tif"
    hills_dem(dem, 35.0, -120.0, 500.0)
    nisar = os.path.join(ROOT, "data", "uavsar", "SanAnd_129.h5")
    for extra, flag, words in ((["--radiometry", "sigma0"], "--radiometry", "beta0"),
                               (["--radiometry", "gamma0"], "--radiometry", "beta0"),
                               (["--noise-removal"], "--noise-removal", "Sentinel-1")):
        r = run("validate", "--product", nisar, "--dem", str(dem), *extra, "--out", str(tmp_path / "v"), "--quiet")
        assert r.returncode == 2, r.stderr
        assert flag in r.stderr and words in r.stderr
        assert not os.path.exists(tmp_path / "v.json")
