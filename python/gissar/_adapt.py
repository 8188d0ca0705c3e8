"""The Python door's adaptation layer: rasters in (paths, GDAL datasets, NumPy arrays with a transform and a
CRS, rioxarray DataArrays) and xarray out (coordinates in metres, band names, units, provenance, masks with
flag names), progress (callable or tqdm) and Ctrl-C. No pipeline logic: the compiled core computes, this
module only converts arguments and results.
"""
import contextlib
import json
import os
import sys
import threading
import uuid
import warnings

import numpy as np

from . import _core

#: The bands of an image result, as the GeoTIFF band descriptions of `gissar simulate`.
BAND_NAMES = ("total", "single", "double", "triple", "four_or_more")
#: The mask's categories (docs/geometry.md): bit 1 layover, bit 2 shadow, 255 outside the imaged footprint.
MASK_FLAG_VALUES = (0, 1, 2, 3, 255)
MASK_FLAG_MEANINGS = "none layover shadow layover_and_shadow outside_footprint"


# ---------------------------------------------------------------- arrays in

class ArrayTypeError(_core.InputError, TypeError):
    """An array argument whose values are not real numbers (bool, complex, text, other objects): both a
    gissar.InputError (ValueError) and a TypeError."""


ArrayTypeError.__module__ = "gissar"


def real_array(value, what, *, ndim=2, dtype=np.float32, content="real numbers", shape_text=None, empty_ok=False,
               complex_hint=""):
    """`value` (an array, a DataArray, nested lists) as a C-contiguous array of the native `dtype` (float32 or
    float64), after checking what the conversion would hide: bool, complex and non-numeric values are an
    ArrayTypeError, a wrong number of dimensions (or an empty array) an InputError, both naming `what`.
    Integers, float16/32/64 of either byte order and any memory layout (strides, Fortran order) are
    converted; the values are those of `np.asarray(value).astype(dtype)`."""
    if _is_dataarray(value):
        value = value.values
    if value is None:
        raise ArrayTypeError(f"must be an array of {content}, got None ({what})")
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as e:  # e.g. ragged nested lists
        raise ArrayTypeError(f"must be an array of {content}: {e} ({what})") from None
    if a.dtype.kind == "O":
        try:
            a = a.astype(np.float64)
        except (TypeError, ValueError):
            raise ArrayTypeError(f"must be an array of {content}, got objects that are not numbers ({what})") from None
    if a.dtype.kind == "b":
        raise ArrayTypeError(f"must be an array of {content}, got a bool array (convert it explicitly, e.g. "
                             f".astype(np.float32)) ({what})")
    if a.dtype.kind == "c":
        raise ArrayTypeError(f"must be an array of {content}, got complex values ({a.dtype}){complex_hint} ({what})")
    if a.dtype.kind not in "iuf":
        raise ArrayTypeError(f"must be an array of {content}, got dtype {a.dtype} ({what})")
    if a.ndim != ndim or (a.size == 0 and not empty_ok):
        shape = shape_text or f"a non-empty {ndim}-D array"
        raise _core.InputError(f"must be {shape}, got {'an empty array of ' if a.size == 0 else ''}shape "
                               f"{a.shape} ({what})")
    return np.ascontiguousarray(a, dtype=dtype)


def image_values(value, what):
    """A 2-D image (rows = azimuth, columns = range) of real numbers as contiguous native float32."""
    return real_array(value, what, content="real intensities",
                      shape_text="a non-empty 2-D array (rows = azimuth, columns = range)",
                      complex_hint=": give the intensity np.abs(z)**2")


def points_values(value, what, columns):
    """An (N, columns) array of real coordinates as contiguous native float64."""
    a = real_array(value, what, dtype=np.float64, content="real coordinates", empty_ok=True,
                   shape_text=f"an (N, {columns}) array")
    if a.shape[1] != columns:
        raise _core.InputError(f"must be an (N, {columns}) array, got shape {a.shape} ({what})")
    return a


def matrix_values(value, what, rows, columns):
    """A rows x columns matrix of real numbers as contiguous native float64."""
    a = real_array(value, what, dtype=np.float64, content="real numbers", shape_text=f"a {rows} x {columns} matrix")
    if a.shape != (rows, columns):
        raise _core.InputError(f"must be a {rows} x {columns} matrix, got shape {a.shape} ({what})")
    return a


