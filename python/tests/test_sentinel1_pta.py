"""`gissar pta` on a Sentinel-1 SLC: a point target written into a copy of the bundled IW SLC (whose measurement
TIFFs are constant placeholders, DN 2 + 0i) at a geolocation grid point, measured where the annotation alone puts
that point. Every expected figure is derived here from the annotation XML and the injected target, not from
gissar: the pixel from the grid point's azimuthTime and slantRangeTime, the sub-pixel offset as injected, the
-3 dB width of a sinc sampled at one sample per resolution cell (0.886 px) and beta0 = |DN|^2 / betaNought^2."""
import glob
import json
import math
import os
import shutil
import subprocess
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from osgeo import gdal

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
    """Adds AMPLITUDE x sinc(i - line) sinc(j - sample) to the placeholder over a (2 HALF + 1)^2 patch."""
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
