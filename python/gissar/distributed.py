"""gissar.distributed: reference-image databases for a flight corridor, computed on Dask distributed.

A corridor is a route (the sensor's ground track: a GeoJSON LineString or a CSV of ``lon,lat`` waypoints,
WGS84) resampled every ``pose_step_m`` metres along the geodesic, times a list of headings. Each pose x heading
is one ``gissar.simulate`` of a fixed-size image (``width`` x ``height``), so a worker only needs the DEM window
under that image. Every simulation is a Dask task; the default cluster is an embedded
``distributed.LocalCluster`` (one single-threaded worker process per core, loopback), ``scheduler="tcp://..."``
uses a running cluster and ``client=`` an existing ``distributed.Client``.

Outputs (docs/distributed.md): ``PREFIX_<id>.*`` per pose (the files of ``gissar.simulate(out_prefix=...)``,
its STAC Item ``PREFIX_<id>_stac.json`` joined to the collection, and ``PREFIX_<id>_done.json``, the
done-marker written last), ``PREFIX_catalog.json`` (a STAC Collection: every pose with its status, the run
summary) and ``PREFIX_index.csv`` (one row per pose: id, lon, lat, heading_deg, status, footprint WKT, files).

Resuming: a pose whose done-marker holds the same key (SHA-256 of the inputs' identity, the pose's simulate
request and the gissar version) and whose files all exist is not simulated again. A worker that dies mid-task
is replaced (the nanny restarts it) and Dask runs the task again (``retries``).
"""
import csv
import errno
import glob
import hashlib
import io
import json
import math
import os
import resource
import socket
import sys
import time
import uuid

import gissar
from gissar import ConfigError, InputError, IoError

#: STAC version of the catalogue and the Items.
STAC_VERSION = "1.0.0"
#: Simulate keywords the corridor sets itself per pose (or that would name one file for every pose).
_PER_POSE = ("center_lonlat", "center_map", "heading_deg", "out_prefix", "product", "orbit", "radar_grid",
             "contributions")
_INPUT_FILES = ("dem", "scene", "materials", "reflectors")
_HASH_INPUTS = ("sha256", "stat")


# ---------------------------------------------------------------- route and poses

def _number(text, where):
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise InputError(f"not a number: {text!r} ({where})") from None
    if not math.isfinite(value):
        raise InputError(f"not a finite number: {text!r} ({where})")
    return value


def _lonlat(point, where):
    if not isinstance(point, (list, tuple)) or len(point) < 2:
        raise InputError(f"a point must be [lon, lat], got {point!r} ({where})")
    lon, lat = _number(point[0], where), _number(point[1], where)
    if not (-180.0 <= lon <= 360.0 and -90.0 <= lat <= 90.0):
        raise InputError(f"longitude/latitude out of range: {lon}, {lat} ({where})")
    return (lon, lat)


def _geojson_line(data, where):
    """The coordinates of the one LineString of a GeoJSON geometry, Feature or FeatureCollection."""
    kind = data.get("type") if isinstance(data, dict) else None
    if kind == "FeatureCollection":
        lines = [f.get("geometry") for f in data.get("features", []) if isinstance(f, dict)]
        lines = [g for g in lines if isinstance(g, dict) and g.get("type") == "LineString"]
        if len(lines) != 1:
            raise InputError(f"a route FeatureCollection needs exactly one LineString, found {len(lines)} ({where})")
        return lines[0].get("coordinates", [])
    if kind == "Feature":
        return _geojson_line(data.get("geometry") or {}, where)
    if kind == "LineString":
        return data.get("coordinates", [])
    raise InputError(f"a route is a GeoJSON LineString (or a Feature of one), got type {kind!r} ({where})")


def read_route(route):
    """The route's waypoints as [(lon_deg, lat_deg), ...] (WGS84). route: a GeoJSON file (.geojson/.json: a
    LineString, a Feature of one or a FeatureCollection with exactly one), a CSV file of ``lon,lat`` rows (an
    optional header naming the columns lon and lat, in any order, among others), or a sequence of (lon, lat)
    pairs. Fewer than two distinct points is an InputError naming the route."""
    if isinstance(route, (str, os.PathLike)):
        path = os.fspath(route)
        try:
            with open(path, encoding="utf-8") as f:
                text = f.read()
        except FileNotFoundError:
            raise gissar.MissingFileError(f"route file does not exist ({path})") from None
        except OSError as e:
            raise IoError(f"cannot read the route: {e.strerror} ({path})") from None
        if path.lower().endswith((".geojson", ".json")) or text.lstrip().startswith("{"):
            try:
                data = json.loads(text)
            except json.JSONDecodeError as e:
                raise InputError(f"not JSON: {e.msg} at line {e.lineno} ({path})") from None
            points = [_lonlat(p, f"{path}, point {i + 1}") for i, p in enumerate(_geojson_line(data, path))]
        else:
            points = _read_csv_route(text, path)
        where = path
    else:
        points = [_lonlat(p, f"route, point {i + 1}") for i, p in enumerate(route)]
        where = "route"
    distinct = [p for i, p in enumerate(points) if i == 0 or p != points[i - 1]]
    if len(distinct) < 2:
        raise InputError(f"a route needs at least two distinct points, got {len(distinct)} ({where})")
    return distinct


def _read_csv_route(text, path):
    rows = [r for r in csv.reader(io.StringIO(text)) if r and any(c.strip() for c in r)
            and not r[0].lstrip().startswith("#")]
    lon_col, lat_col = 0, 1
    if rows:
        header = [c.strip().lower() for c in rows[0]]
        try:
            float(header[0])
        except ValueError:
            names = {"lon": ("lon", "lon_deg", "longitude", "x"), "lat": ("lat", "lat_deg", "latitude", "y")}
            found = {k: next((i for i, h in enumerate(header) if h in v), None) for k, v in names.items()}
            if found["lon"] is None or found["lat"] is None:
                raise InputError(f"the CSV header needs columns lon and lat, got {rows[0]} ({path}, line 1)")
            lon_col, lat_col = found["lon"], found["lat"]
            rows = rows[1:]
    points = []
    for i, row in enumerate(rows):
        if len(row) <= max(lon_col, lat_col):
            raise InputError(f"a route row needs lon,lat, got {row} ({path}, row {i + 1})")
        points.append(_lonlat((row[lon_col], row[lat_col]), f"{path}, row {i + 1}"))
    return points


def _geod():
    from pyproj import Geod
    return Geod(ellps="WGS84")


def resample_route(points, pose_step_m):
    """Points every pose_step_m metres along the route, measured on the WGS84 ellipsoid (geodesics between the
    waypoints), starting at the first waypoint: [(lon_deg, lat_deg, track_deg, distance_m), ...]; track_deg is
    the geodesic's azimuth there. The last waypoint is a pose only when the length is a multiple of the step."""
    if not (isinstance(pose_step_m, (int, float)) and math.isfinite(pose_step_m) and pose_step_m > 0):
        raise ConfigError(f"must be a positive number of metres, got {pose_step_m!r} (pose_step_m)")
    geod = _geod()
    out = []
    start_m = 0.0  # distance along the route of the current segment's start
    next_m = 0.0
    for (lon0, lat0), (lon1, lat1) in zip(points[:-1], points[1:]):
        azimuth, _, length_m = geod.inv(lon0, lat0, lon1, lat1)
        while next_m <= start_m + length_m + 1e-6:
            s = next_m - start_m
            lon, lat, back = geod.fwd(lon0, lat0, azimuth, s)
            track = (back + 180.0) % 360.0 if s > 0 else azimuth % 360.0
            out.append((lon, lat, track, next_m))
            next_m += pose_step_m
        start_m += length_m
    return out


def _heading_text(heading_deg):
    h = heading_deg % 360.0
    if abs(h - round(h)) < 1e-9:
        return f"{int(round(h)) % 360:03d}"
    return (f"{h:07.3f}".rstrip("0")).replace(".", "p")


