"""Misuse from Python (docs/robustness.md, "Misuse from Python"): every public function of the gissar package
that takes an array, given arrays of awkward layouts and types, transforms and CRSs that disagree with the
array, a budget it exceeds, a progress callback that raises, Ctrl-C, other Python threads and concurrent
calls. Each case expects a correct result (asserted equal to the reference) or an exception of the documented
type whose message names the Python parameter. Small synthetic inputs, seeded: about 20 s in all."""
import concurrent.futures
import os
import signal
import threading
import time
import warnings

import numpy as np
import pytest

import gissar

N = 48  # DEM posts per side
GT = (400000.0, 30.0, 0.0, 4700000.0, 0.0, -30.0)  # UTM 31N, 30 m posts, north up
SIM = dict(heading_deg=20.0, depression_deg=40.0, vertical_datum="ellipsoid", seed=1)


def _dem(n=N, seed=1):
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:n, 0:n]
    return (500 + 80 * np.sin(x / 7.0) * np.cos(y / 9.0) + rng.normal(0, 2, (n, n))).astype(np.float32)


def _simulate(dem, **kwargs):
    options = {"transform": GT, "crs": 32631, **SIM, **kwargs}
    return gissar.simulate(dem, **options)


def _same(a, b):
    """Results (DataArrays, arrays, dicts and tuples of them) equal bit for bit (NaN equal to NaN)."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if hasattr(a, "values") and hasattr(a, "dims"):
        return _same(a.values, b.values) and _same(a["mask"].values, b["mask"].values)
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")


def _strided(a):
    """The same values as a view with steps into a larger array (not contiguous)."""
    big = np.zeros((a.shape[0] * 2, a.shape[1] * 3) + a.shape[2:], a.dtype)
    big[::2, ::3] = a
    view = big[::2, ::3]
    assert not view.flags.c_contiguous
    return view


#: Other memory layouts and byte orders of the same values: each must give the reference result exactly.
LAYOUTS = {
    "strided": _strided,
    "fortran": np.asfortranarray,
    "transposed_view": lambda a: np.ascontiguousarray(a.T).T,
    "big_endian_f4": lambda a: a.astype(">f4"),
    "big_endian_f8": lambda a: a.astype(">f8"),
    "float64": lambda a: a.astype(np.float64),
    "object_of_floats": lambda a: a.astype(object),
}


def _assert_refused(error, parameter, *texts):
    """`error` (a pytest ExceptionInfo) is the documented type and names `parameter` (and says `texts`)."""
    message = str(error.value)
    assert f"{parameter})" in message, message
    for text in texts:
        assert text in message, (text, message)


# ---------------------------------------------------------------- a DEM given as an array

@pytest.fixture(scope="module")
def dem_reference():
    dem = _dem()
    return dem, _simulate(dem)


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_dem_array_in_any_layout_or_byte_order_gives_the_reference_image(dem_reference, layout):
    dem, reference = dem_reference
    variant = LAYOUTS[layout](dem)
    assert _same(_simulate(variant), reference)
    assert _same(gissar.raw.simulate(variant, transform=GT, crs=32631, **SIM)["image"],
                 reference.sel(band="total").values)


@pytest.mark.parametrize("dtype", [np.int16, np.int32, np.uint16, np.float16])
def test_integer_and_float16_heights_are_converted_exactly(dtype):
    heights = np.round(_dem()).astype(dtype)
    assert _same(_simulate(heights), _simulate(heights.astype(np.float32)))


@pytest.mark.parametrize("case, values, text", [
    ("bool", _dem() > 500, "got a bool array"),
    ("complex", _dem().astype(np.complex64), "got complex values"),
    ("text", np.full((N, N), "500"), "got dtype <U3"),
    ("objects", np.array([[object()] * 4] * 4), "objects that are not numbers"),
])
def test_dem_array_of_non_real_values_is_refused(case, values, text):
    with pytest.raises(gissar.ArrayTypeError) as error:
        _simulate(values)
    assert isinstance(error.value, TypeError) and isinstance(error.value, ValueError)
    _assert_refused(error, "dem", "must be an array of real heights", text)


@pytest.mark.parametrize("dtype", [np.bool_, np.complex64, np.complex128, np.dtype("<U3"), object])
def test_the_core_refuses_non_real_dem_arrays_itself(dtype):
    """The private core, called directly (not through the package's converters), casts nothing either."""
    values = np.ones((N, N), dtype=dtype) if dtype is not object else np.full((N, N), 1.0, dtype=object)
    with pytest.raises(gissar.InputError) as error:
        gissar._core.simulate(dem=values, transform=GT, crs=32631, **SIM)
    assert "must be an array of real heights, got dtype" in str(error.value)
    assert "dem" in str(error.value)


@pytest.mark.parametrize("case, values, error_type, text", [
    ("empty_rows", np.zeros((0, N), np.float32), gissar.InputError, "got an empty array of shape (0, 48)"),
    ("empty_columns", np.zeros((N, 0), np.float32), gissar.InputError, "got an empty array of shape (48, 0)"),
    ("one_dimensional", _dem().ravel(), gissar.InputError, "got shape (2304,)"),
    ("three_dimensional", _dem()[None], gissar.InputError, "got shape (1, 48, 48)"),
])
def test_dem_array_of_the_wrong_shape_is_refused(case, values, error_type, text):
    with pytest.raises(error_type) as error:
        _simulate(values)
    _assert_refused(error, "dem", "must be a non-empty 2-D array of heights", text)


def test_dem_array_without_heights_is_refused_naming_the_array():
    with pytest.raises(gissar.InputError) as error:
        _simulate(np.full((N, N), np.nan, np.float32))
    _assert_refused(error, "the `dem` array", "DEM has no valid height (all 2304 cells are no-data)")
    with pytest.raises(gissar.InputError) as error:
        _simulate(_dem()[:1])
    _assert_refused(error, "the `dem` array", "at least 2x2 posts")


def test_dem_array_over_the_memory_budget_is_refused_before_the_run():
    # simulate and sequence take max_memory_bytes (the command line's --max-memory); Scene.build and
    # build_scene have no such keyword (the command line's `scene build --max-memory` is not offered in
    # Python), so they are not attacked on this point.
    with pytest.raises(gissar.InputError) as error:
        _simulate(_dem(), max_memory_bytes=64 * 1024)
    _assert_refused(error, "the `dem` array", "over the memory limit of 64 KiB (max_memory_bytes)")


@pytest.mark.parametrize("case, transform, crs, error_type, parameter, text", [
    ("zero_pixel_width", (400000.0, 0.0, 0.0, 4700000.0, 0.0, -30.0), 32631, gissar.ConfigError, "transform",
     "is singular (a zero pixel size"),
    ("zero_pixel_height", (400000.0, 30.0, 0.0, 4700000.0, 0.0, 0.0), 32631, gissar.ConfigError, "transform",
     "is singular"),
    ("rows_parallel_to_columns", (400000.0, 30.0, 30.0, 4700000.0, 30.0, 30.0), 32631, gissar.ConfigError,
     "transform", "is singular"),
    ("not_finite", (400000.0, np.nan, 0.0, 4700000.0, 0.0, -30.0), 32631, gissar.ConfigError, "transform",
     "coefficients must be finite"),
    ("five_coefficients", (400000.0, 30.0, 0.0, 4700000.0, -30.0), 32631, gissar.ConfigError, "transform",
     "needs GDAL's six coefficients"),
    ("text", "400000 30 0 4700000 0 -30", 32631, gissar.ConfigError, "transform", "needs GDAL's six coefficients"),
    ("crs_proj_cannot_parse", GT, "+proj=nowhere", gissar.ConfigError, "crs", "not a CRS: '+proj=nowhere'"),
    ("crs_unknown_epsg", GT, 999999, gissar.ConfigError, "crs", "not a CRS: 'EPSG:999999'"),
    ("crs_float", GT, 32631.0, gissar.ConfigError, "crs", "must be an EPSG code"),
    # Metres of spacing in a lon/lat CRS put the posts far beyond the poles.
    ("geographic_crs_metre_spacing", (1.5, 30.0, 0.0, 42.5, 0.0, -30.0), 4326, gissar.InputError,
     "the `dem` array", "beyond 90 degrees: its geotransform is wrong"),
])
def test_transform_or_crs_that_disagrees_with_the_array_is_refused(case, transform, crs, error_type, parameter,
                                                                   text):
    with pytest.raises(error_type) as error:
        gissar.simulate(_dem(), transform=transform, crs=crs, **SIM)
    _assert_refused(error, parameter, text)


def test_nodata_must_be_a_number():
    with pytest.raises(gissar.ArrayTypeError) as error:
        _simulate(_dem(), nodata="-9999")
    _assert_refused(error, "nodata", "must be a real number or None, got str")
    assert _same(_simulate(_dem(), nodata=np.nan), _simulate(_dem()))  # NaN: the NaN cells, none here


def test_flipped_and_rotated_transforms_place_the_heights_where_the_transform_says():
    """A negative pixel width, a positive pixel height and a 90-degree rotation describe the same terrain as a
    north-up grid of the same heights: the same image (to float rounding, on a plane where the order in which
    the cells are traced cannot matter) and the same mask."""
    y, x = np.mgrid[0:N, 0:N]
    plane = (500 + 0.3 * x + 0.2 * y).astype(np.float32)
    options = dict(SIM, range_spacing_m=30.0, azimuth_spacing_m=30.0)
    reference = gissar.simulate(plane, transform=GT, crs=32631, **options)
    x0, y0, side = GT[0], GT[3], N * 30.0
    for values, transform in ((plane[:, ::-1], (x0 + side, -30.0, 0.0, y0, 0.0, -30.0)),
                              (plane[::-1], (x0, 30.0, 0.0, y0 - side, 0.0, 30.0)),
                              (plane[::-1].T, (x0, 0.0, 30.0, y0 - side, 30.0, 0.0))):
        image = gissar.simulate(values, transform=transform, crs=32631, **options)
        assert image.shape == reference.shape
        assert np.array_equal(image["mask"].values, reference["mask"].values)
        np.testing.assert_allclose(image.values, reference.values, rtol=1e-4, atol=1e-6)


def test_scene_build_checks_the_dem_array_like_simulate(tmp_path):
    with pytest.raises(gissar.ArrayTypeError) as error:
        gissar.Scene.build(_dem().astype(np.complex64), str(tmp_path / "s"), transform=GT, crs=32631)
    _assert_refused(error, "dem", "got complex values")
    with pytest.raises(gissar.ConfigError) as error:
        gissar.build_scene(_dem(), str(tmp_path / "s"), transform=(0.0, 30.0, 0.0, 0.0, 0.0, 0.0), crs=32631)
    _assert_refused(error, "transform", "is singular")
    assert not list(tmp_path.iterdir())


# ---------------------------------------------------------------- images, points, matrices, pictures

def _texture(shape, seed):
    rng = np.random.default_rng(seed)
    base = rng.gamma(1.0, 1.0, size=shape)
    k = np.ones(5) / 5
    base = np.apply_along_axis(lambda r: np.convolve(r, k, "same"), 1, base)
    base = np.apply_along_axis(lambda c: np.convolve(c, k, "same"), 0, base)
    return (base ** 4).astype(np.float32)


REF = _texture((72, 80), 4)
OBS = np.roll(REF, (-3, 4), axis=(0, 1))
PTS_FIXED = np.array([[10, 10], [60, 12], [20, 50], [70, 60], [40, 40]], float)
PTS_MOVING = PTS_FIXED - [3, -2]
F_TRUE = np.array([[0, 0, 0.6], [0, 0, 0.8], [-0.6, -0.8, 0.0]])
MATCH = dict(patch_px=21, step_px=12, search_px=8, filter_px=1)

#: Each image function with its image parameters (all given the same variant) and its other arguments.
IMAGE_CALLS = {
    "match_images": (gissar.match_images, ("reference", "observed"), lambda a, b: ((a, b), MATCH)),
    "register_images": (gissar.register_images, ("fixed", "moving"),
                        lambda a, b: ((a, b, PTS_FIXED, PTS_MOVING), {})),
    "quicklook": (gissar.quicklook, ("intensity",), lambda a, b: ((a,), {})),
    "annotated_quicklook": (gissar.annotated_quicklook, ("intensity",), lambda a, b: ((a, 10.0, 12.0, "t"), {})),
    "composite": (gissar.composite, ("green", "magenta"), lambda a, b: ((a, b), {})),
    "epipolar_plot": (gissar.epipolar_plot, ("image1", "image2"),
                      lambda a, b: ((a, b, PTS_FIXED, PTS_FIXED, F_TRUE), {})),
}


def _call(name, a, b):
    function, _, arguments = IMAGE_CALLS[name]
    args, kwargs = arguments(a, b)
    return function(*args, **kwargs)


@pytest.mark.parametrize("name", sorted(IMAGE_CALLS))
def test_image_functions_take_any_layout_byte_order_and_real_type(name):
    reference = _call(name, REF, OBS)
    if name == "match_images":
        assert len(reference["score"]) >= 5  # the comparison means something
    for layout, variant in LAYOUTS.items():
        assert _same(_call(name, variant(REF), variant(OBS)), reference), layout
    assert _same(_call(name, REF.tolist(), OBS.tolist()), reference)
    # Integers and float16 convert exactly to float32: the result of the float32 copy.
    for dtype in (np.int32, np.uint16, np.float16):
        a, b = (np.round(v * 100).astype(dtype) for v in (REF, OBS))
        assert _same(_call(name, a, b), _call(name, a.astype(np.float32), b.astype(np.float32))), dtype


@pytest.mark.parametrize("name", sorted(IMAGE_CALLS))
@pytest.mark.parametrize("case, bad, error_type, text", [
    ("bool", REF > 1, gissar.ArrayTypeError, "got a bool array"),
    ("complex", REF.astype(np.complex64), gissar.ArrayTypeError, "got complex values (complex64): give the intensity"),
    ("text", np.full(REF.shape, "1"), gissar.ArrayTypeError, "got dtype <U1"),
    ("none", None, gissar.ArrayTypeError, "got None"),
    ("empty", REF[:0], gissar.InputError, "got an empty array of shape (0, 80)"),
    ("one_dimensional", REF[0], gissar.InputError, "got shape (80,)"),
    ("three_dimensional", REF[None], gissar.InputError, "got shape (1, 72, 80)"),
])
def test_image_functions_refuse_non_real_or_misshapen_images_naming_the_parameter(name, case, bad, error_type, text):
    function, parameters, _ = IMAGE_CALLS[name]
    for i, parameter in enumerate(parameters):
        images = [REF, OBS]
        images[i] = bad
        with pytest.raises(error_type) as error:
            _call(name, *images)
        _assert_refused(error, f"gissar.{name}: {parameter}", text)
        if error_type is gissar.ArrayTypeError:
            assert isinstance(error.value, TypeError)


def test_all_nan_images_are_no_return():
    """NaN is no return (documented): an all-NaN image is a black quicklook and matches nothing."""
    nan = np.full(REF.shape, np.nan, np.float32)
    grey, stretch = gissar.quicklook(nan)
    assert _same(grey, np.zeros(REF.shape, np.uint8)) and stretch == (0.0, 0.0)
    assert _same(gissar.quicklook(nan), gissar.quicklook(np.zeros(REF.shape, np.float32)))
    found = gissar.match_images(nan, OBS, **MATCH)
    assert found["x_reference"].shape == (0, 2) and found["score"].shape == (0,)


def test_points_and_matrices_take_any_layout_and_refuse_non_real_values():
    rng = np.random.default_rng(7)
    geometry = gissar.SarGeometry(heading_deg=30.0, depression_deg=40.0)
    # Values exact in float32, so that every layout (float32 ones too) holds the same numbers.
    enu = (rng.uniform(-500, 500, (30, 3)) * [1, 1, 0.2]).astype(np.float32).astype(np.float64)
    x1 = gissar.SarGeometry(heading_deg=0.0, depression_deg=40.0).project(enu)  # two views of the same points
    x1, x2 = (x.astype(np.float32).astype(np.float64) for x in (x1, geometry.project(enu)))
    reference = gissar.fmatrix(x1, x2, seed=3)
    pose = gissar.resect(enu, x2)
    for layout, variant in LAYOUTS.items():
        assert _same(gissar.fmatrix(variant(x1), variant(x2), seed=3), reference), layout
        assert _same(gissar.resect(variant(enu), variant(x2)), pose), layout
        assert _same(geometry.project(variant(enu)), geometry.project(enu)), layout
    assert _same(gissar.kvd(np.asfortranarray(reference["F"]).astype(">f8")), gissar.kvd(reference["F"]))
    assert _same(gissar.register_points(_strided(PTS_FIXED), PTS_MOVING.astype(">f4")),
                 gissar.register_points(PTS_FIXED, PTS_MOVING.astype(np.float32)))
    for call, parameter in ((lambda v: gissar.fmatrix(v, x2), "gissar.fmatrix: x1"),
                            (lambda v: gissar.register_points(PTS_FIXED, v[:5]), "gissar.register_points: moving_px"),
                            (lambda v: gissar.register_images(REF, OBS, v[:5], PTS_MOVING),
                             "gissar.register_images: fixed_px"),
                            (lambda v: gissar.epipolar_plot(REF, REF, PTS_FIXED, v[:5], F_TRUE),
                             "gissar.epipolar_plot: x2")):
        with pytest.raises(gissar.ArrayTypeError) as error:
            call(x1 > 100)
        _assert_refused(error, parameter, "must be an array of real coordinates, got a bool array")
        with pytest.raises(gissar.ArrayTypeError) as error:
            call(x1.astype(complex))
        _assert_refused(error, parameter, "got complex values")
        with pytest.raises(gissar.InputError) as error:
            call(x1[:, :1])
        _assert_refused(error, parameter, "must be an (N, 2) array, got shape")
    with pytest.raises(gissar.InputError) as error:
        gissar.resect(enu[:, :2], x2)
    _assert_refused(error, "gissar.resect: world_enu_m", "must be an (N, 3) array, got shape (30, 2)")
    with pytest.raises(gissar.ArrayTypeError) as error:
        geometry.project(enu.astype(complex))
    _assert_refused(error, "SarGeometry.project: points_enu_m", "got complex values")
    with pytest.raises(gissar.InputError) as error:
        gissar.kvd(np.eye(2))
    _assert_refused(error, "gissar.kvd: F", "must be a 3 x 3 matrix, got shape (2, 2)")
    with pytest.raises(gissar.ArrayTypeError) as error:
        gissar.match_images(REF, OBS, warp=np.eye(2, 3, dtype=complex))
    _assert_refused(error, "gissar.match_images: warp", "got complex values")


def test_pictures_refuse_floats_instead_of_truncating_them(tmp_path):
    grey = (np.arange(12 * 16).reshape(12, 16) % 256).astype(np.uint8)
    # Before: a float picture in 0..1 was cast to uint8 and written as a black PNG.
    with pytest.raises(gissar.ArrayTypeError) as error:
        gissar.write_png(str(tmp_path / "a.png"), grey / 255.0)
    _assert_refused(error, "gissar.write_png: image", "must be a uint8 array (0..255), got dtype float64")
    with pytest.raises(gissar.InputError) as error:
        gissar.write_png(str(tmp_path / "a.png"), grey.astype(np.int32) * 2)
    _assert_refused(error, "gissar.write_png: image", "pixel values must be within 0..255, got 0..382")
    with pytest.raises(gissar.ArrayTypeError) as error:
        gissar.write_gif(str(tmp_path / "a.gif"), [grey, grey.astype(np.float32)])
    _assert_refused(error, "gissar.write_gif: frames[1]", "got dtype float32")
    with pytest.raises(gissar.ArrayTypeError) as error:
        gissar.side_by_side([np.zeros((4, 4, 3), bool)], ["a"])
    _assert_refused(error, "gissar.side_by_side: panels[0]", "got dtype bool")
    assert not list(tmp_path.iterdir())
    # Integers within 0..255 in any layout: the same file as the uint8 original.
    gissar.write_png(str(tmp_path / "a.png"), grey)
    gissar.write_png(str(tmp_path / "b.png"), _strided(grey.astype(">u2")))
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()


def test_pta_and_polsar_take_paths_and_say_so_for_an_array(tmp_path):
    with pytest.raises(gissar.ArrayTypeError) as error:
        gissar.polsar(str(tmp_path / "p"), image=np.zeros((8, 8), np.complex64))
    _assert_refused(error, "image", "must be a path (str or os.PathLike), got ndarray: write the array")
    with pytest.raises(gissar.ArrayTypeError) as error:
        gissar.pta(np.zeros((2, 7)), str(tmp_path / "p"), image=str(tmp_path / "x_slc.tif"))
    _assert_refused(error, "reflectors", "must be a path (str or os.PathLike), got ndarray")
    assert not list(tmp_path.iterdir())


# ---------------------------------------------------------------- progress callbacks, Ctrl-C, threads

class CallbackFailure(Exception):
    pass


def _failing_callback(stage, done, total):
    raise CallbackFailure(f"stopped at {stage} {done}/{total}")


def test_a_raising_progress_callback_propagates_as_itself_and_writes_nothing(tmp_path):
    # Before: the exception was printed as "unraisable" and the call raised gissar.Cancelled.
    with pytest.raises(CallbackFailure, match="stopped at simulate: tracing"):
        _simulate(_dem(), out_prefix=str(tmp_path / "s"), progress=_failing_callback)
    with pytest.raises(CallbackFailure, match="stopped at scene build 1/"):
        gissar.Scene.build(_dem(), str(tmp_path / "scene"), transform=GT, crs=32631, vertical_datum="ellipsoid",
                           progress=_failing_callback)
    with pytest.raises(CallbackFailure, match="stopped at"):
        gissar.sequence(str(tmp_path / "q"), 0.0, 10.0, frames=2, dem=_dem(), transform=GT, crs=32631,
                        progress=_failing_callback, **{k: v for k, v in SIM.items() if k != "heading_deg"})
    assert not list(tmp_path.iterdir())
    # A callback returning False still cancels (gissar.Cancelled), and the next call works.
    with pytest.raises(gissar.Cancelled, match="cancelled on request"):
        _simulate(_dem(), progress=lambda *a: False)
    assert _same(_simulate(_dem()), _simulate(_dem()))


def test_ctrl_c_during_a_simulation_that_writes_files_leaves_nothing(tmp_path):
    """SIGINT from another thread while the core traces: KeyboardInterrupt within a few seconds of the signal,
    no output, no temporary and no lock file in the directory."""
    dem = _dem(64)
    long_run = dict(range_spacing_m=2.0, azimuth_spacing_m=2.0, rays_per_cell=16, bounces=2)
    sent = {}

    def progress(stage, done, total):
        if not sent:  # the first report: the core is tracing; interrupt it from a timer thread
            sent["at"] = None
            def interrupt():
                sent["at"] = time.perf_counter()
                os.kill(os.getpid(), signal.SIGINT)
            threading.Timer(0.1, interrupt).start()

    with pytest.raises(KeyboardInterrupt):
        _simulate(dem, out_prefix=str(tmp_path / "k"), progress=progress, **long_run)
    stopped = time.perf_counter()
    assert sent.get("at") is not None, "the run ended before the signal"
    assert stopped - sent["at"] < 3.0, stopped - sent["at"]
    assert sorted(os.listdir(tmp_path)) == []
    # The uninterrupted run is longer than the interrupted one: it was stopped, not finished.
    t = time.perf_counter()
    full = _simulate(dem, out_prefix=str(tmp_path / "k"), **long_run)
    assert time.perf_counter() - t > stopped - sent["at"]
    assert sorted(os.path.basename(p) for p in full.attrs["outputs"]) == sorted(os.listdir(tmp_path))


def _longest_pause_while(function):
    """(seconds `function` took in another thread, longest pause of this thread meanwhile)."""
    done, took = threading.Event(), {}

    def work():
        t = time.perf_counter()
        try:
            function()
        finally:
            took["s"] = time.perf_counter() - t
            done.set()

    thread = threading.Thread(target=work)
    last = time.perf_counter()
    longest = 0.0
    thread.start()
    while not done.is_set():
        now = time.perf_counter()
        longest = max(longest, now - last)
        last = now
    thread.join()
    return took["s"], longest


def test_long_calls_release_the_gil(tmp_path):
    """While each long call runs in another thread, this thread keeps running: the longest pause between two
    of its loop iterations stays far below the call's duration (it would be the whole duration if the GIL
    were held; before, the picture functions held it for their whole run: 0.4 s to 1.4 s on 3000 x 3000
    pixels)."""
    big = _texture((3000, 3000), 5)
    matrix = _texture((220, 220), 6)
    andorra = os.path.join(os.path.dirname(__file__), "..", "..", "data", "andorra", "andorra_srtm3_dem_filled.tif")
    calls = {
        "simulate": lambda: gissar.simulate(dem=andorra, heading_deg=10, depression_deg=40, range_spacing_m=60,
                                            azimuth_spacing_m=60, rays_per_cell=8),
        "quicklook": lambda: gissar.quicklook(big),
        "annotated_quicklook": lambda: gissar.annotated_quicklook(big, 10.0, 10.0),
        "composite": lambda: gissar.composite(big, big),
        "epipolar_plot": lambda: gissar.epipolar_plot(big, big, PTS_FIXED, PTS_FIXED, F_TRUE),
        "register_images": lambda: gissar.register_images(big, big, PTS_FIXED, PTS_MOVING),
        "match_images": lambda: gissar.match_images(matrix, matrix, patch_px=21, step_px=6, search_px=12),
        "Scene.build": lambda: gissar.Scene.build(_dem(96), str(tmp_path / "s"), transform=GT, crs=32631,
                                                  vertical_datum="ellipsoid"),
    }
    measured = []
    for name, call in calls.items():
        took, longest = _longest_pause_while(call)
        if name == "simulate":
            assert took > 0.2, took  # long enough for the measurement to mean something
        if took < 0.1:
            continue  # too quick on this machine for the pause to mean anything; counted below
        measured.append(name)
        assert longest < 0.6 * took, (name, longest, took)
    # A faster machine may finish a picture call in under 0.1 s; most calls must still be measured.
    assert "simulate" in measured and len(measured) >= 5, measured


def test_concurrent_calls_equal_sequential_ones_and_keep_warnings_working():
    """Four threads calling simulate (DEM arrays), match_images and quicklook at once give what sequential
    calls give; every call's warnings reach the caller, and the process's warnings state is untouched (before,
    concurrent simulate calls left warnings.catch_warnings' state swapped: later warnings vanished)."""
    dems = [_dem(seed=s) for s in range(3)]
    tasks = []
    for i in range(12):
        kind = i % 3
        if kind == 0:
            # No vertical_datum: each call warns once that the DEM states none.
            tasks.append(("simulate", lambda d=dems[i % 2], h=float(10 * (i % 4)): gissar.simulate(
                d, transform=GT, crs=32631, heading_deg=h, depression_deg=40.0, seed=1)))
        elif kind == 1:
            tasks.append(("match_images", lambda s=i: gissar.match_images(REF, np.roll(OBS, s % 3, axis=1), **MATCH)))
        else:
            tasks.append(("quicklook", lambda s=i: gissar.quicklook(REF, low_percentile=float(s % 5))))
    filters_before = list(warnings.filters)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sequential = [task() for _, task in tasks]
        n_sequential = len(caught)
        with concurrent.futures.ThreadPoolExecutor(max_workers=4) as pool:
            concurrent_results = list(pool.map(lambda t: t[1](), tasks))
        n_concurrent = len(caught) - n_sequential
    for (name, _), a, b in zip(tasks, sequential, concurrent_results):
        assert _same(a, b), name
    simulations = sum(1 for name, _ in tasks if name == "simulate")
    datum = [w for w in caught if issubclass(w.category, gissar.GissarWarning) and "vertical datum" in str(w.message)]
    assert n_sequential == n_concurrent and len(datum) == 2 * simulations, (n_sequential, n_concurrent, len(datum))
    # Issued by the calling thread and attributed to the caller's line, here (not to gissar's modules).
    assert {os.path.abspath(w.filename) for w in datum} == {os.path.abspath(__file__)}
    assert warnings.filters == filters_before
    with pytest.warns(gissar.GissarWarning, match="vertical datum"):
        gissar.simulate(dems[0], transform=GT, crs=32631, heading_deg=0.0, depression_deg=40.0)


def test_geocode_says_a_bare_dem_array_has_no_georeferencing(tmp_path):
    with pytest.raises(gissar.ConfigError) as error:
        gissar.geocode(str(tmp_path / "sim.tif"), str(tmp_path / "m"), dem=_dem())
    _assert_refused(error, "dem", "a bare array has no georeferencing here")
    assert not list(tmp_path.iterdir())