def uint8_values(value, what):
    """Picture pixels as contiguous uint8: uint8 itself, or integers all within 0..255 (converted exactly).
    Floats are refused rather than truncated (0.7 would become 0)."""
    if _is_dataarray(value):
        value = value.values
    a = np.asarray(value)
    if a.dtype.kind == "u" and a.dtype.itemsize == 1:
        return np.ascontiguousarray(a)
    if a.dtype.kind in "iu" and (a.size == 0 or (int(a.min()) >= 0 and int(a.max()) <= 255)):
        return np.ascontiguousarray(a, dtype=np.uint8)
    if a.dtype.kind in "iu":
        raise _core.InputError(f"pixel values must be within 0..255, got {int(a.min())}..{int(a.max())} ({what})")
    raise ArrayTypeError(f"must be a uint8 array (0..255), got dtype {a.dtype}: scale floats yourself, e.g. "
                         f"(np.clip(x, 0, 1) * 255).astype(np.uint8), or use gissar.quicklook ({what})")


# ---------------------------------------------------------------- rasters in

def _crs_text(crs, what):
    if crs is None:
        return None
    if isinstance(crs, (int, np.integer)) and not isinstance(crs, bool):
        return f"EPSG:{int(crs)}"
    if hasattr(crs, "to_wkt"):  # pyproj.CRS, rasterio CRS
        return crs.to_wkt()
    if isinstance(crs, str):
        return crs
    raise _core.ConfigError(f"must be an EPSG code, a WKT/'EPSG:n' string or a pyproj CRS, got "
                            f"{type(crs).__name__} ({what})")


def _transform_coefficients(transform, what):
    if hasattr(transform, "to_gdal"):  # affine.Affine
        transform = transform.to_gdal()
    try:
        gt = [float(v) for v in transform]
    except (TypeError, ValueError):
        gt = []
    if len(gt) != 6:
        raise _core.ConfigError(f"needs GDAL's six coefficients (x0, dx, rx, y0, ry, dy) or an affine.Affine "
                                f"({what})")
    if not all(np.isfinite(gt)):
        raise _core.ConfigError(f"coefficients must be finite, got {gt} ({what})")
    if gt[1] * gt[5] - gt[2] * gt[4] == 0.0:
        raise _core.ConfigError(f"is singular (a zero pixel size, or rows parallel to columns): {gt}; GDAL's order "
                                f"is (x0, dx, rx, y0, ry, dy) ({what})")
    return gt


def _nodata_value(nodata, what):
    if nodata is None:
        return None
    if isinstance(nodata, (bool, np.bool_)) or not isinstance(nodata, (int, float, np.integer, np.floating)):
        raise ArrayTypeError(f"must be a real number or None, got {type(nodata).__name__} ({what})")
    return float(nodata)


def _is_dataarray(value):
    return type(value).__name__ == "DataArray" and hasattr(value, "dims")


def _is_gdal_dataset(value):
    return type(value).__name__ == "Dataset" and hasattr(value, "GetRasterBand")


def _array_from_dataarray(da, what):
    """(values, transform, crs, nodata) of a rioxarray-georeferenced DataArray (a single band)."""
    if "band" in da.dims:
        if da.sizes["band"] != 1:
            raise _core.ConfigError(f"a DataArray with {da.sizes['band']} bands: select one ({what})")
        da = da.squeeze("band", drop=True)
    try:
        transform = da.rio.transform(recalc=False)
        crs = da.rio.crs
        nodata = da.rio.nodata if da.rio.nodata is not None else da.rio.encoded_nodata
    except AttributeError:
        raise _core.ConfigError(f"a DataArray needs rioxarray georeferencing (import rioxarray; .rio.crs) "
                                f"({what})") from None
    if crs is None:
        raise _core.ConfigError(f"the DataArray has no CRS (.rio.write_crs) ({what})")
    return np.asarray(da.values), transform, crs, nodata


def _array_from_gdal(ds):
    band = ds.GetRasterBand(1)
    srs = ds.GetSpatialRef()
    return band.ReadAsArray(), ds.GetGeoTransform(), srs.ExportToWkt() if srs is not None else None, \
        band.GetNoDataValue()