def pose_id(index, heading_deg, digits=4):
    """The stable id of a pose: ``p0007_h090`` (pose 7 along the route, heading 90 deg), ``p0007_h022p5`` for
    22.5 deg; ``digits`` digits for the pose number."""
    return f"p{index:0{digits}d}_h{_heading_text(heading_deg)}"


def corridor_poses(route, *, pose_step_m, headings_deg, slant_range_m=10000.0, depression_deg=40.0,
                   look_side="right"):
    """The poses of a corridor, in id order: a list of dicts with id, index, lon_deg, lat_deg (the sensor's
    ground-track point), distance_m (along the route), track_deg (the route's azimuth there), heading_deg,
    center_lon_deg, center_lat_deg (the scene centre: the track point moved by the ground range
    slant_range_m * cos(depression_deg) along the geodesic at heading_deg + 90 deg, right-looking, or - 90 deg,
    left-looking) and ground_range_m."""
    headings = _headings(headings_deg)
    if look_side not in ("right", "left"):
        raise ConfigError(f"must be right or left, got {look_side!r} (look_side)")
    if not (0.0 < depression_deg < 90.0):
        raise ConfigError(f"must be in (0, 90) degrees, got {depression_deg} (depression_deg)")
    if not (slant_range_m > 0.0):
        raise ConfigError(f"must be positive, got {slant_range_m} (slant_range_m)")
    points = read_route(route)
    track = resample_route(points, pose_step_m)
    ground_range_m = slant_range_m * math.cos(math.radians(depression_deg))
    side = 90.0 if look_side == "right" else -90.0
    digits = max(4, len(str(len(track) - 1)))
    geod = _geod()
    poses = []
    for index, (lon, lat, track_deg, distance_m) in enumerate(track):
        for heading in headings:
            clon, clat, _ = geod.fwd(lon, lat, heading + side, ground_range_m)
            poses.append({"id": pose_id(index, heading, digits), "index": index, "lon_deg": lon, "lat_deg": lat,
                          "distance_m": distance_m, "track_deg": track_deg, "heading_deg": heading,
                          "center_lon_deg": clon, "center_lat_deg": clat, "ground_range_m": ground_range_m})
    return poses


def _headings(headings_deg):
    if isinstance(headings_deg, (int, float)):
        headings_deg = [headings_deg]
    try:
        values = [float(h) for h in headings_deg]
    except (TypeError, ValueError):
        raise ConfigError(f"must be a list of degrees, got {headings_deg!r} (headings_deg)") from None
    if not values or not all(math.isfinite(h) for h in values):
        raise ConfigError(f"must be one or more finite headings in degrees, got {headings_deg!r} (headings_deg)")
    texts = [_heading_text(h) for h in values]
    if len(set(texts)) != len(texts):
        raise ConfigError(f"headings repeat (modulo 360): {headings_deg!r} (headings_deg)")
    return [h % 360.0 for h in values]


# ---------------------------------------------------------------- footprints and extents

def _enu_offset_lonlat(lon, lat, east_m, north_m):
    """A point east_m/north_m from (lon, lat) on the ellipsoid (geodesic of that length and azimuth)."""
    distance = math.hypot(east_m, north_m)
    if distance == 0.0:
        return lon, lat
    lon2, lat2, _ = _geod().fwd(lon, lat, math.degrees(math.atan2(east_m, north_m)), distance)
    return lon2, lat2


def predicted_footprint(pose, width, height, range_spacing_m, azimuth_spacing_m, depression_deg, look_side):
    """The image's ground footprint (WGS84 lon/lat ring, 5 points, closed) on the plane of the scene centre:
    width * range_spacing_m / cos(depression) of ground range across, height * azimuth_spacing_m along the
    heading. Terrain higher or lower than the centre shifts by its height * tan(depression) toward or away from
    the sensor; the estimate ignores that."""
    across = 0.5 * width * range_spacing_m / math.cos(math.radians(depression_deg))
    along = 0.5 * height * azimuth_spacing_m
    h = math.radians(pose["heading_deg"])
    f = (math.sin(h), math.cos(h))                      # flight direction (east, north)
    s = 1.0 if look_side == "right" else -1.0
    r = (s * math.cos(h), -s * math.sin(h))             # ground look direction
    ring = []
    for a, c in ((-1, -1), (1, -1), (1, 1), (-1, 1), (-1, -1)):
        e = a * along * f[0] + c * across * r[0]
        n = a * along * f[1] + c * across * r[1]
        ring.append(_enu_offset_lonlat(pose["center_lon_deg"], pose["center_lat_deg"], e, n))
    return ring


class _DemExtent:
    """Which lon/lat points fall inside a DEM's raster (in its own CRS)."""

    def __init__(self, path):
        from osgeo import gdal, osr
        gdal.UseExceptions()
        try:
            ds = gdal.Open(path)
        except RuntimeError as e:
            if not os.path.exists(path) and not path.startswith("/vsi"):
                raise gissar.MissingFileError(f"DEM file does not exist ({path})") from None
            raise InputError(f"cannot open the DEM: {str(e).strip()} ({path})") from None
        self.size = (ds.RasterXSize, ds.RasterYSize)
        gt = ds.GetGeoTransform()
        self.inverse = gdal.InvGeoTransform(gt)
        srs = ds.GetSpatialRef()
        if srs is None:
            raise InputError(f"the DEM has no CRS ({path})")
        srs = srs.Clone()
        if srs.IsCompound():
            srs.StripVertical()
        srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
        wgs84 = osr.SpatialReference()
        wgs84.ImportFromEPSG(4326)
        wgs84.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
        self.to_dem = osr.CoordinateTransformation(wgs84, srs)
        self.geographic = bool(srs.IsGeographic())
        # Mean post spacing in metres at the DEM centre (the default pixel spacing of a corridor).
        if self.geographic:
            lat = gt[3] + gt[5] * ds.RasterYSize / 2
            m_per_deg = math.pi * 6371008.8 / 180.0
            self.post_spacing_m = 0.5 * (abs(gt[1]) * m_per_deg * math.cos(math.radians(lat))
                                         + abs(gt[5]) * m_per_deg)
        else:
            self.post_spacing_m = 0.5 * (abs(gt[1]) + abs(gt[5])) * srs.GetLinearUnits()
        self.kind = "DEM"
        if self.geographic:
            lat = gt[3] + gt[5] * ds.RasterYSize / 2
            m_per_deg = math.pi * 6371008.8 / 180.0
            self.extent_m = (abs(gt[1]) * ds.RasterXSize * m_per_deg * math.cos(math.radians(lat)),
                             abs(gt[5]) * ds.RasterYSize * m_per_deg)
        else:
            self.extent_m = (abs(gt[1]) * ds.RasterXSize * srs.GetLinearUnits(),
                             abs(gt[5]) * ds.RasterYSize * srs.GetLinearUnits())

    def outside(self, ring):
        """The first lon/lat point of ring outside the raster, or None."""
        for lon, lat in ring:
            x, y, *_ = self.to_dem.TransformPoint(lon, lat)
            col = self.inverse[0] + self.inverse[1] * x + self.inverse[2] * y
            row = self.inverse[3] + self.inverse[4] * x + self.inverse[5] * y
            if not (0.0 <= col <= self.size[0] and 0.0 <= row <= self.size[1]):
                return (lon, lat)
        return None


class _SceneExtent:
    """Which lon/lat points fall inside a scene's mesh (its ENU bounding box)."""

    def __init__(self, path):
        scene = gissar.load_scene(path)
        v = scene["vertices_enu_m"]
        self.lo = v[:, :2].min(axis=0)
        self.hi = v[:, :2].max(axis=0)
        self.origin = scene["origin_lonlat_deg"]
        self.post_spacing_m = None
        self.kind = "scene"
        self.extent_m = (float(self.hi[0] - self.lo[0]), float(self.hi[1] - self.lo[1]))

    def outside(self, ring):
        geod = _geod()
        lon0, lat0 = self.origin
        for lon, lat in ring:
            azimuth, _, distance = geod.inv(lon0, lat0, lon, lat)
            e = distance * math.sin(math.radians(azimuth))
            n = distance * math.cos(math.radians(azimuth))
            if not (self.lo[0] <= e <= self.hi[0] and self.lo[1] <= n <= self.hi[1]):
                return (lon, lat)
        return None


