"""gissar: simulate SAR images of real terrain from GIS data, and estimate an aircraft's pose from SAR
images with an affine SAR camera model.

The compiled core is ``gissar._core`` (C++, pybind11); this package gives it Python signatures, the
error classes users catch (``ValueError``/``OSError``/``RuntimeError`` subclasses) and the version.
Keyword names are the request field names of docs/conventions.md (``heading_deg``, ``range_spacing_m``):
the same names as the options-file keys and the sidecar keys of the command line.
"""
import inspect as _inspect
import json as _json
import os as _os

from . import _core
from ._core import *  # noqa: F401,F403  (the compiled API)
from ._core import (Cancelled, ConfigError, Error, GissarWarning, InputError, IoError,  # noqa: F401
                    MissingFileError, SarGeometry, Scene)
from . import _adapt
from ._adapt import ArrayTypeError  # noqa: F401

#: The library version, as ``gissar --version`` prints it (``gissar 0.1.0 (describe)``: the middle word).
__version__ = _core.version().split()[1]

_UNITS = {"_deg": "degrees", "_m": "metres", "_db": "dB", "_bytes": "bytes", "_px": "pixels", "_s": "seconds"}


def _unit_of(name):
    for suffix, unit in _UNITS.items():
        if name.endswith(suffix):
            return unit
    return None


def _with_request_signature(function, defaults, leading, trailing, summary, required=(), help=None):
    """Gives `function` (a **kwargs wrapper of the core) the signature of its request: every field a
    keyword-only parameter with its default (`required` ones first, without a default: the core raises
    ConfigError "is required (NAME)" without them, as the command line does), units and the request table's
    one-line `help` ({name: text}) in the docstring."""
    params = [_inspect.Parameter(name, _inspect.Parameter.POSITIONAL_OR_KEYWORD, default=default)
              for name, default in leading]
    params += [_inspect.Parameter(name, _inspect.Parameter.KEYWORD_ONLY) for name in required]
    params += [_inspect.Parameter(name, _inspect.Parameter.KEYWORD_ONLY, default=value)
               for name, value in defaults.items()
               if name not in dict(leading) and name not in required and name != "out_prefix"]
    params += [_inspect.Parameter(name, _inspect.Parameter.KEYWORD_ONLY, default=default)
               for name, default in trailing]
    function.__signature__ = _inspect.Signature(params)
    lines = [summary, "", "Parameters (units from the name's suffix):"]
    for p in params:
        unit = _unit_of(p.name)
        given = "required" if p.default is _inspect.Parameter.empty else f"default {p.default!r}"
        text = (help or {}).get(p.name)
        lines.append(f"    {p.name}: {given}" + (f" ({unit})" if unit else "") + (f". {text}" if text else ""))
    function.__doc__ = "\n".join(lines)
    return function


def _scene_path(scene):
    return scene.path if isinstance(scene, _core.Scene) else scene


def _simulate_raw(dem=None, *, transform=None, crs=None, nodata=None, progress=None, **kwargs):
    if "scene" in kwargs:
        kwargs["scene"] = _scene_path(kwargs["scene"])
    with _adapt.raster_path(dem, transform, crs, nodata, "dem") as path:
        if path is not None:
            kwargs["dem"] = path
        return _adapt.run(_core.simulate, (), kwargs, progress)


def simulate(dem=None, **kwargs):
    if kwargs.get("out_prefix") is None:
        kwargs.pop("out_prefix", None)
    else:
        kwargs["out_prefix"] = _os.fspath(kwargs["out_prefix"])
    return _adapt.simulated_dataarray(_simulate_raw(dem, **kwargs))


def _simulate_product_raw(product=None, *, dem=None, transform=None, crs=None, nodata=None, progress=None, **kwargs):
    if "scene" in kwargs:
        kwargs["scene"] = _scene_path(kwargs["scene"])
    with _adapt.raster_path(dem, transform, crs, nodata, "dem") as path:
        if path is not None:
            kwargs["dem"] = path
        return _adapt.run(_core.simulate_product, ("" if product is None else _os.fspath(product),), kwargs,
                          progress)