@contextlib.contextmanager
def raster_path(value, transform=None, crs=None, nodata=None, what="dem"):
    """A path the core reads for a raster given as a path (str, os.PathLike), an open GDAL dataset, a NumPy
    array with `transform` and `crs`, or a rioxarray DataArray. In-memory rasters live under GDAL's /vsimem/
    (nothing is written to disk) for the duration of the `with` block; the core's warnings and error messages
    meanwhile name what the user gave ("the `dem` array") instead of that path. None stays None."""
    if value is None or isinstance(value, (str, os.PathLike)):
        if transform is not None or crs is not None:
            raise _core.ConfigError(f"transform and crs go with a raster given as an array ({what})")
        yield None if value is None else os.fspath(value)
        return
    if _is_dataarray(value):
        if transform is not None or crs is not None:
            raise _core.ConfigError(f"a DataArray carries its own transform and crs ({what})")
        values, transform, crs, da_nodata = _array_from_dataarray(value, what)
        nodata = nodata if nodata is not None else da_nodata
        description = f"the `{what}` DataArray"
    elif _is_gdal_dataset(value):
        values, transform, crs, ds_nodata = _array_from_gdal(value)
        description = f"the `{what}` GDAL dataset"
        nodata = nodata if nodata is not None else ds_nodata
        if crs is None:
            raise _core.ConfigError(f"the GDAL dataset has no CRS ({what})")
    elif isinstance(value, np.ndarray) or hasattr(value, "__array__"):
        values = value
        description = f"the `{what}` array"
        if transform is None or crs is None:
            raise _core.ConfigError(f"a DEM given as an array needs transform= and crs= ({what})")
    else:
        raise _core.ConfigError(f"must be a path, a GDAL dataset, a NumPy array or an xarray DataArray, got "
                                f"{type(value).__name__} ({what})")
    # Heights as native float32, C order (any layout, byte order, integer or float16/64 type converts; bool,
    # complex and text are refused rather than turned into numbers).
    values = real_array(values, what, content="real heights", shape_text="a non-empty 2-D array of heights",
                        complex_hint=": heights are real")
    nodata = _nodata_value(nodata, "nodata")
    gt = _transform_coefficients(transform, "transform")
    crs_text = _crs_text(crs, "crs")
    from osgeo import gdal, osr
    srs = osr.SpatialReference()
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    try:
        failed = srs.SetFromUserInput(crs_text) != 0
    except RuntimeError:
        failed = True
    if failed:
        raise _core.ConfigError(f"not a CRS: {crs_text[:80]!r} (crs)")
    path = f"/vsimem/gissar_{uuid.uuid4().hex}.tif"
    ds = gdal.GetDriverByName("GTiff").Create(path, values.shape[1], values.shape[0], 1, gdal.GDT_Float32)
    _core._name_path(path, description)
    try:
        ds.SetGeoTransform(gt)
        ds.SetSpatialRef(srs)
        band = ds.GetRasterBand(1)
        if nodata is not None and np.isfinite(nodata):
            band.SetNoDataValue(float(nodata))
        band.WriteArray(values)
        ds = None
        yield path
    finally:
        ds = None
        gdal.Unlink(path)
        _core._name_path(path, "")


def image_array(value, what):
    """A 2-D image as contiguous native float32 from an array, a DataArray (its 'total' band when it has bands),
    a path or a GDAL dataset (band 1); checked by image_values (`what` names the argument in errors)."""
    if _is_dataarray(value):
        if "band" in value.dims:
            value = value.sel(band="total") if "total" in list(value["band"].values) else value.isel(band=0)
        value = value.values
    elif isinstance(value, (str, os.PathLike)):
        from osgeo import gdal
        path = os.fspath(value)
        if not os.path.exists(path) and not path.startswith("/vsi"):
            raise _core.MissingFileError(f"image file does not exist ({what}: {path})")
        ds = gdal.Open(path)
        value = ds.GetRasterBand(1).ReadAsArray()
    elif _is_gdal_dataset(value):
        value = value.GetRasterBand(1).ReadAsArray()
    return image_values(value, what)


# ---------------------------------------------------------------- progress and Ctrl-C

def _tqdm_progress():
    from tqdm.auto import tqdm
    bars = {}

    def report(stage, done, total):
        bar = bars.get(stage)
        if bar is None:
            for other in bars.values():
                other.close()
            bar = bars[stage] = tqdm(total=total, desc=stage, unit="", leave=False)
        bar.total = total
        bar.update(done - bar.n)
        if done >= total:
            bar.close()
        return None

    report.close = lambda: [b.close() for b in bars.values()]
    return report