def _absolute(path):
    """A local file's absolute path (workers may run in another directory); GDAL names and URLs as given."""
    return path if path.startswith(("/vsi", "http://", "https://")) or ":" in path.split("/")[0] \
        else os.path.abspath(path)


def _wkt_polygon(ring):
    return "POLYGON ((" + ", ".join(f"{lon:.7f} {lat:.7f}" for lon, lat in ring) + "))"


def _ring_of_geometry(geometry):
    if geometry and geometry.get("type") == "Polygon" and geometry.get("coordinates"):
        return [tuple(p[:2]) for p in geometry["coordinates"][0]]
    return []


# ---------------------------------------------------------------- identity of inputs

def _file_identity(path, how):
    """path, size, mtime and (how == 'sha256') the SHA-256 of the file's bytes."""
    if path.startswith("/vsi") or not os.path.exists(path):
        return {"path": path}  # GDAL virtual paths: by name (simulate reports a missing file)
    st = os.stat(path)
    identity = {"path": os.path.abspath(path), "bytes": st.st_size}
    if how == "stat":
        identity["mtime_ns"] = st.st_mtime_ns
    else:
        digest = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
        identity["sha256"] = digest.hexdigest()
    return identity


def _pose_key(request, inputs, hash_inputs):
    """SHA-256 of what determines a pose's image: the request without file paths, the inputs' identity, the
    gissar version. With hash_inputs='sha256' the inputs are their contents (moving the files keeps the key);
    with 'stat' their absolute path, size and mtime."""
    record = {"gissar_version": gissar.__version__,
              "request": {k: v for k, v in request.items() if k not in _INPUT_FILES + ("max_memory_bytes",)},
              "inputs": {k: ({kk: vv for kk, vv in inputs[k].items() if hash_inputs == "stat" or kk != "path"})
                         for k in sorted(inputs)}}
    return hashlib.sha256(json.dumps(record, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


# ---------------------------------------------------------------- files

def _temporary_for(path):
    """The temporary _write_atomic writes path through: .gs-<name>-<16 hex>.tmp beside it, so that a run
    killed between writing and renaming leaves a name _sweep_temporaries can find."""
    directory, name = os.path.split(os.path.abspath(path))
    tag = uuid.uuid4().hex[:16]
    if len(name) + 26 > 255:  # no room for the name: an anonymous temporary
        return os.path.join(directory, f".gs-{tag}.tmp")
    return os.path.join(directory, f".gs-{name}-{tag}.tmp")


def _sweep_temporaries(path):
    """Removes the temporaries a killed writer of path left (see _temporary_for); only one task writes a
    pose's files at a time, so none of them is in use."""
    directory, name = os.path.split(os.path.abspath(path))
    for leftover in glob.glob(os.path.join(glob.escape(directory), f".gs-{glob.escape(name)}-" + "[0-9a-f]" * 16
                                           + ".tmp")):
        try:
            os.unlink(leftover)
        except OSError:
            pass


def _write_atomic(path, text):
    """Writes text to path through a temporary in the same directory and a rename."""
    tmp = _temporary_for(path)
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if e.errno in (errno.ENOSPC, errno.EDQUOT):
            # As the C++ writers say it (util/atomic_output.h WriteError): the final path, never the temporary.
            kind = {".json": "JSON output", ".csv": "CSV output"}.get(os.path.splitext(path)[1], "output")
            holder = os.path.dirname(os.path.abspath(path))
            raise IoError(f"failed writing {kind}: no space left on the device holding {holder} ({path})") from None
        raise IoError(f"cannot write: {e.strerror} ({path})") from None


#: The catalogue's own checksum: SHA-256 of its canonical JSON (sorted keys, no spaces) without this key.
CHECKSUM_KEY = "gissar:checksum_sha256"


def _catalogue_checksum(catalog):
    body = {k: v for k, v in catalog.items() if k != CHECKSUM_KEY}
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode("utf-8")).hexdigest()


def _write_catalogue(path, catalog):
    """Writes the catalogue with its checksum (atomically), so a re-run can tell an edited or truncated one."""
    catalog[CHECKSUM_KEY] = _catalogue_checksum(catalog)
    _write_atomic(path, json.dumps(catalog, indent=2) + "\n")


def catalogue_damage(path):
    """Why the catalogue at `path` is not as gissar wrote it ("truncated or not JSON: ...", "edited: ..."), or
    None when it is intact or absent. Catalogues written before the checksum existed count as intact."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except FileNotFoundError:
        return None
    except OSError as e:
        raise IoError(f"cannot read the catalogue: {e.strerror} ({path})") from None
    try:
        catalog = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as e:
        return f"truncated or not JSON ({e}; {len(raw)} bytes)"
    if not isinstance(catalog, dict):
        return "not a catalogue (its JSON is not an object)"
    stored = catalog.get(CHECKSUM_KEY)
    if stored is None:
        return None
    if stored != _catalogue_checksum(catalog):
        return "edited since gissar wrote it (its gissar:checksum_sha256 no longer matches its content)"
    return None


def _set_aside_damaged_catalogue(path):
    """A damaged catalogue is never overwritten silently: it is renamed to PATH.damaged-<UTC time> (returned,
    or None when the catalogue is intact or absent) and a GissarWarning says so; the run then rebuilds the
    catalogue from the per-pose records (done-markers, Items), which hold everything it lists."""
    damage = catalogue_damage(path)
    if damage is None:
        return None
    kept = stamp = f"{path}.damaged-{time.strftime('%Y%m%dT%H%M%SZ', time.gmtime())}"
    n = 1
    while os.path.lexists(kept):
        n += 1
        kept = f"{stamp}-{n}"
    try:
        os.replace(path, kept)
    except OSError as e:
        raise IoError(f"the catalogue is {damage}, and cannot be set aside: {e.strerror} ({path})") from None
    import warnings
    warnings.warn(f"the catalogue was {damage}: kept as {os.path.basename(kept)} and rebuilt from the per-pose "
                  f"records ({path})", gissar.GissarWarning, stacklevel=3)
    return kept


def _marker_path(prefix):
    return prefix + "_done.json"


def _read_marker(prefix):
    try:
        with open(_marker_path(prefix), encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def _marker_matches(prefix, key):
    marker = _read_marker(prefix)
    if not marker or marker.get("key") != key:
        return None
    directory = os.path.dirname(os.path.abspath(prefix))
    if not all(os.path.exists(os.path.join(directory, name)) for name in marker.get("files", [])):
        return None
    return marker


# ---------------------------------------------------------------- worker side

def limit_threads(threads):
    """Caps the simulations of this process at `threads` threads (gissar._core.set_threads: TBB's
    max_allowed_parallelism, as the command line's --threads). None or 0 leaves the default (all cores).
    Returns the active cap (0 when none was set)."""
    if not threads:
        return 0
    return int(gissar._core.set_threads(int(threads)))


def _cpu_seconds():
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _peak_rss_bytes():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux: kilobytes


def _simulate_pose(task):
    """One pose on a worker: simulate, join the Item to the collection, write the done-marker last. Returns a
    small dict (status, files, item, seconds, peak_rss_bytes, worker). A gissar error (bad input) is a failed
    pose, not a Dask error (no retry: it would fail again)."""
    start, cpu = time.perf_counter(), _cpu_seconds()
    limit_threads(task["threads"])
    prefix = task["out_prefix"]
    try:
        os.unlink(_marker_path(prefix))  # the marker exists only beside the outputs it describes
    except FileNotFoundError:
        pass
    # A worker killed while it wrote this pose's Item or marker left their temporaries (the simulation's own
    # are swept by gissar itself when it takes the prefix's lock).
    for path in (prefix + "_stac.json", _marker_path(prefix)):
        _sweep_temporaries(path)
    base = {"id": task["id"], "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        da = gissar.simulate(**task["request"], out_prefix=prefix, progress=None)
    except gissar.Error as e:
        return dict(base, status="failed", reason=f"{type(e).__name__}: {e}", seconds=time.perf_counter() - start,
                    cpu_seconds=_cpu_seconds() - cpu, peak_rss_bytes=_peak_rss_bytes())
    outputs = [os.fspath(p) for p in da.attrs.get("outputs", [])]
    del da
    stac_path = prefix + "_stac.json"
    with open(stac_path, encoding="utf-8") as f:
        item = json.load(f)
    item = _join_item(item, task)
    if task.get("geocode"):
        try:
            geocoded = _geocode_pose(prefix, item)
        except gissar.Error as e:
            _write_atomic(stac_path, json.dumps(item, indent=2) + "\n")
            return dict(base, status="failed", reason=f"geocode: {type(e).__name__}: {e}",
                        seconds=time.perf_counter() - start, cpu_seconds=_cpu_seconds() - cpu,
                        peak_rss_bytes=_peak_rss_bytes())
        outputs += geocoded
    _write_atomic(stac_path, json.dumps(item, indent=2) + "\n")
    files = [os.path.basename(p) for p in outputs]
    seconds = time.perf_counter() - start
    marker = {"id": task["id"], "key": task["key"], "gissar_version": gissar.__version__, "files": files,
              "seconds": seconds, "worker": base["worker"], "created_utc": _utc_now()}
    _write_atomic(_marker_path(prefix), json.dumps(marker, indent=2) + "\n")
    return dict(base, status="done", files=files + [os.path.basename(_marker_path(prefix))], item=item,
                seconds=seconds, cpu_seconds=_cpu_seconds() - cpu, peak_rss_bytes=_peak_rss_bytes())


#: Suffix of a pose's geocoded image (`gissar corridor --geocode`): PREFIX_<id>_geocoded.tif (+ .json, _stac.json).
GEOCODED_SUFFIX = "_geocoded"


def _geocode_pose(prefix, item):
    """`gissar geocode` of a pose's image (gissar.geocode, the library's exact back-geocoding onto the
    simulation's own terrain) to PREFIX_<id>_geocoded.tif; adds it to the pose's STAC Item as the asset
    ``geocoded``. Returns the files written."""
    out = prefix + GEOCODED_SUFFIX
    da = gissar.geocode(prefix + ".tif", out)
    outputs = [os.fspath(p) for p in da.attrs.get("outputs", [])]
    del da
    item.setdefault("assets", {})["geocoded"] = {
        "href": os.path.basename(out + ".tif"), "type": "image/tiff; application=geotiff",
        "title": "the image in map geometry (gissar geocode)", "roles": ["data"]}
    return outputs


def _geocode_cached_pose(task):
    """A pose found complete by a --geocode run whose geocoded image is missing: geocode it (no new
    simulation); the done-marker gains the geocoded files."""
    start, cpu = time.perf_counter(), _cpu_seconds()
    limit_threads(task["threads"])
    prefix = task["out_prefix"]
    base = {"id": task["id"], "worker": f"{socket.gethostname()}:{os.getpid()}"}
    stac_path = prefix + "_stac.json"
    with open(stac_path, encoding="utf-8") as f:
        item = json.load(f)
    try:
        geocoded = _geocode_pose(prefix, item)
    except gissar.Error as e:
        return dict(base, status="failed", reason=f"geocode: {type(e).__name__}: {e}",
                    seconds=time.perf_counter() - start, cpu_seconds=_cpu_seconds() - cpu,
                    peak_rss_bytes=_peak_rss_bytes())
    _write_atomic(stac_path, json.dumps(item, indent=2) + "\n")
    marker = dict(task["marker"])
    marker["files"] = [f for f in marker.get("files", []) if GEOCODED_SUFFIX + "." not in f
                       and not f.endswith(GEOCODED_SUFFIX + "_stac.json")]
    marker["files"] += [os.path.basename(p) for p in geocoded]
    _write_atomic(_marker_path(prefix), json.dumps(marker, indent=2) + "\n")
    return dict(base, status="done", cached=True,
                files=marker["files"] + [os.path.basename(_marker_path(prefix))], item=item,
                seconds=marker.get("seconds"), cpu_seconds=_cpu_seconds() - cpu, peak_rss_bytes=_peak_rss_bytes())


def _join_item(item, task):
    """The simulation's STAC Item as a member of the corridor collection, with the pose's properties."""
    pose = task["pose"]
    p = item.setdefault("properties", {})
    p.update({"gissar:pose_id": task["id"], "gissar:pose_index": pose["index"],
              "gissar:pose_lon_deg": pose["lon_deg"], "gissar:pose_lat_deg": pose["lat_deg"],
              "gissar:distance_m": pose["distance_m"], "gissar:track_deg": pose["track_deg"],
              "gissar:heading_deg": pose["heading_deg"], "gissar:depression_deg": task["depression_deg"],
              "gissar:slant_range_m": task["slant_range_m"], "gissar:ground_range_m": pose["ground_range_m"],
              "gissar:look_side": task["look_side"],
              "gissar:center_lonlat_deg": [pose["center_lon_deg"], pose["center_lat_deg"]],
              "gissar:options_sha256": task["key"]})
    item["collection"] = task["collection_id"]
    links = [link for link in item.get("links", []) if link.get("rel") not in ("collection", "parent", "root")]
    catalog = os.path.basename(task["catalog_path"])
    links += [{"rel": "collection", "href": catalog, "type": "application/json"},
              {"rel": "parent", "href": catalog, "type": "application/json"},
              {"rel": "root", "href": catalog, "type": "application/json"}]
    item["links"] = links
    return item


def _utc_now():
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


# ---------------------------------------------------------------- the run

def _simulate_keywords():
    return gissar._core.simulate_request_defaults()


def _check_keywords(keywords):
    defaults = _simulate_keywords()
    for name in keywords:
        if name in _PER_POSE:
            raise ConfigError(f"the corridor sets {name} for every pose ({name})")
        if name not in defaults:
            hint = gissar._core.unknown_key_message(name, [k for k in defaults if k not in _PER_POSE])
            suggestion = hint.partition("; ")[2]
            raise ConfigError(f"unknown keyword '{name}' (not a simulate request field)"
                              + (f"; {suggestion}" if suggestion else "") + f" ({name})")


def _progress_reporter(progress, total):
    if progress is True:
        from tqdm import tqdm
        bar = tqdm(total=total, desc="corridor", unit="pose", file=sys.stderr, leave=True)

        def report(done):
            bar.update(done - bar.n)
        report.close = bar.close
        return report
    if callable(progress):
        def call(done):
            progress("corridor", done, total)
        call.close = lambda: None
        return call
    if progress is None or progress is False:
        quiet = lambda done: None  # noqa: E731
        quiet.close = lambda: None
        return quiet
    raise ConfigError("progress must be True (a tqdm bar on stderr), a callable(stage, done, total) or None "
                      "(progress)")


def _dashboard_link(client):
    """The dashboard address when one is running (it needs bokeh), else None."""
    def has_bokeh():  # runs on the scheduler (pickled by value: gissar need not be installed there)
        import importlib.util
        return importlib.util.find_spec("bokeh") is not None

    try:
        info = client.scheduler_info()
        if "dashboard" not in info.get("services", {}) or not client.run_on_scheduler(has_bokeh):
            return None
        return client.dashboard_link
    except Exception:  # noqa: BLE001 (observability only)
        return None


def _start_client(client, scheduler, workers, threads_per_worker):
    """(client, cluster or None, owned): an existing client, a connection to `scheduler`, or an embedded
    LocalCluster of `workers` processes (default: one per core) on loopback."""
    if client is not None:
        if scheduler is not None or workers is not None:
            raise ConfigError("give client, or scheduler, or workers (client)")
        return client, None, False
    from distributed import Client, LocalCluster
    if scheduler is not None:
        if workers is not None:
            raise ConfigError("give scheduler or workers: a running cluster has its own workers (scheduler)")
        try:
            return Client(scheduler, timeout="20s"), None, True
        except (OSError, ValueError) as e:
            raise IoError(f"cannot connect to the Dask scheduler: {e} ({scheduler})") from None
    n = workers if workers is not None else (os.cpu_count() or 1)
    if not (isinstance(n, int) and n >= 1):
        raise ConfigError(f"must be a positive number of workers, got {workers!r} (workers)")
    if not (isinstance(threads_per_worker, int) and threads_per_worker >= 1):
        raise ConfigError(f"must be a positive integer, got {threads_per_worker!r} (threads_per_worker)")
    cluster = LocalCluster(n_workers=n, threads_per_worker=threads_per_worker, processes=True,
                           host="127.0.0.1", dashboard_address=":0")
    client = Client(cluster)
    try:
        client.wait_for_workers(n, timeout=120)
    except Exception:  # noqa: BLE001 (closed below, then re-raised)
        client.close()
        cluster.close()
        raise
    return client, cluster, True


def _scheduler_lost(client, error, wait_s=5.0):
    """True when `error`, raised by a future's result(), means the client lost its scheduler (it died or the
    network went): the client then cancels every future, or the result's transfer fails on a closed comm. For
    those two errors a few seconds are given for the client to notice the closed connection itself; any other
    error (the task's own, gissar's included) is checked at once."""
    from concurrent.futures import CancelledError
    from distributed.comm.core import CommClosedError
    wait = isinstance(error, (CancelledError, CommClosedError)) and not isinstance(error, gissar.Error)
    deadline = time.monotonic() + (wait_s if wait else 0.0)
    while True:
        comm = getattr(client, "scheduler_comm", None)
        if client.status != "running" or comm is None or comm.comm is None or comm.comm.closed():
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.1)


def _release_client(client, cluster, owned, lost):
    """Closes a client (and its cluster) this call started (`owned`); quietly when its scheduler was `lost`. A
    caller's own client is left as it is."""
    if not owned:
        return
    if lost:
        _close_quietly(client, cluster)
        return
    client.close()
    if cluster is not None:
        cluster.close()


def _close_quietly(client, cluster):
    """Closes a client whose scheduler is gone: the client's own reconnection attempts are cancelled, which
    Dask logs as tracebacks; they are not the user's concern (the error raised says what happened)."""
    import logging
    names = [name for name in logging.root.manager.loggerDict
             if name.split(".")[0] in ("distributed", "asyncio", "tornado")]
    loggers = [logging.getLogger(name) for name in sorted(set(names) | {"distributed", "asyncio", "tornado"})]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL + 1)
    try:
        client.close(timeout=5)
        if cluster is not None:
            cluster.close(timeout=5)
    except Exception:  # noqa: BLE001 (the scheduler is gone; closing is best effort)
        pass
    finally:
        for logger, level in zip(loggers, levels):
            logger.setLevel(level)