def simulate_product(product=None, **kwargs):
    """Simulate a real product's radar grid (NISAR RSLC HDF5, e.g. the UAVSAR chips), or any sensor's track with
    orbit= (state vectors: CSV, JSON or an ESA .EOF file) and radar_grid= (JSON) instead of a product: keywords as for
    simulate (dem or scene, fill_nodata, dem_oversample, vertical_datum, rays_per_cell, bounces, seed, ...; no
    heading/depression/spacings: the product fixes them); dem as for simulate (path, GDAL dataset, array with
    transform= and crs=, rioxarray DataArray); progress as for simulate.

    Returns an xarray.DataArray 'intensity' (band, zero_doppler_time_s, slant_range_m): bands total, single,
    double, triple, four_or_more (the request's radiometry, sigma0 by default, each pixel at its own ellipsoid
    incidence; units '1'), coordinates the product's line times (s) and bin slant
    ranges (m); 2-D coordinates mask (flag_values/flag_meanings), lon_deg, lat_deg, height_m (per-pixel ground
    point, NaN where none) and real_amplitude (|SLC|); attrs wavelength_m, look_side, options (JSON),
    gissar_version. Same values as `gissar simulate --product` (gissar.raw.simulate_product: the dict)."""
    return _adapt.product_dataarray(_simulate_product_raw(product, **kwargs))


simulate_product.__module__ = "gissar"

_SIMULATE_SUMMARY = """Simulate a SAR image of a DEM (path, GDAL dataset, NumPy array with transform= and crs=, or a
rioxarray DataArray; nothing is written to disk) or a scene (scene=path or gissar.Scene). heading_deg and
depression_deg are required, as `gissar simulate`'s --heading and --depression (gissar.ConfigError "is required
(heading_deg)" without them).

Returns an xarray.DataArray 'intensity' with dims (band, along_track_m, slant_range_m): bands total, single,
double, triple, four_or_more, up to the highest bounce count that can return (bounces, reflectors) as the
GeoTIFF (linear intensity in the request's radiometry, sigma0 by default; units '1'),
along_track_m = metres along track from the scene centre's row, slant_range_m = slant range (m) of each
column; 2-D coordinates mask (uint8, flag_values 0 1 2 3 255 = none layover shadow layover_and_shadow
outside_footprint; NaN outside), layover, shadow (bool); attrs: units, radiometry, options (JSON), gissar_version
and the GISSAR_* geometry metadata of the GeoTIFF. `da.gissar.geometry` is its SarGeometry,
`da.gissar.image` the total band. Values identical to `gissar simulate`'s GeoTIFF bands.
transform: GDAL's six coefficients or affine.Affine; crs: EPSG code, WKT/'EPSG:n' or pyproj CRS; nodata: the
array's no-data value. progress: callable(stage, done, total) (return False to stop: gissar.Cancelled), True
for a tqdm bar, or None. Ctrl-C stops the run (KeyboardInterrupt). out_prefix: also write the command line's
files (PREFIX.tif, _mask.tif, .png, _quicklook.png, .json, _stac.json; attrs['outputs'] lists them), e.g. for
gissar.geocode; nothing is written without it. gissar.raw.simulate returns the dict."""

_with_request_signature(
    simulate, _core.simulate_request_defaults(),
    leading=[("dem", None)],
    trailing=[("transform", None), ("crs", None), ("nodata", None), ("progress", None), ("out_prefix", None)],
    summary=_SIMULATE_SUMMARY, required=("heading_deg", "depression_deg"), help=_core.simulate_request_help())
simulate.__module__ = "gissar"