def _user_stacklevel():
    """The warnings.warn stacklevel of the first caller outside the gissar package."""
    package = os.path.dirname(os.path.abspath(__file__))
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.dirname(os.path.abspath(frame.f_code.co_filename)) == package:
        frame, level = frame.f_back, level + 1
    return level


def run(function, args, kwargs, progress):
    """Calls the core `function` on a worker thread with a progress hook, so that the calling (main) thread
    stays responsive: Ctrl-C (KeyboardInterrupt) cancels the run through the hook and is re-raised once the
    core has stopped. `progress`: None, a callable(stage, done, total) (return False to stop: gissar.Cancelled)
    or True (a tqdm bar)."""
    if progress is True:
        user = _tqdm_progress()
    elif progress is None or progress is False:
        user = None
    elif callable(progress):
        user = progress
    else:
        raise _core.ConfigError("progress must be a callable(stage, done, total), True (a tqdm bar) or None "
                                "(progress)")
    interrupted = threading.Event()
    outcome = {}

    def hook(stage, done, total):
        if interrupted.is_set() or "callback_error" in outcome:
            return False
        if user is not None:
            try:
                answer = user(stage, done, total)
            except BaseException as e:  # noqa: B902 (re-raised as itself by the calling thread)
                # The callback's own exception stops the run (as a False would) and is what the call raises,
                # not gissar.Cancelled: the core only sees the stop request.
                outcome["callback_error"] = e
                return False
            if answer is not None and not answer:
                return False
        return True

    # Completion is our own event: a Thread.join interrupted by KeyboardInterrupt can leave the thread looking
    # stopped while it still runs (CPython gh-90882).
    finished = threading.Event()

    # The core's warnings are collected in this list (the core appends to a progress hook's
    # `_gissar_warnings`) and issued from the calling thread (below), so that they point at the user's line
    # and -W error / filters apply there. Not warnings.catch_warnings: it swaps process-wide state, which
    # concurrent calls from several threads would leave swapped (later warnings lost).
    hook._gissar_warnings = []

    def work():
        try:
            outcome["value"] = function(*args, progress=hook, **kwargs)
        except BaseException as e:  # noqa: B902 (handed to the calling thread)
            outcome["error"] = e
        finally:
            finished.set()

    worker = threading.Thread(target=work, name="gissar", daemon=True)
    worker.start()
    try:
        try:
            while not finished.wait(0.05):
                pass
        except KeyboardInterrupt:
            interrupted.set()  # the core stops at its next progress report
            while not finished.is_set():
                try:
                    finished.wait(0.05)
                except KeyboardInterrupt:
                    pass  # already stopping
            raise
    finally:
        if hasattr(user, "close"):
            user.close()
    for text in hook._gissar_warnings:
        warnings.warn(text, _core.GissarWarning, stacklevel=_user_stacklevel())
    if "callback_error" in outcome:
        # The progress callback raised: that exception, whatever the core made of the stop (Cancelled, or a
        # result when it had already finished its last report).
        outcome.pop("error", None)
        error = outcome.pop("callback_error")
        try:
            raise error
        finally:
            error = None
    if "error" in outcome:
        error = outcome.pop("error")
        try:
            raise error
        finally:
            error = None
    return outcome["value"]


# ---------------------------------------------------------------- xarray out

def _provenance(options):
    return {"gissar_version": _core.version().split()[1], "options": json.dumps(options, sort_keys=True)}


def _mask_coord(mask, dims):
    import xarray as xr
    return xr.Variable(dims, mask, attrs={
        "long_name": "layover/shadow mask", "flag_values": np.array(MASK_FLAG_VALUES, np.uint8),
        "flag_meanings": MASK_FLAG_MEANINGS})


def _bands(raw):
    if "channel_bands" in raw:  # several polarisation channels: the GeoTIFF's bands
        return raw["channel_bands"]
    return np.concatenate([raw["image"][None], raw["bounces"]], axis=0)


def _band_coord(raw):
    if "band_names" in raw:
        return ("band", list(raw["band_names"]),
                {"long_name": "polarisation channel (totals, then each channel's bounce counts)"})
    return _bounce_band_coord(raw)