def _worker_memory_limits(client):
    """The distinct memory limits (bytes, 0 = none) of the cluster's workers, from the scheduler."""
    try:
        workers = client.scheduler_info().get("workers", {}).values()
        return sorted({int(w.get("memory_limit") or 0) for w in workers})
    except Exception:  # noqa: BLE001 (only used to explain a failure)
        return []


def _failure_reason(error, memory_limits, what="simulated this pose"):
    """A failed task's reason: the worker's error, or, when every worker that ran it died, what kills workers."""
    from distributed import KilledWorker
    if isinstance(error, KilledWorker):
        attempts = getattr(error, "allowed_failures", None)
        limits = [limit for limit in memory_limits if limit > 0]
        limit_text = (" of " + " / ".join(f"{limit / 2 ** 20:.0f} MiB" for limit in limits) + " per worker"
                      if limits else "")
        return (f"KilledWorker: the worker process died each time it {what}"
                f"{f' ({attempts + 1} attempts)' if isinstance(attempts, int) else ''}: killed by its nanny at the "
                f"worker memory limit{limit_text}, or crashed (the workers' logs say which); give the workers more "
                f"memory or simulate smaller images")
    return f"{type(error).__name__}: {error}"


#: The image side a corridor chooses when it is given no size (auto_image_size): at most, and at least.
AUTO_SIZE_MAX_PX = 512
AUTO_SIZE_MIN_PX = 64