def geocode(image, out_prefix, *, dem=None, vertical_datum="", crs=None, pixel_size_m=0.0, resampling="bilinear"):
    """`gissar geocode` (docs/georeferencing.md): a simulation to map geometry by exact back-geocoding.

    image: the PREFIX.tif a simulation wrote (str/Path), or a DataArray returned by simulate(...,
    out_prefix=...). out_prefix: where the map product goes (out_prefix.tif, .json, _stac.json). dem: optional
    DEM replacing the simulation's terrain (path, GDAL dataset or rioxarray DataArray). crs: the output CRS (EPSG
    code, 'EPSG:n', WKT or pyproj CRS; projected, metres; None = the UTM zone of the scene centre);
    pixel_size_m: output pixel size (0 = the image's larger spacing); resampling: 'bilinear' or 'average'.

    Returns an xarray.DataArray 'intensity' (band, y, x): bands as the image's, x/y in metres of the CRS,
    .rio.crs set (rioxarray), 2-D coordinates local_incidence_deg and layover_shadow (flag_values 0 1 2 3:
    none layover shadow layover_and_shadow; NaN where not imaged); attrs['outputs'] the written files.
    `da.rio.to_raster(path)` writes it as a GeoTIFF."""
    if _adapt._is_dataarray(image):
        try:
            image = _json.loads(image.attrs["options"])["out_prefix"] + ".tif"
        except KeyError:
            raise ConfigError("a DataArray image must come from simulate(..., out_prefix=...) (image)") from None
        if image == "(python).tif":
            raise ConfigError("the simulation wrote no files: give simulate(..., out_prefix=...) (image)")
    crs_text = "" if crs is None else _adapt._crs_text(crs, "crs")
    if isinstance(dem, _np_ndarray()):
        raise ConfigError("geocode takes the DEM as a path, a GDAL dataset or a rioxarray DataArray (a bare array "
                          "has no georeferencing here: use rioxarray's .rio.write_transform/.rio.write_crs) (dem)")
    with _adapt.raster_path(dem, None, None, None, "dem") as dem_path:
        r = _core.geocode(dict(image=_os.fspath(image), out_prefix=_os.fspath(out_prefix), dem=dem_path or "",
                               vertical_datum=vertical_datum, crs=crs_text, pixel_size_m=pixel_size_m,
                               resampling=resampling))
    return _adapt.map_dataarray(_os.fspath(out_prefix) + ".tif", r["outputs"])


def open_product(path, *, swath=None, burst=None, polarization=None, radiometry=None, noise_removal=False,
                 frequency=None):
    """Open a real product's image as an xarray.Dataset (docs/sentinel1.md, "Images and calibration"), read
    lazily: pixels are read (and calibrated) only for the part you index or load.

    path: a Sentinel-1 SAFE (the NAME.SAFE directory, its manifest.safe, or a .zip holding it) or a NISAR-format
    RSLC (HDF5). swath ('IW1', 'S3', 'IW' for a GRD; default the first one present), burst (1-based, IW/EW SLC;
    default the whole swath), polarization ('VV', ...; default the first one present), frequency ('A' or 'B',
    NISAR only). radiometry: None for the stored digital numbers, or 'sigma0', 'beta0', 'gamma0' for linear
    calibrated power |DN|^2 / A^2 (A the product's LUT, interpolated bilinearly in line and pixel as ESA
    specifies; NISAR: beta0 only, = LUT x |DN|^2, and only when the product states its beta0 LUT).
    noise_removal: subtract the thermal noise power (range LUT x azimuth LUT) before dividing (needs a
    radiometry; negative results are NaN).

    Returns a Dataset with one data variable: 'slc' (complex64 DN of an SLC) or 'amplitude' (float32 DN of a GRD)
    when radiometry is None, else the radiometry's name (float32 linear power); units '1', NaN no-data (DN 0,
    samples outside a burst's valid window, negative after noise removal). Dims (azimuth_time, slant_range),
    (azimuth_time, ground_range) for a GRD, or (line, pixel) for an IW/EW SLC swath of overlapping bursts;
    coordinates azimuth_time (datetime64[ns] UTC, zero-Doppler), slant_range (m, one-way) or ground_range (m from
    the first pixel), line and pixel (the measurement's numbering, Sentinel-1). Attributes: sensor, mission,
    product, product_type, mode, swath, burst, polarization, orbit_pass, wavelength_m, look_side, radiometry,
    noise_removal, calibration, nodata, azimuth_time_interval_s, azimuth_spacing_m, range_spacing_m (slant) or
    ground_range_spacing_m, source_files, gissar_version and options (this call's arguments, JSON).

    Errors: ValueError (gissar.ConfigError) for a bad argument (unknown swath, burst, polarization or radiometry
    string, a keyword that does not apply to the product), gissar.InputError (ValueError) for an unreadable
    product, FileNotFoundError/OSError (gissar.MissingFileError) for a product or a file of it that does not
    exist (a measurement or calibration file the manifest lists but the SAFE lacks)."""
    for name, value in (("swath", swath), ("polarization", polarization), ("radiometry", radiometry),
                        ("frequency", frequency)):
        if value is not None and not isinstance(value, str):
            raise ConfigError(f"must be a string or None, got {type(value).__name__} ({name})")
    if burst is not None and (isinstance(burst, bool) or not isinstance(burst, (int, _np_integer()))):
        raise ConfigError(f"must be a burst number (1, 2, ...) or None, got {type(burst).__name__} (burst)")
    if not isinstance(noise_removal, bool):
        raise ConfigError(f"must be True or False, got {type(noise_removal).__name__} (noise_removal)")
    arguments = {"path": _os.fspath(path), "swath": swath, "burst": None if burst is None else int(burst),
                 "polarization": polarization, "radiometry": radiometry, "noise_removal": noise_removal,
                 "frequency": frequency}
    return _adapt.product_dataset(arguments)