def _bounce_band_coord(raw):
    """total, then the bounce counts the run holds (the GeoTIFF's bands: up to the highest count that can return)."""
    return ("band", list(BAND_NAMES[:1 + raw["bounces"].shape[0]]), {"long_name": "contribution (bounce count)"})


def _intensity_attrs(options):
    radiometry = options.get("radiometry", "sigma0")
    scale = "dB" if options.get("db") else "linear"
    return {"long_name": f"SAR intensity ({radiometry}, {scale})", "units": "dB" if scale == "dB" else "1",
            "radiometry": radiometry, "scale": scale}


def simulated_dataarray(raw):
    """The core's simulate result (a dict) as an xarray.DataArray (band, along_track_m, slant_range_m)."""
    import xarray as xr
    g = raw["geometry"]
    rows, cols = raw["image"].shape
    along_track_m = (np.arange(rows) - g.v0) * g.azimuth_spacing_m
    slant_range_m = g.slant_range_m + (np.arange(cols) - g.u0) * g.range_spacing_m
    dims = ("along_track_m", "slant_range_m")
    coords = {
        "band": _band_coord(raw),
        "along_track_m": ("along_track_m", along_track_m,
                          {"units": "m", "long_name": "along-track distance from the scene centre's row"}),
        "slant_range_m": ("slant_range_m", slant_range_m,
                          {"units": "m", "long_name": "slant range"
                           + (" (affine mode: linear in the column)" if g.mode == "affine" else "")}),
        "mask": _mask_coord(raw["mask"], dims),
        "layover": (dims, raw["layover"], {"long_name": "layover"}),
        "shadow": (dims, raw["shadow"], {"long_name": "shadow"}),
    }
    attrs = _intensity_attrs(raw["options"])
    attrs.update(_provenance(raw["options"]))
    attrs.update(raw["metadata"])
    attrs["centre_enu_m"] = list(raw["centre_enu_m"])
    if "outputs" in raw:
        attrs["outputs"] = list(raw["outputs"])
    return xr.DataArray(_bands(raw), dims=("band",) + dims, coords=coords, attrs=attrs, name="intensity")


def product_dataarray(raw):
    """The core's simulate_product result as an xarray.DataArray (band, zero_doppler_time_s, slant_range_m)."""
    import xarray as xr
    dims = ("zero_doppler_time_s", "slant_range_m")
    coords = {
        "band": _bounce_band_coord(raw),
        "zero_doppler_time_s": ("zero_doppler_time_s", np.asarray(raw["zero_doppler_time_s"]),
                                {"units": "s", "long_name": "zero-Doppler azimuth time of the product's lines"}),
        "slant_range_m": ("slant_range_m", np.asarray(raw["slant_range_m"]),
                          {"units": "m", "long_name": "slant range of the product's bins"}),
        "mask": _mask_coord(raw["mask"], dims),
        "lon_deg": (dims, raw["lon_deg"], {"units": "degrees_east", "long_name": "ground point longitude (WGS84)"}),
        "lat_deg": (dims, raw["lat_deg"], {"units": "degrees_north", "long_name": "ground point latitude (WGS84)"}),
        "height_m": (dims, raw["height_m"], {"units": "m", "long_name": "ground point ellipsoidal height"}),
    }
    if "real_amplitude" in raw:
        coords["real_amplitude"] = (dims, raw["real_amplitude"], {"units": "1", "long_name": "|SLC| of the product"})
    attrs = _intensity_attrs(raw["options"])
    attrs.update(_provenance(raw["options"]))
    attrs.update({"wavelength_m": raw["wavelength_m"], "look_side": raw["look_side"]})
    return xr.DataArray(_bands(raw), dims=("band",) + dims, coords=coords, attrs=attrs, name="intensity")


def geometry_from_attrs(attrs, shape):
    """The SarGeometry of a simulated DataArray, from its GISSAR_* attributes (17 significant digits: exact)."""
    try:
        centre = [float(v) for v in attrs["GISSAR_SCENE_CENTRE_ENU"].split(",")]
        return _core.SarGeometry(
            heading_deg=float(attrs["GISSAR_HEADING_DEG"]), depression_deg=float(attrs["GISSAR_DEPRESSION_DEG"]),
            range_spacing_m=float(attrs["GISSAR_RANGE_SPACING_M"]),
            azimuth_spacing_m=float(attrs["GISSAR_AZIMUTH_SPACING_M"]), look_side=attrs["GISSAR_LOOK_SIDE"],
            mode=attrs["GISSAR_PROJECTION_MODE"], slant_range_m=float(attrs["GISSAR_SLANT_RANGE_M"]),
            scene_centre_enu_m=centre, u0=float(attrs["GISSAR_U0"]), v0=float(attrs["GISSAR_V0"]),
            width=int(shape[1]), height=int(shape[0]))
    except KeyError as e:
        raise AttributeError(f"no SAR geometry in the attributes (missing {e.args[0]})") from None