def _centre_outside(extent, pose):
    return extent.outside([(pose["center_lon_deg"], pose["center_lat_deg"])]) is not None


def auto_image_size(poses, extent, range_spacing_m, azimuth_spacing_m, depression_deg, look_side,
                    largest=AUTO_SIZE_MAX_PX, smallest=AUTO_SIZE_MIN_PX):
    """The square image side (pixels) of a corridor given no --width/--height: the largest side in
    [smallest, largest] whose predicted footprint (predicted_footprint) fits the terrain at every pose whose scene
    centre lies on it. Poses whose footprint cannot fit even `smallest` pixels, and poses whose centre lies off
    the terrain, are skipped by the corridor and do not constrain the size. The footprint grows with the side
    around a fixed centre, so each pose's largest fitting side is found by bisection."""
    def fits(pose, side):
        ring = predicted_footprint(pose, side, side, range_spacing_m, azimuth_spacing_m, depression_deg, look_side)
        return extent.outside(ring) is None

    side = largest
    for pose in poses:
        if _centre_outside(extent, pose) or fits(pose, side) or not fits(pose, smallest):
            continue
        lo, hi = smallest, side  # fits(lo), not fits(hi)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if fits(pose, mid):
                lo = mid
            else:
                hi = mid
        side = lo
    return side


def _skip_reasons(records, extent, *, width, height, range_spacing_m, azimuth_spacing_m, depression_deg,
                  slant_range_m, look_side, auto_size):
    """One line per kind of skip (scene centre off the terrain; footprint leaving it): how many poses, the
    footprint and terrain sizes, and the flags that would fix it."""
    skipped = [r for r in records if r["status"] == "skipped"]
    lines = []
    terrain = f"{extent.kind} ({extent.extent_m[0] / 1000:.1f} x {extent.extent_m[1] / 1000:.1f} km)"
    centre = [r for r in skipped if r.get("skip_kind") == "centre"]
    if centre:
        ground_km = slant_range_m * math.cos(math.radians(depression_deg)) / 1000.0
        lines.append(f"{len(centre)} of {len(records)} poses skipped: their scene centre, {ground_km:.1f} km to the "
                     f"{look_side} of the route (--slant-range {slant_range_m:g} m at --depression "
                     f"{depression_deg:g} deg, --look {look_side}), lies outside the {terrain}; give a --route "
                     f"over the {extent.kind}, or change --slant-range/--depression/--look")
    footprint = [r for r in skipped if r.get("skip_kind") == "footprint"]
    if footprint:
        across = width * range_spacing_m / math.cos(math.radians(depression_deg)) / 1000.0
        along = height * azimuth_spacing_m / 1000.0
        fix = (f"even at the smallest automatic size ({AUTO_SIZE_MIN_PX} px); give finer "
               "--range-spacing/--azimuth-spacing or move the --route away from the edge" if auto_size else
               "give a smaller --width/--height (or leave both out: the corridor then chooses a size that fits) "
               "or finer --range-spacing/--azimuth-spacing")
        lines.append(f"{len(footprint)} of {len(records)} poses skipped: their {width} x {height} px footprint "
                     f"({across:.1f} km across x {along:.1f} km along at {range_spacing_m:g} m x "
                     f"{azimuth_spacing_m:g} m spacing) leaves the {terrain}; {fix}")
    return lines


