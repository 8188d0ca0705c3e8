"""`gissar geocode` of images simulated on a real radar grid (a Sentinel-1 burst window, a Sentinel-1 GRD window,
a NISAR-format RSLC): a trihedral placed at a known longitude and latitude is rendered by `simulate --product
--reflectors`, and the geocoded map must hold its peak at that longitude and latitude. The expected position is the
CSV row's, not anything gissar computed; the tolerance is one output pixel (the map's own sampling) plus the
impulse response's sub-pixel spread."""
import glob
import json
import math
import os
import subprocess
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from osgeo import gdal, osr

ROOT = os.environ.get("GISSAR_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
CLI = os.environ.get("GISSAR_CLI", "gissar")
S1 = os.path.join(ROOT, "data", "sentinel1")
SLC = os.path.join(S1, "S1B_IW_SLC__1SDV_20210401T052622_20210401T052650_026269_032297_EFA4.SAFE")
GRD = os.path.join(S1, "S1B_IW_GRDH_1SDV_20210401T052623_20210401T052648_026269_032297_ECC8.SAFE")
SANAND = os.path.join(ROOT, "data", "uavsar", "SanAnd_129.h5")
SANAND_DEM = os.path.join(ROOT, "data", "uavsar", "SanAnd_dem.tif")
PIXEL_M = 10.0


def run(*args):
    r = subprocess.run([CLI, *args, "--quiet"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return r


def seconds(text):
    return np.datetime64(text, "ns").astype("int64") * 1e-9


def hills(path, lat, lon, height):
    """Gentle hills (+-40 m) on the ellipsoid around (lat, lon), 0.0003 deg posts."""
    n, step = 300, 0.0003
    yy, xx = np.mgrid[0:n, 0:n]
    z = height + 40 * np.sin(xx / 23.0) * np.cos(yy / 31.0)
    ds = gdal.GetDriverByName("GTiff").Create(str(path), n, n, 1, gdal.GDT_Float32)
    ds.SetGeoTransform([lon - n / 2 * step, step, 0, lat + n / 2 * step, 0, -step])
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4979)
    ds.SetProjection(srs.ExportToWkt())
    ds.GetRasterBand(1).WriteArray(z.astype(np.float32))
    ds = None


def reflector_csv(path, lon, lat, boresight_azimuth_deg):
    path.write_text("type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n"
                    f"trihedral,{lon!r},{lat!r},0,2.0,{boresight_azimuth_deg},35.26439\n")


def peak_lonlat(prefix):
    """Longitude and latitude of the centre of the brightest map pixel of band 1."""
    ds = gdal.Open(str(prefix) + ".tif")
    band = ds.GetRasterBand(1).ReadAsArray()
    gt = ds.GetGeoTransform()
    srs = osr.SpatialReference()
    srs.ImportFromWkt(ds.GetProjection())
    ds = None
    row, col = np.unravel_index(np.nanargmax(band), band.shape)
    x, y = gt[0] + (col + 0.5) * gt[1], gt[3] + (row + 0.5) * gt[5]
    wgs = osr.SpatialReference()
    wgs.ImportFromEPSG(4326)
    wgs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    lon, lat, _ = osr.CoordinateTransformation(srs, wgs).TransformPoint(x, y)
    return lon, lat


def metres_between(lon1, lat1, lon2, lat2):
    north = (lat2 - lat1) * 111_320.0
    east = (lon2 - lon1) * 111_320.0 * math.cos(math.radians(lat1))
    return math.hypot(east, north)


def geocoded_peak_error_m(tmp_path, product_args, lon, lat, dem, look_azimuth_deg):
    csv = tmp_path / "cr.csv"
    reflector_csv(csv, lon, lat, (look_azimuth_deg + 180.0) % 360.0)
    sim = tmp_path / "sim"
    run("simulate", *product_args, "--dem", str(dem), "--reflectors", str(csv), "--out", str(sim))
    geo = tmp_path / "geo"
    run("geocode", "--image", str(sim) + ".tif", "--pixel-size", str(PIXEL_M), "--out", str(geo))
    record = json.load(open(str(geo) + ".json"))
    assert record["projection_mode"].startswith("radar grid (zero-Doppler geo2rdr")
    stac = json.load(open(str(geo) + "_stac.json"))
    assert abs(((stac["properties"]["view:azimuth"] - look_azimuth_deg) + 180) % 360 - 180) < 5
    return metres_between(lon, lat, *peak_lonlat(geo)), stac


def grid_point(annotation_xml, index):
    p = list(ET.parse(annotation_xml).getroot().iter("geolocationGridPoint"))[index]
    return {k: float(p.find(k).text) for k in ("latitude", "longitude", "height", "line", "pixel")} | {
        "azimuthTime": seconds(p.find("azimuthTime").text), "slantRangeTime": float(p.find("slantRangeTime").text)}


def test_geocode_of_a_sentinel1_burst_simulation_puts_a_reflector_at_its_coordinates(tmp_path):
    xml = glob.glob(os.path.join(SLC, "annotation", "s1b-iw1-slc-vv-*.xml"))[0]
    root = ET.parse(xml).getroot()
    dt = float(root.find("imageAnnotation/imageInformation/azimuthTimeInterval").text)
    tau0 = float(root.find("imageAnnotation/imageInformation/slantRangeTime").text)
    fs = float(root.find("generalAnnotation/productInformation/rangeSamplingRate").text)
    start = seconds(next(root.iter("burst")).find("azimuthTime").text)
    # A grid point inside burst 1 (line ~1341 of its 1500), and a reflector 300 m east, 200 m north of it.
    points = list(root.iter("geolocationGridPoint"))
    p = next(q for q in points if 100 < (seconds(q.find("azimuthTime").text) - start) / dt < 1400
             and 1000 < (float(q.find("slantRangeTime").text) - tau0) * fs < 20000)
    lat, lon, h = (float(p.find(k).text) for k in ("latitude", "longitude", "height"))
    row = int((seconds(p.find("azimuthTime").text) - start) / dt)
    col = int((float(p.find("slantRangeTime").text) - tau0) * fs)
    dem = tmp_path / "hills.tif"
    hills(dem, lat, lon, h)
    r_lon = lon + 300.0 / (111_320.0 * math.cos(math.radians(lat)))
    r_lat = lat + 200.0 / 111_320.0
    window = f"{row - 120},{col - 400},240,800"
    error, stac = geocoded_peak_error_m(
        tmp_path, ["--product", SLC, "--swath", "IW1", "--burst", "1", "--polarization", "VV",
                   "--product-window", window], r_lon, r_lat, dem, 281.0)
    assert error < 1.5 * PIXEL_M, error
    # The product's band, not the simulation's default X band.
    assert stac["properties"]["sar:frequency_band"] == "C"


def test_geocode_of_a_sentinel1_grd_simulation_puts_a_reflector_at_its_coordinates(tmp_path):
    xml = glob.glob(os.path.join(GRD, "annotation", "s1b-iw-grd-vv-*.xml"))[0]
    points = list(ET.parse(xml).getroot().iter("geolocationGridPoint"))
    p = points[len(points) // 2 + 3]
    lat, lon, h = (float(p.find(k).text) for k in ("latitude", "longitude", "height"))
    line, pixel = int(p.find("line").text), int(p.find("pixel").text)
    dem = tmp_path / "hills.tif"
    hills(dem, lat, lon, h)
    r_lon = lon - 250.0 / (111_320.0 * math.cos(math.radians(lat)))
    r_lat = lat + 150.0 / 111_320.0
    error, _ = geocoded_peak_error_m(
        tmp_path, ["--product", GRD, "--polarization", "VV", "--product-window", f"{line - 100},{pixel - 100},200,200"],
        r_lon, r_lat, dem, 281.0)
    assert error < 1.5 * PIXEL_M, error


def test_geocode_of_a_nisar_product_simulation_puts_a_reflector_at_its_coordinates(tmp_path):
    plain = tmp_path / "plain"
    run("simulate", "--product", SANAND, "--dem", SANAND_DEM, "--out", str(plain))
    # Some point inside the chip: the ground point of its middle pixel (lon_deg, lat_deg bands).
    ds = gdal.Open(str(plain) + ".tif")
    names = [ds.GetRasterBand(b + 1).GetDescription() for b in range(ds.RasterCount)]
    middle = (ds.RasterYSize // 2, ds.RasterXSize // 2)
    lon = float(ds.GetRasterBand(names.index("lon_deg") + 1).ReadAsArray()[middle])
    lat = float(ds.GetRasterBand(names.index("lat_deg") + 1).ReadAsArray()[middle])
    ds = None
    # The look azimuth of the chip, to face the trihedral at the sensor.
    run("geocode", "--image", str(plain) + ".tif", "--pixel-size", str(PIXEL_M), "--out", str(tmp_path / "pg"))
    look = json.load(open(str(tmp_path / "pg") + "_stac.json"))["properties"]["view:azimuth"]
    error, stac = geocoded_peak_error_m(tmp_path, ["--product", SANAND], lon, lat, SANAND_DEM, look)
    assert error < 1.5 * PIXEL_M, error
    assert stac["properties"]["sar:frequency_band"] == "L"