def register_accessor():
    """`da.gissar`: .geometry (SarGeometry), .image (the total band, 2-D), .options (dict)."""
    import xarray as xr

    @xr.register_dataarray_accessor("gissar")
    class GissarAccessor:
        def __init__(self, da):
            self._da = da

        @property
        def image(self):
            da = self._da
            return da.sel(band="total", drop=True) if "band" in da.dims else da

        @property
        def geometry(self):
            shape = self.image.shape
            return geometry_from_attrs(self._da.attrs, shape)

        @property
        def options(self):
            return json.loads(self._da.attrs["options"])

    return GissarAccessor


def map_dataarray(path, outputs):
    """A geocoded GeoTIFF (pipeline/geocode.h) as an xarray.DataArray (band, y, x) with .rio.crs: the image
    bands by name; local_incidence and layover_shadow as 2-D coordinates."""
    import rioxarray
    with rioxarray.open_rasterio(path, mask_and_scale=False) as src:
        da = src.load()
    names = da.attrs.pop("long_name", None)
    names = [names] if isinstance(names, str) else list(names)
    da = da.assign_coords(band=names)
    incidence = da.sel(band="local_incidence", drop=True).values
    codes = da.sel(band="layover_shadow", drop=True).values
    image = da.sel(band=[n for n in names if n not in ("local_incidence", "layover_shadow")])
    spatial = ("y", "x")
    image = image.assign_coords(
        local_incidence_deg=(spatial, incidence, {"units": "degrees", "long_name": "local incidence angle"}),
        layover_shadow=(spatial, codes, {"long_name": "layover/shadow mask", "flag_values": np.array([0, 1, 2, 3]),
                                         "flag_meanings": "none layover shadow layover_and_shadow"}))
    db = "(dB)" in str(image.attrs.get("GISSAR_UNITS", ""))
    image.attrs.update({"units": "dB" if db else "1", "long_name": "SAR intensity (map geometry)",
                        "outputs": list(outputs),
                        "gissar_version": _core.version().split()[1]})
    image.name = "intensity"
    return image


# ---------------------------------------------------------------- products in (gissar.open_product)