def build_corridor(route, *, pose_step_m, headings_deg, out_prefix, dem=None, scene=None, width=None, height=None,
                   client=None, scheduler=None, workers=None, threads_per_worker=1, threads=None, retries=2,
                   hash_inputs="sha256", progress=True, log=None, report_summary=True, geocode=False,
                   **simulate_keywords):
    """Builds (or completes) a reference-image database along a route: ``gissar corridor`` in Python.

    route: GeoJSON/CSV path or [(lon, lat), ...] (see read_route); pose_step_m: spacing of the poses along the
    route (metres on the WGS84 ellipsoid); headings_deg: the headings simulated at every pose; out_prefix: every
    file starts with it (PREFIX_<id>.*, PREFIX_catalog.json, PREFIX_index.csv). dem (a path every worker can
    read, GDAL names included) or scene (a .gscene path or gissar.Scene). width, height: the fixed image size in
    pixels; when neither is given, the largest square side up to 512 px whose footprint fits the terrain at every
    pose (auto_image_size; recorded in the catalogue's ``gissar:image_size``); when one is given, the other
    defaults to 512. Other keywords: gissar.simulate's (depression_deg, slant_range_m, range_spacing_m, azimuth_spacing_m,
    look_side, rays_per_cell, seed, ...; not center_lonlat/heading_deg, which the corridor sets per pose). The
    pixel spacings default to the DEM's mean post spacing at its centre (one spacing for every pose).

    Cluster: client (an existing distributed.Client), or scheduler ("tcp://host:8786"), or an embedded
    LocalCluster of `workers` processes (default one per core) with threads_per_worker task threads each.
    threads: threads of each simulation (as --threads; default: cores // workers for the embedded cluster, all
    cores of a worker otherwise). retries: Dask retries of a task whose worker died. hash_inputs: 'sha256'
    (the inputs' contents, default) or 'stat' (path, size, mtime: for inputs too large to read once per run).
    progress: True (a tqdm bar on stderr), a callable(stage, done, total) or None; log: callable(str) for the
    information lines (dashboard address, summary) or None. geocode: also write each done pose's image in map
    geometry, PREFIX_<id>_geocoded.tif (gissar.geocode on the pose's own terrain; named by the pose's
    ``geocoded`` key in the catalogue and its Item's ``geocoded`` asset); a re-run with geocode=True geocodes
    the poses already complete that have none, without simulating them again.

    Returns the catalogue (the STAC Collection written to PREFIX_catalog.json, a dict); its
    ``gissar:summary`` counts the poses done (simulated now or found complete), skipped (footprint outside the
    terrain) and failed."""
    started = time.perf_counter()
    say = log if callable(log) else (lambda text: None)
    if (dem is None) == (scene is None):
        raise ConfigError("give dem or scene, not both and not neither (dem/scene)")
    if out_prefix is None or os.fspath(out_prefix) == "":
        raise ConfigError("is required (out_prefix)")
    out_prefix = os.path.abspath(os.fspath(out_prefix))  # workers may run elsewhere, in another directory
    if hash_inputs not in _HASH_INPUTS:
        raise ConfigError(f"must be sha256 or stat, got {hash_inputs!r} (hash_inputs)")
    if not (isinstance(retries, int) and retries >= 0):
        raise ConfigError(f"must be a non-negative integer, got {retries!r} (retries)")
    auto_size = width is None and height is None
    for name, value in (("width", width), ("height", height)):
        if value is None:
            continue
        if not (isinstance(value, int) and value >= 1):
            raise ConfigError(f"must be a positive number of pixels, got {value!r} ({name})")
    if threads is not None and not (isinstance(threads, int) and threads >= 0):
        raise ConfigError(f"must be a non-negative integer, got {threads!r} (threads)")
    _check_keywords(simulate_keywords)
    defaults = _simulate_keywords()
    kw = dict(simulate_keywords)
    if scene is not None:
        scene = scene.path if isinstance(scene, gissar.Scene) else os.fspath(scene)
        terrain = {"scene": _absolute(scene)}
    else:
        if not isinstance(dem, (str, os.PathLike)):
            raise ConfigError("a corridor's DEM is a path (or GDAL name) every worker can open (dem)")
        terrain = {"dem": _absolute(os.fspath(dem))}
    for name in ("materials", "reflectors"):
        if kw.get(name):
            kw[name] = _absolute(os.fspath(kw[name]))
    depression_deg = float(kw.get("depression_deg", defaults["depression_deg"]))
    slant_range_m = float(kw.get("slant_range_m", defaults["slant_range_m"]))
    look_side = kw.get("look_side", defaults["look_side"])
    poses = corridor_poses(route, pose_step_m=pose_step_m, headings_deg=headings_deg, slant_range_m=slant_range_m,
                           depression_deg=depression_deg, look_side=look_side)
    extent = _DemExtent(terrain["dem"]) if "dem" in terrain else _SceneExtent(terrain["scene"])
    for name in ("range_spacing_m", "azimuth_spacing_m"):
        if not kw.get(name):
            if extent.post_spacing_m is None:
                raise ConfigError(f"give the pixel spacings of a scene corridor ({name})")
            kw[name] = round(extent.post_spacing_m, 3)
    if auto_size:
        width = height = auto_image_size(poses, extent, kw["range_spacing_m"], kw["azimuth_spacing_m"],
                                         depression_deg, look_side)
        size_rule = (f"auto: the largest square side up to {AUTO_SIZE_MAX_PX} px whose footprint fits the "
                     f"{extent.kind} at every pose (at least {AUTO_SIZE_MIN_PX} px)")
    else:
        width = AUTO_SIZE_MAX_PX if width is None else width
        height = AUTO_SIZE_MAX_PX if height is None else height
        size_rule = "given"
    inputs = {name: _file_identity(os.fspath(value), hash_inputs)
              for name, value in list(terrain.items()) + [(k, kw[k]) for k in ("materials", "reflectors")
                                                             if kw.get(k)]}
    collection_id = os.path.basename(out_prefix) or "corridor"
    catalog_path = out_prefix + "_catalog.json"
    index_path = out_prefix + "_index.csv"
    directory = os.path.dirname(os.path.abspath(out_prefix))
    if not os.path.isdir(directory):
        raise IoError(f"the output directory does not exist ({directory})")
    # One writer per database: a second run on this prefix is refused at once (IoError naming the prefix).
    with gissar._core._PrefixLock(out_prefix):
        _set_aside_damaged_catalogue(catalog_path)
        records, tasks = [], []
        for pose in poses:
            record = {"pose": pose, "id": pose["id"], "status": None, "reason": "", "files": [], "item": None,
                      "ring": predicted_footprint(pose, width, height, kw["range_spacing_m"], kw["azimuth_spacing_m"],
                                                  depression_deg, look_side)}
            records.append(record)
            where = extent.outside(record["ring"])
            if where is not None:
                if _centre_outside(extent, pose):
                    record.update(status="skipped", skip_kind="centre",
                                  reason="scene centre outside the %s at lon %.5f, lat %.5f"
                                  % (extent.kind, pose["center_lon_deg"], pose["center_lat_deg"]))
                else:
                    record.update(status="skipped", skip_kind="footprint",
                                  reason="footprint leaves the %s at lon %.5f, lat %.5f"
                                  % (extent.kind, where[0], where[1]))
                continue
            request = dict(kw, **terrain, center_lonlat=[pose["center_lon_deg"], pose["center_lat_deg"]],
                           heading_deg=pose["heading_deg"], depression_deg=depression_deg, width=width, height=height)
            prefix = f"{out_prefix}_{pose['id']}"
            key = _pose_key(dict(request, pose_id=pose["id"]), inputs, hash_inputs)
            marker = _marker_matches(prefix, key)
            task = {"id": pose["id"], "pose": pose, "request": request, "out_prefix": prefix,
                    "key": key, "threads": threads, "depression_deg": depression_deg,
                    "slant_range_m": slant_range_m, "look_side": look_side,
                    "collection_id": collection_id, "catalog_path": catalog_path, "geocode": bool(geocode)}
            if marker is not None and geocode and not (
                    os.path.basename(prefix + GEOCODED_SUFFIX + ".tif") in marker.get("files", [])
                    and os.path.isfile(prefix + GEOCODED_SUFFIX + ".tif")):
                record.update(status="done", cached=True)
                tasks.append((record, dict(task, marker=marker, geocode_only=True)))
                continue
            if marker is not None:
                record.update(status="done", cached=True, seconds=marker.get("seconds"),
                              files=marker["files"] + [os.path.basename(_marker_path(prefix))])
                try:
                    with open(prefix + "_stac.json", encoding="utf-8") as f:
                        record["item"] = json.load(f)
                except (OSError, ValueError):
                    record["item"] = None
                continue
            tasks.append((record, task))

        worker_count = 0
        peak_rss = 0
        cpu_seconds = task_seconds = 0.0
        lost_scheduler = None
        if tasks:
            from distributed import as_completed
            client, cluster, owned = _start_client(client, scheduler, workers, threads_per_worker)
            address = client.scheduler.address
            try:
                worker_count = len(client.scheduler_info().get("workers", {}))
                memory_limits = _worker_memory_limits(client)
                if threads is None and cluster is not None:
                    cores = os.cpu_count() or 1
                    for _, task in tasks:
                        task["threads"] = max(1, cores // max(1, worker_count))
                link = _dashboard_link(client)
                if link:
                    say(f"corridor: Dask dashboard at {link}")
                say(f"corridor: {len(tasks)} poses to simulate on {worker_count} workers ({address})")
                futures = {}
                for record, task in tasks:
                    function = _geocode_cached_pose if task.get("geocode_only") else _simulate_pose
                    future = client.submit(function, task, key=f"gissar-pose-{task['id']}-{uuid.uuid4().hex[:8]}",
                                           retries=retries, pure=False)
                    futures[future] = (record, task)
                report = _progress_reporter(progress, len(futures))
                done = 0
                unfinished = dict(futures)
                try:
                    for future in as_completed(futures):
                        record, _ = futures[future]
                        try:
                            result = future.result()
                        except Exception as e:  # noqa: BLE001 (the worker's error, after the retries)
                            if _scheduler_lost(client, e):
                                lost_scheduler = type(e).__name__
                                break
                            result = {"status": "failed", "reason": _failure_reason(e, memory_limits)}
                        del unfinished[future]
                        record.update(status=result["status"], reason=result.get("reason", ""),
                                      files=result.get("files", []), item=result.get("item"),
                                      seconds=result.get("seconds"), worker=result.get("worker"),
                                      cached=bool(result.get("cached")))
                        peak_rss = max(peak_rss, int(result.get("peak_rss_bytes") or 0))
                        cpu_seconds += float(result.get("cpu_seconds") or 0.0)
                        task_seconds += float(result.get("seconds") or 0.0)
                        done += 1
                        report(done)
                finally:
                    report.close()
                    # Only what is still pending (an interrupted run): cancelling finished futures sends the
                    # scheduler a message each, which can still be in flight when the client closes (a
                    # "Future exception was never retrieved: TimeoutError" on stderr under load).
                    if lost_scheduler is None:
                        for future in futures:
                            if not future.done():
                                future.cancel()
                if lost_scheduler is not None:
                    # The poses whose results never arrived: those that finished before the scheduler went have
                    # their done-marker (written last, on the worker); the others were not run.
                    for record, task in unfinished.values():
                        marker = _marker_matches(task["out_prefix"], task["key"])
                        if marker is not None:
                            record.update(status="done", cached=False, reason="",
                                          files=marker["files"] + [os.path.basename(_marker_path(task["out_prefix"]))])
                            try:
                                with open(task["out_prefix"] + "_stac.json", encoding="utf-8") as f:
                                    record["item"] = json.load(f)
                            except (OSError, ValueError):
                                record["item"] = None
                        else:
                            record.update(status="failed", files=[],
                                          reason=f"not run: the Dask scheduler at {address} was lost mid-run")
            finally:
                _release_client(client, cluster, owned, lost_scheduler is not None)

        wall_seconds = time.perf_counter() - started
        catalog = _catalogue(records, collection_id=collection_id, catalog_path=catalog_path, route=route,
                             pose_step_m=pose_step_m, headings_deg=headings_deg, width=width, height=height,
                             keywords=kw, terrain=terrain, inputs=inputs, hash_inputs=hash_inputs,
                             wall_seconds=wall_seconds, workers=worker_count, peak_rss=peak_rss,
                             simulated=len(tasks), index_path=index_path, cpu_seconds=cpu_seconds,
                             task_seconds=task_seconds, size_rule=size_rule,
                             skip_reasons=_skip_reasons(records, extent, width=width, height=height,
                                                        range_spacing_m=kw["range_spacing_m"],
                                                        azimuth_spacing_m=kw["azimuth_spacing_m"],
                                                        depression_deg=depression_deg, slant_range_m=slant_range_m,
                                                        look_side=look_side, auto_size=auto_size))
        failures = [r for r in records if r["status"] == "failed"]
        bad_input = ("ConfigError", "InputError", "MissingFileError")
        if failures and len(failures) == len(tasks) and all(r["reason"].startswith(bad_input) for r in failures):
            # Every simulation refused its input: a bad request, reported like gissar.simulate's (nothing written).
            kind, _, message = failures[0]["reason"].partition(": ")
            raise {"ConfigError": ConfigError, "InputError": InputError,
                   "MissingFileError": gissar.MissingFileError}[kind](message)
        _write_atomic(index_path, _index_csv(records))
        _write_catalogue(catalog_path, catalog)
        if lost_scheduler is not None:
            s = catalog["gissar:summary"]
            not_run = sum(1 for r in records if r["reason"].startswith("not run:"))
            raise IoError(f"lost the Dask scheduler mid-run ({lost_scheduler}): {s['done']} of {s['poses']} poses are "
                          f"done and kept, {not_run} were not run; run the same command again (with a running "
                          f"scheduler) to resume ({address})")
        if report_summary:
            say(summary_line(catalog))
            for line in catalog["gissar:summary"]["skip_reasons"]:
                say("corridor: " + line)
        return catalog


def summary_line(catalog):
    """The one-line result of a corridor run (what ``gissar corridor`` prints on stdout)."""
    s = catalog["gissar:summary"]
    return (f"corridor: {s['poses']} poses: {s['done']} done ({s['cached']} already complete), {s['skipped']} "
            f"skipped, {s['failed']} failed in {s['wall_seconds']:.1f} s on {s['workers']} workers; "
            f"{catalog['gissar:width']} x {catalog['gissar:height']} px")


def _index_csv(records):
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["id", "lon", "lat", "heading_deg", "status", "footprint_wkt", "files", "reason"])
    for r in records:
        pose = r["pose"]
        ring = _ring_of_geometry((r.get("item") or {}).get("geometry")) or r["ring"]
        w.writerow([r["id"], f"{pose['lon_deg']:.7f}", f"{pose['lat_deg']:.7f}", f"{pose['heading_deg']:g}",
                    r["status"], _wkt_polygon(ring), " ".join(r["files"]), r["reason"]])
    return out.getvalue()