def _np_integer():
    import numpy
    return numpy.integer


def _np_ndarray():
    import numpy
    return numpy.ndarray


# ---------------------------------------------------------------- Scene

_core_scene_build = _core.Scene.build


def _scene_build(dem, out_prefix, vectors=(), osm="", config="", fill_nodata=False, window=None, export_obj=False,
                 vertical_datum="", *, transform=None, crs=None, nodata=None, progress=None):
    with _adapt.raster_path(dem, transform, crs, nodata, "dem") as path:
        options = dict(dem=path, out_prefix=_os.fspath(out_prefix), vectors=[_os.fspath(v) for v in vectors],
                       osm=_os.fspath(osm), config=_os.fspath(config), fill_nodata=fill_nodata, window=window,
                       export_obj=export_obj, vertical_datum=vertical_datum)
        return _adapt.run(_core_scene_build, (options,), {}, progress)


_scene_build.__doc__ = (_core_scene_build.__doc__ or "").split("\n\n")[-1].strip() + (
    " dem: a path, GDAL dataset, NumPy array with transform=/crs= (nodata=) or a rioxarray DataArray. progress: "
    "None, a callable(stage, done, total) (return False to stop) or True (a tqdm bar); Ctrl-C stops the build "
    "at its next step.")


def _scene_simulate(self, **kwargs):
    """gissar.simulate(scene=self, ...): same keywords and result (an xarray.DataArray)."""
    if "scene" in kwargs or "dem" in kwargs:
        raise ConfigError("the scene is given (Scene.simulate)")
    return simulate(scene=self.path, **kwargs)


_scene_simulate.__signature__ = _inspect.Signature(
    [_inspect.Parameter("self", _inspect.Parameter.POSITIONAL_ONLY)]
    + [p for name, p in _inspect.signature(simulate).parameters.items()
       if name not in ("dem", "scene", "transform", "crs", "nodata")])
Scene.build = staticmethod(_scene_build)
Scene.simulate = _scene_simulate


def build_scene(dem, out_prefix, vectors=(), osm="", config="", fill_nodata=False, vertical_datum="", *,
                transform=None, crs=None, nodata=None, progress=None):
    """`gissar scene build`: writes PREFIX.gscene/.ply/_classes.png/.json, returns the summary (dict). dem as
    for Scene.build."""
    return _scene_build(dem, out_prefix, vectors, osm, config, fill_nodata, None, False, vertical_datum,
                        transform=transform, crs=crs, nodata=nodata, progress=progress).summary