def _product_array_class():
    """ProductArray, defined on first use so that importing gissar does not import xarray's backends."""
    global _ProductArray
    if _ProductArray is not None:
        return _ProductArray
    # Created here, not at import; pickle finds it as gissar._adapt.ProductArray (the module's __getattr__).
    from xarray.backends import BackendArray
    from xarray.core import indexing

    class ProductArray(BackendArray):
        """A product's image, read window by window through gissar._core._OpenedProduct when indexed (xarray's
        lazy backend protocol, outer indexing: integers, slices, integer arrays). Pickles by its arguments: the
        product is opened again where it is unpickled."""

        def __init__(self, arguments):
            self._arguments = dict(arguments)
            self._opened = _core._OpenedProduct(**self._arguments)
            info = self._opened.info()
            self.shape = (int(info["rows"]), int(info["cols"]))
            self.dtype = np.dtype(info["dtype"])

        def __getstate__(self):
            return self._arguments

        def __setstate__(self, arguments):
            self.__init__(arguments)

        def __getitem__(self, key):
            # Negative-step slices are turned round here: some xarray versions (2023.01, Debian 12) decompose
            # them one element off (xarray.core.indexing._decompose_slice).
            post = None
            if isinstance(key, (indexing.BasicIndexer, indexing.OuterIndexer)) and any(
                    isinstance(k, slice) and (k.step or 1) < 0 for k in key.tuple):
                fixed, post = [], []
                for k, size in zip(key.tuple, self.shape):
                    if isinstance(k, slice) and (k.step or 1) < 0:
                        idx = range(*k.indices(size))
                        fixed.append(slice(idx[-1], idx[0] + 1, -idx.step) if len(idx) else slice(0, 0))
                        post.append(slice(None, None, -1))
                    else:
                        fixed.append(k)
                        if not isinstance(k, (int, np.integer)):
                            post.append(slice(None))
                key = type(key)(tuple(fixed))
            out = indexing.explicit_indexing_adapter(key, self.shape, indexing.IndexingSupport.OUTER, self._read)
            return out if post is None else out[tuple(post)]

        def _read(self, key):
            # Outer indexing (per axis: an integer, a slice or an array of integers). The columns are read as
            # one span; the lines as one block when they are dense, else one read per line selected (every
            # 1000th line of a GRD reads 17 lines, not the 16 000 between them).
            sels, keep = [], []
            for k, size in zip(key, self.shape):
                if isinstance(k, slice):
                    sels.append(np.arange(size)[k])
                    keep.append(True)
                elif isinstance(k, (np.ndarray, list, tuple)):
                    a = np.asarray(k, np.int64)
                    sels.append(np.where(a < 0, a + size, a))
                    keep.append(True)
                else:
                    i = int(k)
                    sels.append(np.array([i + size if i < 0 else i]))
                    keep.append(False)
            rows, cols = sels
            if rows.size == 0 or cols.size == 0:
                out = np.empty((rows.size, cols.size), self.dtype)
            else:
                r0, r1 = int(rows.min()), int(rows.max()) + 1
                c0, c1 = int(cols.min()), int(cols.max()) + 1
                col_pick = _as_slice(cols - c0)
                if r1 - r0 <= 2 * rows.size:  # dense: one block
                    block = self._opened.read(r0, r1 - r0, c0, c1 - c0)
                    row_pick = _as_slice(rows - r0)
                    out = block[row_pick][:, col_pick]
                else:
                    lines, inverse = np.unique(rows, return_inverse=True)
                    block = np.stack([self._opened.read(int(r), 1, c0, c1 - c0)[0] for r in lines])
                    out = block[inverse][:, col_pick]
            return out[tuple(slice(None) if kept else 0 for kept in keep)]

        def __repr__(self):
            return f"ProductArray({self._arguments['path']!r}, shape={self.shape}, dtype={self.dtype})"

    ProductArray.__module__ = __name__
    ProductArray.__qualname__ = "ProductArray"
    _ProductArray = ProductArray
    return ProductArray


_ProductArray = None


def _as_slice(index):
    """`index` (sorted or not) as a slice when it is a run of consecutive integers, else itself."""
    if index.size and index[0] >= 0 and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return slice(int(index[0]), int(index[0]) + index.size)
    return index


def __getattr__(name):
    if name == "ProductArray":
        return _product_array_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def product_dataset(arguments):
    """gissar.open_product's Dataset: the image as a lazy data variable, its coordinates and attributes."""
    import xarray as xr
    from xarray.core import indexing
    array = _product_array_class()(arguments)
    info = array._opened.info()
    dims = tuple(info["dims"])
    row_dim, col_dim = dims
    coords = {}
    time = np.asarray(info["azimuth_time_ns"], np.int64).view("datetime64[ns]")
    coords["azimuth_time"] = (row_dim, time, {"long_name": "zero-Doppler azimuth time (UTC)"})
    if "line" in info:
        coords["line"] = (row_dim, np.asarray(info["line"]),
                          {"long_name": "measurement line (the annotations' line numbering, 0-based)"})
        coords["pixel"] = (col_dim, np.asarray(info["pixel"]),
                           {"long_name": "measurement sample (the annotations' pixel numbering, 0-based)"})
    if "slant_range_m" in info:
        coords["slant_range"] = (col_dim, np.asarray(info["slant_range_m"]),
                                 {"units": "m", "long_name": "slant range (one-way)"})
    if "ground_range_m" in info:
        coords["ground_range"] = (col_dim, np.asarray(info["ground_range_m"]),
                                  {"units": "m", "long_name": "ground range from the first pixel"})
    attrs = dict(info["attrs"])
    attrs["source_files"] = list(attrs["source_files"])
    attrs.update(_provenance({k: v for k, v in arguments.items() if v is not None}))
    var_attrs = {"units": "1", "long_name": info["long_name"], "radiometry": attrs["radiometry"]}
    variable = xr.Variable(dims, indexing.LazilyIndexedArray(array), attrs=var_attrs)
    return xr.Dataset({info["name"]: variable}, coords=coords, attrs=attrs)