def _catalogue(records, *, collection_id, catalog_path, route, pose_step_m, headings_deg, width, height, keywords,
               terrain, inputs, hash_inputs, wall_seconds, workers, peak_rss, simulated, index_path, cpu_seconds,
               task_seconds, size_rule, skip_reasons):
    """The STAC Collection: links to every simulated pose's Item, every pose with its status, the summary."""
    done = [r for r in records if r["status"] == "done"]
    lons, lats, times = [], [], []
    for r in done:
        item = r.get("item") or {}
        bbox = item.get("bbox")
        if bbox and len(bbox) >= 4:
            lons += [bbox[0], bbox[2]]
            lats += [bbox[1], bbox[3]]
        if item.get("properties", {}).get("datetime"):
            times.append(item["properties"]["datetime"])
    if not lons:  # nothing simulated: the route's predicted footprints
        for r in records:
            lons += [p[0] for p in r["ring"]]
            lats += [p[1] for p in r["ring"]]
    now = _utc_now()
    times = sorted(times) or [now]
    links = [{"rel": "self", "href": os.path.basename(catalog_path), "type": "application/json"},
             {"rel": "root", "href": os.path.basename(catalog_path), "type": "application/json"},
             {"rel": "alternate", "href": os.path.basename(index_path), "type": "text/csv",
              "title": "index of the poses (CSV)"}]
    links += [{"rel": "item", "href": f"{collection_id}_{r['id']}_stac.json", "type": "application/geo+json",
               "title": r["id"]} for r in done]
    poses = []
    for r in records:
        p = r["pose"]
        entry = {"id": r["id"], "status": r["status"], "lon_deg": p["lon_deg"], "lat_deg": p["lat_deg"],
                 "heading_deg": p["heading_deg"], "distance_m": p["distance_m"],
                 "center_lonlat_deg": [p["center_lon_deg"], p["center_lat_deg"]], "files": r["files"]}
        if r["reason"]:
            entry["reason"] = r["reason"]
        if r["status"] == "done":
            entry["cached"] = bool(r.get("cached"))
            geocoded = f"{collection_id}_{r['id']}{GEOCODED_SUFFIX}.tif"
            if geocoded in r["files"]:
                entry["geocoded"] = geocoded
        poses.append(entry)
    summary = {"poses": len(records), "done": len(done), "cached": sum(1 for r in done if r.get("cached")),
               "simulated": sum(1 for r in done if not r.get("cached")),
               "skipped": sum(1 for r in records if r["status"] == "skipped"),
               "failed": sum(1 for r in records if r["status"] == "failed"),
               "wall_seconds": wall_seconds, "workers": workers, "tasks_submitted": simulated,
               "task_seconds": task_seconds, "task_cpu_seconds": cpu_seconds,
               "peak_worker_rss_bytes": peak_rss or None, "finished_utc": now, "skip_reasons": skip_reasons}
    # No result (exit 3 of `gissar corridor`, docs/conventions.md): every pose skipped.
    no_result = bool(records) and summary["skipped"] == len(records)
    summary["converged"] = not no_result
    summary["reason"] = "; ".join(skip_reasons) if no_result else None
    # What a pose fix from this database needs (`gissar locate --database`, docs/distributed.md "Reference
    # database keys"): the terrain's content hash and, per done pose, its stored image and affine camera.
    directory = os.path.dirname(os.path.abspath(catalog_path))
    for entry in poses:
        if entry["status"] == "done":
            reference = _reference_entry(directory, collection_id, entry["id"])
            if reference is not None:
                entry["reference"] = reference
    database = _database_entry(terrain, inputs, keywords, width, height)
    route_text = os.fspath(route) if isinstance(route, (str, os.PathLike)) else "(python)"
    return {
        "type": "Collection", "stac_version": STAC_VERSION, "stac_extensions": [], "id": collection_id,
        "title": f"gissar corridor {collection_id}",
        "description": (f"Simulated SAR reference images along {route_text}: a pose every {pose_step_m:g} m, "
                        f"headings {', '.join(f'{h:g}' for h in _headings(headings_deg))} deg, "
                        f"{width} x {height} px."),
        "license": "proprietary",
        "extent": {"spatial": {"bbox": [[min(lons), min(lats), max(lons), max(lats)]]},
                   "temporal": {"interval": [[times[0], times[-1]]]}},
        "links": links,
        "gissar:version": gissar.__version__,
        "gissar:route": route_text, "gissar:pose_step_m": pose_step_m,
        "gissar:headings_deg": _headings(headings_deg), "gissar:width": width, "gissar:height": height,
        "gissar:image_size": {"width": width, "height": height, "rule": size_rule},
        "gissar:options": dict(keywords, **{k: os.fspath(v) for k, v in terrain.items()}),
        "gissar:inputs": inputs, "gissar:hash_inputs": hash_inputs, "gissar:database": database,
        "gissar:summary": summary, "gissar:poses": poses,
    }