def sequence(out_prefix, heading_from_deg, heading_to_deg, frames=7, frame_delay_cs=50, *, dem=None,
             transform=None, crs=None, nodata=None, progress=None, **kwargs):
    """`gissar sequence`: frames at evenly spaced headings (degrees) around the scene centre, one dB stretch:
    PREFIX_fNN.tif/.png, PREFIX_contact.png, PREFIX.gif, PREFIX.json. depression_deg is required (as `gissar
    sequence --depression`); other keywords as gissar.simulate (dem in any of its forms); progress and Ctrl-C
    as gissar.simulate (Ctrl-C stops before the next frame). Returns the written paths."""
    if "scene" in kwargs:
        kwargs["scene"] = _scene_path(kwargs["scene"])
    with _adapt.raster_path(dem, transform, crs, nodata, "dem") as path:
        if path is not None:
            kwargs["dem"] = path
        return _adapt.run(_core.sequence, (_os.fspath(out_prefix), heading_from_deg, heading_to_deg, frames,
                                           frame_delay_cs), kwargs, progress)


def _with_required_keywords(function, names):
    """Shows the keywords `names` (checked by the core) as required keyword-only parameters of `function`."""
    params = list(_inspect.signature(function).parameters.values())
    first_keyword = next(i for i, p in enumerate(params) if p.kind in (p.KEYWORD_ONLY, p.VAR_KEYWORD))
    params[first_keyword:first_keyword] = [_inspect.Parameter(n, _inspect.Parameter.KEYWORD_ONLY) for n in names]
    function.__signature__ = _inspect.Signature(params)
    return function


_with_required_keywords(sequence, ["depression_deg"])


# ---------------------------------------------------------------- images in

def _image(function):
    return lambda value, name: _adapt.image_array(value, f"gissar.{function}: {name}")


def _points(function, columns):
    return lambda value, name: _adapt.points_values(value, f"gissar.{function}: {name}", columns)


def _matrix(function, rows, columns, optional=False):
    def convert(value, name):
        if optional and value is None:
            return None
        return _adapt.matrix_values(value, f"gissar.{function}: {name}", rows, columns)
    return convert


def _pictures(function, many=False):
    def convert(value, name):
        what = f"gissar.{function}: {name}"
        if many:
            return [_adapt.uint8_values(v, f"{what}[{i}]") for i, v in enumerate(value)]
        return _adapt.uint8_values(value, what)
    return convert


def _arrays_in(core, parameters, module_doc_extra=" Images: NumPy arrays, xarray DataArrays (their 'total' band), "
                                                  "paths or GDAL datasets (band 1)."):
    """Wraps a core function so that its array arguments (by position or keyword) are checked and converted in
    Python first: `parameters` lists the core's leading parameters in order as (name, converter or None).
    Converters take any image form or array layout and raise gissar.ArrayTypeError/InputError naming the
    parameter (bool, complex, text, a wrong number of dimensions) instead of pybind11's signature listing."""
    positions = {name: (i, convert) for i, (name, convert) in enumerate(parameters) if convert is not None}

    def wrapper(*args, **kwargs):
        args = list(args)
        for name, (i, convert) in positions.items():
            if i < len(args):
                args[i] = convert(args[i], name)
            elif name in kwargs:
                kwargs[name] = convert(kwargs[name], name)
        return core(*args, **kwargs)

    wrapper.__name__ = wrapper.__qualname__ = core.__name__
    wrapper.__doc__ = (core.__doc__ or "") + module_doc_extra
    wrapper.__module__ = "gissar"
    return wrapper


match_images = _arrays_in(_core.match_images, [
    ("reference", _image("match_images")), ("observed", _image("match_images")), ("matcher", None),
    ("patch_px", None), ("step_px", None), ("search_px", None), ("filter_px", None), ("min_score", None),
    ("warp", _matrix("match_images", 2, 3, optional=True))])
register_images = _arrays_in(_core.register_images, [
    ("fixed", _image("register_images")), ("moving", _image("register_images")),
    ("fixed_px", _points("register_images", 2)), ("moving_px", _points("register_images", 2))])