#: Version of the catalogue's reference-database record (gissar:database and the poses' reference entries).
DATABASE_FORMAT = 1


def _content_sha256(identity):
    """The SHA-256 of an input's bytes: from its identity when hashed already (hash_inputs='sha256'), else
    read now (a 'stat' run still records the terrain's content hash: locate --database checks it); None for a
    GDAL virtual path or a missing file."""
    if identity.get("sha256"):
        return identity["sha256"]
    path = identity.get("path", "")
    if path.startswith("/vsi") or not os.path.isfile(path):
        return None
    return _file_identity(path, "sha256")["sha256"]


def _database_entry(terrain, inputs, keywords, width, height):
    """gissar:database: the terrain (dem or scene) and the content hashes every stored reference was built from,
    and the sensor shared by the poses."""
    kind = "scene" if "scene" in terrain else "dem"
    return {"format": DATABASE_FORMAT, "terrain": kind,
            "terrain_sha256": _content_sha256(inputs[kind]),
            "materials_sha256": _content_sha256(inputs["materials"]) if "materials" in inputs else None,
            "reflectors_sha256": _content_sha256(inputs["reflectors"]) if "reflectors" in inputs else None,
            "vertical_datum": keywords.get("vertical_datum") or "",
            "projection_mode": keywords.get("mode") or "affine",
            "look_side": keywords.get("look_side") or "right",
            "width": width, "height": height,
            "range_spacing_m": keywords.get("range_spacing_m"), "azimuth_spacing_m": keywords.get("azimuth_spacing_m")}


def _geodetic_of_enu(origin, enu):
    """(lon, lat, h) of a point of the ENU tangent frame at origin (lon, lat, h), WGS84 (PROJ's topocentric
    conversion, inverted)."""
    from pyproj import Transformer
    from pyproj.enums import TransformDirection
    to_enu = Transformer.from_pipeline(
        "+proj=pipeline +step +proj=cart +ellps=WGS84 "
        f"+step +proj=topocentric +ellps=WGS84 +lon_0={origin[0]!r} +lat_0={origin[1]!r} +h_0={origin[2]!r}")
    lon, lat, h = to_enu.transform(enu[0], enu[1], enu[2], direction=TransformDirection.INVERSE)
    return (lon, lat, h)


def _reference_entry(directory, collection_id, pose_id):
    """A done pose's stored reference: its files (relative to the catalogue), the pose (sensor position,
    heading, depression, slant range, look side) and the affine camera of the image (in the ENU tangent frame of
    the simulation, origin frame_origin_lon_lat_h), from the simulation's sidecar. None when the sidecar cannot
    be read (the pose is then not usable as a reference)."""
    stem = f"{collection_id}_{pose_id}"
    try:
        with open(os.path.join(directory, stem + ".json"), encoding="utf-8") as f:
            sidecar = json.load(f)
        g, frame, centre = sidecar["geometry"], sidecar["frame"], sidecar["scene_centre"]
        options = sidecar.get("options", {})
        origin = (float(frame["origin_lon_deg"]), float(frame["origin_lat_deg"]), float(frame["origin_height_m"]))
        sensor = _geodetic_of_enu(origin, g["sensor_enu_m_at_centre"])
        mask = stem + "_mask.tif"
        return {"image": stem + ".tif", "band": 1, "mask": mask if os.path.exists(os.path.join(directory, mask))
                else None, "sidecar": stem + ".json",
                "heading_deg": float(options["heading_deg"]), "depression_deg": float(options["depression_deg"]),
                "slant_range_m": float(options["slant_range_m"]), "look_side": options.get("look_side", "right"),
                "projection_mode": options.get("mode") or "affine",
                "radiometry": options.get("radiometry", "sigma0"), "db": bool(options.get("db", False)),
                "sensor_lon_lat_h": list(sensor),
                "centre_lon_lat_h": [float(centre["lon_deg"]), float(centre["lat_deg"]), float(centre["height_m"])],
                "frame_origin_lon_lat_h": list(origin),
                "centre_enu_m": list(map(float, centre["enu_m"])),
                "sensor_enu_m": list(map(float, g["sensor_enu_m_at_centre"])),
                "look_direction_enu": list(map(float, g["look_direction_enu"])),
                "flight_direction_enu": list(map(float, g["flight_direction_enu"])),
                "u0": float(g["u0"]), "v0": float(g["v0"]), "width": int(g["width"]), "height": int(g["height"]),
                "range_spacing_m": float(g["range_spacing_m"]), "azimuth_spacing_m": float(g["azimuth_spacing_m"])}
    except (OSError, ValueError, KeyError, TypeError):
        return None