quicklook = _arrays_in(_core.quicklook, [("intensity", _image("quicklook"))])
annotated_quicklook = _arrays_in(_core.annotated_quicklook, [("intensity", _image("annotated_quicklook"))])
composite = _arrays_in(_core.composite, [("green", _image("composite")), ("magenta", _image("composite"))])
epipolar_plot = _arrays_in(_core.epipolar_plot, [
    ("image1", _image("epipolar_plot")), ("image2", _image("epipolar_plot")), ("x1", _points("epipolar_plot", 2)),
    ("x2", _points("epipolar_plot", 2)), ("F", _matrix("epipolar_plot", 3, 3))])
_NO_IMAGES = ""
fmatrix = _arrays_in(_core.fmatrix, [("x1", _points("fmatrix", 2)), ("x2", _points("fmatrix", 2))], _NO_IMAGES)
resect = _arrays_in(_core.resect, [("world_enu_m", _points("resect", 3)), ("pixels", _points("resect", 2))],
                    _NO_IMAGES)
register_points = _arrays_in(_core.register_points, [
    ("fixed_px", _points("register_points", 2)), ("moving_px", _points("register_points", 2))], _NO_IMAGES)
kvd = _arrays_in(_core.kvd, [("F", _matrix("kvd", 3, 3))], _NO_IMAGES)
write_png = _arrays_in(_core.write_png, [("path", None), ("image", _pictures("write_png"))], _NO_IMAGES)
write_gif = _arrays_in(_core.write_gif, [("path", None), ("frames", _pictures("write_gif", many=True))], _NO_IMAGES)
side_by_side = _arrays_in(_core.side_by_side, [("panels", _pictures("side_by_side", many=True))], _NO_IMAGES)

_core_project = SarGeometry.project


def _project(self, points_enu_m):
    return _core_project(self, _adapt.points_values(points_enu_m, "SarGeometry.project: points_enu_m", 3))


_project.__doc__ = _core_project.__doc__
SarGeometry.project = _project


#: The keywords of gissar.locate after its positional arguments (gissar._core.locate's).
_LOCATE_KEYWORDS = ("look_side", "matcher", "search_px", "step_px", "dense_renders", "polish_evaluations", "bounces",
                    "rays_per_cell", "references")


def locate(scene, image, prior, range_spacing_m, azimuth_spacing_m, **kwargs):
    """`gissar locate` (docs/navigation.md): pose fix of one observed SAR image against a scene (gissar.Scene or
    the path of a .gscene). image: NumPy array, DataArray (its total band), path or GDAL dataset. Keywords:
    look_side, matcher, search_px, step_px, dense_renders, polish_evaluations, bounces, rays_per_cell, references (as
    gissar._core.locate). Returns the fix as a dict (see help(gissar._core.locate))."""
    for name in kwargs:
        if name not in _LOCATE_KEYWORDS:
            raise ConfigError(f"{_core.unknown_key_message(name, list(_LOCATE_KEYWORDS))} (gissar.locate)")
    if not isinstance(scene, _core.Scene):
        scene = Scene(_os.fspath(scene))
    return _core.locate(scene, _adapt.image_array(image, "gissar.locate: image"), prior, range_spacing_m, azimuth_spacing_m,
                        **kwargs)


def locate_product(**kwargs):
    """`gissar locate --product` (docs/navigation.md, "Real images"): pose fix of a real zero-Doppler product
    (product=path) or of an image on any sensor's track (orbit=, radar_grid=, image= paths), against dem= or
    scene=, from the annotated track moved by prior_offset_track=(along, cross, up) metres and
    prior_heading_offset_deg. Other keywords: prior_sigma_horizontal_m, prior_sigma_vertical_m,
    prior_sigma_heading_deg, terrain_horizontal_sigma_m (the DEM's own horizontal error, added to the relief
    fix's along/cross variance; default 6 m), looks_range, looks_azimuth, dem_oversample, matcher (ncc, gradient,
    phase, mi), frequency, polarization, vertical_datum, bounces, rays_per_cell, reflectors, sea, out and
    composite_png (files, optional); every key of gissar._core.locate_request_defaults() (the request's table).
    Returns the fix dict (converged, reason, fix.error_against_annotated_track, ...)."""
    paths = ("product", "orbit", "radar_grid", "image", "scene", "dem", "out", "composite_png")
    options = _paths(kwargs, paths)
    if "prior_offset_track" in options and options["prior_offset_track"] is not None:
        options["prior_offset_track"] = [float(v) for v in options["prior_offset_track"]]
    return _core.locate_product(options)


def _fspath(value, name):
    """os.fspath naming the parameter: an array where a file is expected (pta, polsar) is a clear error."""
    try:
        return _os.fspath(value)
    except TypeError:
        raise ArrayTypeError(f"must be a path (str or os.PathLike), got {type(value).__name__}"
                             + (": write the array to a GeoTIFF first (e.g. simulate(..., out_prefix=...))"
                                if hasattr(value, "__array__") else "") + f" ({name})") from None


def _paths(kwargs, keys):
    return {k: (_fspath(v, k) if k in keys and v is not None else v) for k, v in kwargs.items()}


def pta(reflectors, out_prefix, *, product=None, image=None, **kwargs):
    """`gissar pta` (docs/radiometry.md, "Point targets"): each reflector of the CSV `reflectors` measured in a
    real NISAR RSLC (product=path) or a gissar coherent simulation (image=PREFIX_slc.tif): predicted and peak
    pixel, location error (px, m), resolution, PSLR/ISLR, calibrated RCS against physical optics, and for
    quad-pol data the HH/VV ratio and phase and the cross-polarised isolation. Other keywords: the fields of
    gissar._core.pta_request_defaults() (frequency, polarization, upsampling, search_px, ...). Writes
    out_prefix.json and out_prefix_irf.png; returns the JSON's dict ('reflectors', 'converged', 'outputs').
    No reflector found: converged False with the reason (the CLI's exit status 3)."""
    options = {**kwargs, "reflectors": reflectors, "out_prefix": out_prefix}
    if product is not None:
        options["product"] = product
    if image is not None:
        options["image"] = image
    return _core.pta(_paths(options, ("reflectors", "out_prefix", "product", "image")))


def polsar(out_prefix, *, image=None, product=None, **kwargs):
    """`gissar polsar` (docs/radiometry.md, "Polarimetric decomposition"): the multilooked covariance C3 (or
    coherency T3, matrix="coherency") and the Cloude-Pottier entropy / anisotropy / mean alpha of a quad-pol
    SLC (image=PREFIX_slc.tif of `gissar simulate --polarization quad --coherent`) or NISAR product
    (product=path), written as float32 GeoTIFFs with a Pauli quicklook. Other keywords: the fields of
    gissar._core.polsar_request_defaults() (multilook=[R, A] looks, matrix, frequency, ...). Returns PREFIX.json's dict (means of H, A,
    alpha; 'outputs')."""
    options = {**kwargs, "out_prefix": out_prefix}
    if image is not None:
        options["image"] = image
    if product is not None:
        options["product"] = product
    return _core.polsar(_paths(options, ("out_prefix", "product", "image")))


def _evaluate_options(kwargs):
    return _paths(kwargs, ("scene", "dem", "out_prefix", "product"))


def evaluate_trials(**kwargs):
    """Trial records (list of dicts) of trials trial_first .. trial_first + trial_count - 1 of `gissar evaluate`
    (keywords: the fields of gissar._core.evaluate_request_defaults()); trial k depends only on (seed, k)."""
    return _core.evaluate_trials(_evaluate_options(kwargs))


def summarise_trials(records, **kwargs):
    """The summary dict of `gissar evaluate` (success_rate, position_error_m, ...) of trial records, any order."""
    return _core.summarise_trials(_evaluate_options(kwargs), list(records))


def evaluate(**kwargs):
    """`gissar evaluate` in this process: every trial, then the summary dict (with out_prefix, also writes
    PREFIX.json, PREFIX_trials.csv and PREFIX_hist.png). gissar.distributed_evaluate.evaluate spreads the trials."""
    options = _evaluate_options({**kwargs, "trial_first": 0, "trial_count": -1})
    records = _core.evaluate_trials(options)
    if options.get("out_prefix"):
        return _core.write_evaluation(options, records)
    return _core.summarise_trials(options, records)


_adapt.register_accessor()
from . import raw  # noqa: E402  (the dict results)
