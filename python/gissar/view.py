"""`gissar view PATH [--port N] [--host ADDR] [--no-browser]`: a corridor, a simulation or a pose fix on a map.

The C++ command line runs this module for `gissar view ARGS` (python3 -m gissar.view, as `gissar corridor`;
docs/view.md). PATH is a corridor catalogue (PREFIX_catalog.json), a `simulate`/`geocode` output (its prefix,
image or sidecar), a `locate`/`evaluate` result JSON, or a directory holding one of these. A local web server
(Python's http.server, one thread per connection) serves the bundled page (web/, OpenLayers) and, read-only,
exactly the files the catalogue or result names under PATH's directory, plus images it renders itself with
GDAL (the DEM's hillshade and each image warped to WGS84, cached).

Security: binds 127.0.0.1 unless --host says otherwise (a warning when it is not a loopback address); GET and
HEAD only (405 otherwise); no directory listing; a request names a file of the allow-list or nothing (`..`,
percent-encoded separators and symlinks leading out of the directory are refused); Host header checked against
the bound address on loopback (DNS rebinding); request line <= 8 KiB, headers <= 16 KiB and <= 64 lines;
10 s socket timeout. Exit statuses: 0 after Ctrl-C; 2 bad input or usage (one `gissar: error:` line, nothing
written), e.g. a PATH of no known kind or a port in use; 128 + N after SIGTERM/SIGHUP.
"""
import os as _os
import sys as _sys

if __name__ == "__main__" and not __package__ and _sys.path and (
        _os.path.abspath(_sys.path[0] or ".") == _os.path.dirname(_os.path.abspath(__file__))):
    # Run as a file (`gissar view` execs gissar/view.py): its directory is the package's, not one of modules.
    del _sys.path[0]

import argparse
import errno
import hashlib
import http.server
import io
import ipaddress
import json
import math
import mimetypes
import os
import re
import signal
import socket
import sys
import tempfile
import threading
import urllib.parse

#: Column of the flag names in --help (CLI11's, as in every other gissar command).
_HELP_COLUMN = 30
MAX_REQUEST_LINE = 8192
MAX_HEADER_BYTES = 16384
MAX_HEADER_LINES = 64
SOCKET_TIMEOUT_S = 10.0
#: Largest side of a rendered PNG (hillshade, warped images).
MAX_RENDER_PX = 2048
STATUS_COLOURS = {"done": "#2e9d3a", "cached": "#1f6fd1", "skipped": "#9a9a9a", "failed": "#d12f1f",
                  "missing": "#f0a000"}


class Usage(Exception):
    """A command-line error: one `gissar: error: ... (command line)` line, exit 2."""


class BadInput(Exception):
    """A PATH gissar view cannot show: one `gissar: error: ...` line, exit 2."""


class _Signal(Exception):
    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


# --------------------------------------------------------------------------------------------------------------
# What PATH is

def _read_json(path):
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None


def _kind_of_json(doc):
    if not isinstance(doc, dict):
        return None
    if doc.get("type") == "Collection" and isinstance(doc.get("gissar:poses"), list):
        return "corridor"
    command = doc.get("command")
    if command in ("simulate", "geocode", "locate", "evaluate"):
        return command
    return None


def _sidecar_of(path):
    """The sidecar JSON of a simulate/geocode output given as its prefix, image or sidecar; None otherwise."""
    candidates = [path + ".json"]
    for suffix in (".json", ".tif", ".png", "_mask.tif", "_quicklook.png", "_stac.json"):
        if path.endswith(suffix):
            candidates.append(path[: -len(suffix)] + ".json")
    for c in candidates:
        if os.path.isfile(c):
            doc = _read_json(c)
            if _kind_of_json(doc) in ("simulate", "geocode", "locate", "evaluate"):
                return c, doc
    return None


def resolve(path):
    """(kind, json_path, document) of PATH; raises BadInput when PATH is no known kind."""
    if os.path.isdir(path):
        entries = sorted(os.listdir(path))
        found = []
        for order, pattern in enumerate(("_catalog.json", ".json")):
            for name in entries:
                if not name.endswith(pattern) or name.endswith("_stac.json") or name.endswith("_done.json"):
                    continue
                full = os.path.join(path, name)
                doc = _read_json(full)
                kind = _kind_of_json(doc)
                if kind and (order == 1 or kind == "corridor"):
                    found.append((order, kind, full, doc))
        if found:
            rank = {"corridor": 0, "locate": 1, "evaluate": 2, "geocode": 3, "simulate": 4}
            found.sort(key=lambda f: (f[0], rank[f[1]], f[2]))
            _, kind, full, doc = found[0]
            return kind, os.path.abspath(full), doc
        raise BadInput(f"{path}: the directory holds no corridor catalogue, simulate/geocode output or "
                       "locate/evaluate result")
    if path.endswith(".json") and os.path.isfile(path):
        doc = _read_json(path)
        kind = _kind_of_json(doc)
        if kind:
            return kind, os.path.abspath(path), doc
        if doc is None:
            raise BadInput(f"{path}: not a JSON file gissar view can read")
    found = _sidecar_of(path)
    if found:
        return _kind_of_json(found[1]), os.path.abspath(found[0]), found[1]
    if not os.path.exists(path) and not os.path.exists(path + ".json"):
        raise BadInput(f"{path}: no such file, prefix or directory")
    raise BadInput(f"{path}: not a corridor catalogue (PREFIX_catalog.json), a simulate/geocode output or a "
                   "locate/evaluate result")


# --------------------------------------------------------------------------------------------------------------
# Geometry helpers

def _ring_of_wkt(text):
    m = re.match(r"\s*POLYGON\s*\(\((.*?)\)", text or "")
    if not m:
        return None
    try:
        return [[float(v) for v in p.split()[:2]] for p in m.group(1).split(",")]
    except ValueError:
        return None


def _index_rings(catalog_path):
    """{pose id: footprint ring} from PREFIX_index.csv (predicted footprints of skipped poses too)."""
    import csv
    index = catalog_path[: -len("_catalog.json")] + "_index.csv"
    rings = {}
    try:
        with open(index, newline="", encoding="utf-8") as f:
            for row in csv.DictReader(f):
                ring = _ring_of_wkt(row.get("footprint_wkt"))
                if ring:
                    rings[row.get("id")] = ring
    except OSError:
        pass
    return rings


def _offset_lonlat(lon, lat, east_m, north_m):
    r = 6378137.0
    dlat = north_m / r
    dlon = east_m / (r * math.cos(math.radians(lat)))
    return lon + math.degrees(dlon), lat + math.degrees(dlat)


def _track_to_en(along, cross, track_deg):
    """(east, north) of an (along, cross) offset: along the track angle (compass), cross to its right."""
    t = math.radians(track_deg)
    return along * math.sin(t) + cross * math.cos(t), along * math.cos(t) - cross * math.sin(t)


def _ellipse_ring(lon, lat, cov_ac, track_deg, k=math.sqrt(5.991464547107979), n=72):
    """95 % ellipse (chi-square 2 dof) of the (along, cross) covariance around (lon, lat), a closed ring."""
    a, b, c = cov_ac[0][0], cov_ac[0][1], cov_ac[1][1]
    tr, det = a + c, a * c - b * b
    disc = math.sqrt(max(tr * tr / 4 - det, 0.0))
    l1, l2 = max(tr / 2 + disc, 0.0), max(tr / 2 - disc, 0.0)
    theta = 0.5 * math.atan2(2 * b, a - c)  # major axis angle from the along axis
    ring = []
    for i in range(n + 1):
        s = 2 * math.pi * i / n
        u, v = k * math.sqrt(l1) * math.cos(s), k * math.sqrt(l2) * math.sin(s)
        along = u * math.cos(theta) - v * math.sin(theta)
        cross = u * math.sin(theta) + v * math.cos(theta)
        ring.append(list(_offset_lonlat(lon, lat, *_track_to_en(along, cross, track_deg))))
    return ring, k * math.sqrt(l1), k * math.sqrt(l2)


_CORE_LOCK = threading.Lock()


def _core_module():
    """gissar's compiled module (geocode, load_scene). Run as `gissar view`, only the extension itself is
    loaded (0.5 s), not the package's Python side (xarray, pandas: 2 s of imports competing with the first
    page load); registered as gissar._core, so a later `import gissar` reuses it."""
    with _CORE_LOCK:
        module = sys.modules.get("gissar._core")
        if module is not None:
            return module
        if "gissar" not in sys.modules:
            import importlib.machinery
            import importlib.util
            here = os.path.dirname(os.path.abspath(__file__))
            for suffix in importlib.machinery.EXTENSION_SUFFIXES:
                path = os.path.join(here, "_core" + suffix)
                if os.path.isfile(path):
                    spec = importlib.util.spec_from_file_location("gissar._core", path)
                    module = importlib.util.module_from_spec(spec)
                    sys.modules["gissar._core"] = module
                    try:
                        spec.loader.exec_module(module)
                    except BaseException:
                        del sys.modules["gissar._core"]
                        raise
                    return module
        from gissar import _core
        return _core


def _preload_core():
    try:
        _core_module()
    except Exception:  # noqa: BLE001 (geocode then falls back to the GCP warp)
        pass


def _scene_dem(scene):
    """The DEM a scene was built from (its build sidecar PREFIX.json beside PREFIX.gscene), for the hillshade."""
    if not scene:
        return None
    doc = _read_json(scene[: -len(".gscene")] + ".json") or {}
    inputs = doc.get("inputs") if isinstance(doc.get("inputs"), list) else []
    for i in inputs:
        path = i.get("path") if isinstance(i, dict) else None
        if isinstance(path, str) and path.lower().endswith((".tif", ".tiff", ".vrt", ".img")) and os.path.isfile(path):
            return path
    return None


def _feature(geometry, **properties):
    return {"type": "Feature", "geometry": geometry, "properties": properties}


# --------------------------------------------------------------------------------------------------------------
# The model of the page: what to draw, and the allow-list of files

class View:
    """The page's description (`/api/view.json`) and the files the server may send."""

    def __init__(self, path, cache_dir=None):
        self.kind, self.json_path, self.doc = resolve(path)
        self.root = os.path.dirname(self.json_path)
        self.root_real = os.path.realpath(self.root)
        self.files = {}      # url name -> absolute path under root
        self.renders = {}    # render key -> (function, args)
        self.cache_dir = cache_dir
        self.cache_lock = threading.Lock()
        self.description = {"kind": self.kind, "title": os.path.basename(self.json_path),
                            "source": os.path.basename(self.json_path), "status_colours": STATUS_COLOURS}
        self._allow(os.path.basename(self.json_path))
        getattr(self, "_build_" + self.kind)()
        scene = self._scene_path()
        dem = self._dem_path() or _scene_dem(scene)
        base = {}
        if dem:
            self._render("hillshade.png", "hillshade", dem)
            base.update(hillshade="/render/hillshade.png", hillshade_info="/render/hillshade.json")
        if scene:
            self._render("classes.png", "classes", scene)
            base.update(classes="/render/classes.png", classes_info="/render/classes.json")
        if base:
            self.description["base"] = base
        # gissar's compiled module takes half a second to load: loaded after the page's first render (not
        # competing with the first paint), not on the first click.
        self._preload = bool(scene) or any(spec[0] == "geocoded" for spec in self.renders.values())

    # files ---------------------------------------------------------------------------------------------------
    def _allow(self, name):
        """Adds a file the catalogue/result names (a name relative to root); returns its URL or None when
        it does not exist, is outside root or is no regular file."""
        if not isinstance(name, str) or not name or "\x00" in name:
            return None
        full = os.path.normpath(os.path.join(self.root, name))
        if os.path.dirname(full) != os.path.normpath(self.root) and not full.startswith(self.root + os.sep):
            return None
        if not self.inside(full) or not os.path.isfile(full):
            return None
        rel = os.path.relpath(full, self.root).replace(os.sep, "/")
        self.files[rel] = full
        return "/files/" + urllib.parse.quote(rel)

    def inside(self, full):
        real = os.path.realpath(full)
        return real == self.root_real or real.startswith(self.root_real + os.sep)

    def _render(self, key, what, *args):
        """Registers a rendered image: KEY.png (the picture) and KEY.json (its WGS84 extent, dB range)."""
        stem = key.rsplit(".", 1)[0]
        if what != "image_info":
            self.renders[stem] = (what, *args)
        return "/render/" + key

    def _dem_path(self):
        doc = self.doc
        candidates = []
        if self.kind == "corridor":
            candidates.append(((doc.get("gissar:inputs") or {}).get("dem") or {}).get("path"))
            candidates.append((doc.get("gissar:options") or {}).get("dem"))
        else:
            inputs = doc.get("inputs")
            if isinstance(inputs, dict):
                candidates += [v.get("path") if isinstance(v, dict) else v for k, v in inputs.items()
                               if "dem" in k or "terrain" in k]
            options = doc.get("options") or {}
            candidates.append(options.get("dem"))
            if self.kind == "geocode":
                image = self._geocode_source_sidecar()
                if image:
                    candidates.append((image.get("options") or {}).get("dem"))
            if isinstance(inputs, list):
                candidates += [i.get("path") for i in inputs if isinstance(i, dict)]
        for c in candidates:
            if isinstance(c, str) and c.lower().endswith((".tif", ".tiff", ".vrt", ".img")):
                full = c if os.path.isabs(c) else os.path.join(self.root, c)
                if os.path.isfile(full):
                    return full
        return None

    def _scene_path(self):
        """The .gscene the corridor, simulation or fix was made from (its class layer is drawn), or None."""
        doc = self.doc
        candidates = []
        if self.kind == "corridor":
            candidates.append(((doc.get("gissar:inputs") or {}).get("scene") or {}).get("path"))
            candidates.append((doc.get("gissar:options") or {}).get("scene"))
        else:
            inputs = doc.get("inputs")
            if isinstance(inputs, dict):
                candidates += [v.get("path") if isinstance(v, dict) else v for k, v in inputs.items() if "scene" in k]
            elif isinstance(inputs, list):
                candidates += [i.get("path") for i in inputs if isinstance(i, dict)]
            candidates.append((doc.get("options") or {}).get("scene"))
            if self.kind == "geocode":
                image = self._geocode_source_sidecar()
                if image:
                    candidates.append((image.get("options") or {}).get("scene"))
        for c in candidates:
            if isinstance(c, str) and c.endswith(".gscene"):
                full = c if os.path.isabs(c) else os.path.join(self.root, c)
                if os.path.isfile(full):
                    return full
        return None

    def _geocode_source_sidecar(self):
        image = (self.doc.get("options") or {}).get("image")
        if isinstance(image, str):
            full = image if os.path.isabs(image) else os.path.join(self.root, image)
            side = _sidecar_of(full)
            if side:
                return side[1]
        return None

    # corridor ------------------------------------------------------------------------------------------------
    def _build_corridor(self):
        doc = self.doc
        prefix = self.json_path[: -len("_catalog.json")]
        stem = os.path.basename(prefix)
        index_rings = _index_rings(self.json_path)
        self._allow(stem + "_index.csv")
        features, route, arrows = [], [], []
        counts = {}
        for pose in doc["gissar:poses"]:
            pid = str(pose.get("id"))
            status = pose.get("status", "failed")
            shown = "cached" if status == "done" and pose.get("cached") else status
            files = [f for f in pose.get("files") or [] if isinstance(f, str)]
            missing = [f for f in files if self._allow(f) is None]
            if status == "done" and missing:
                shown = "missing"
            counts[shown] = counts.get(shown, 0) + 1
            item = _read_json(os.path.join(self.root, f"{stem}_{pid}_stac.json")) if status == "done" else None
            ring = None
            if item and isinstance(item.get("geometry"), dict) and item["geometry"].get("type") == "Polygon":
                ring = item["geometry"]["coordinates"][0]
            ring = ring or index_rings.get(pid)
            base = f"{stem}_{pid}"
            image = {}
            tif = base + ".tif"
            geocoded = [pose["geocoded"]] if isinstance(pose.get("geocoded"), str) else []
            for g in geocoded:
                self._allow(g)
            geocoded += [f for f in files if f.endswith("_geocoded.tif") or f.endswith("_map.tif")]
            geocoded = [g for g in geocoded if g in self.files]
            if geocoded:
                # `gissar corridor --geocode` wrote the pose's image in map geometry: shown as it is.
                g = self.files[geocoded[0]]
                image["render"] = self._render(f"pose_{pid}.png", "image", g)
                image["render_info"] = self._render(f"pose_{pid}.json", "image_info", g)
                image["mask"] = self._render(f"pose_{pid}_mask.png", "mask", g, "layover_shadow")
                image["geotiff"] = "/files/" + urllib.parse.quote(geocoded[0])
                image["geocoded"] = "stored"
            elif tif in self.files:
                # None stored: geocoded on demand (gissar's geocode, cached), else warped through its GCPs.
                mask = self.files.get(base + "_mask.tif")
                image["render"] = self._render(f"pose_{pid}.png", "geocoded", self.files[tif], "image", mask)
                image["render_info"] = self._render(f"pose_{pid}.json", "image_info", self.files[tif])
                image["mask"] = self._render(f"pose_{pid}_mask.png", "geocoded", self.files[tif], "mask", mask)
                image["geocoded"] = "on demand"
            for name, key in ((base + ".png", "thumbnail"), (base + "_quicklook.png", "quicklook")):
                if name in self.files:
                    image[key] = "/files/" + urllib.parse.quote(name)
            if (base + ".json") in self.files:
                image["sidecar"] = "/files/" + urllib.parse.quote(base + ".json")
            props = {"id": pid, "status": shown, "reason": pose.get("reason") or (
                         f"missing files: {', '.join(missing)}" if shown == "missing" else None),
                     "heading_deg": pose.get("heading_deg"), "lon_deg": pose.get("lon_deg"),
                     "lat_deg": pose.get("lat_deg"), "distance_m": pose.get("distance_m"),
                     "center_lonlat_deg": pose.get("center_lonlat_deg"), "files": files, "image": image,
                     "time_utc": (item or {}).get("properties", {}).get("datetime"),
                     "options_sha256": (item or {}).get("properties", {}).get("gissar:options_sha256")}
            if ring:
                features.append(_feature({"type": "Polygon", "coordinates": [ring]}, **props))
            lon, lat = pose.get("lon_deg"), pose.get("lat_deg")
            if isinstance(lon, (int, float)) and isinstance(lat, (int, float)):
                if not route or route[-1] != [lon, lat]:
                    route.append([lon, lat])
                arrows.append(_feature({"type": "Point", "coordinates": [lon, lat]}, id=pid,
                                       heading_deg=pose.get("heading_deg") or 0.0, status=shown))
        self.description.update({
            "title": doc.get("title") or self.description["title"],
            "footprints": {"type": "FeatureCollection", "features": features},
            "route": _feature({"type": "LineString", "coordinates": route}) if len(route) >= 2 else None,
            "arrows": {"type": "FeatureCollection", "features": arrows},
            "poses": len(doc["gissar:poses"]), "counts": counts,
            "metadata": {"summary": doc.get("gissar:summary"), "options": doc.get("gissar:options"),
                         "inputs": doc.get("gissar:inputs"), "image_size": doc.get("gissar:image_size"),
                         "description": doc.get("description")},
        })

    # simulate / geocode ---------------------------------------------------------------------------------------
    def _build_simulate(self):
        prefix = self.json_path[: -len(".json")]
        stem = os.path.basename(prefix)
        for f in self.doc.get("outputs") or []:
            if isinstance(f, str):
                self._allow(os.path.basename(f))
        for suffix in (".tif", "_mask.tif", ".png", "_quicklook.png", "_stac.json"):
            self._allow(stem + suffix)
        image = {}
        if self.kind == "simulate" and stem + ".tif" in self.files:
            # As a corridor pose: geocoded on demand (gissar's geocode, cached), else warped through its GCPs.
            tif, mask = self.files[stem + ".tif"], self.files.get(stem + "_mask.tif")
            image["render"] = self._render("image.png", "geocoded", tif, "image", mask)
            image["render_info"] = self._render("image.json", "image_info", tif)
            if mask:
                image["mask"] = self._render("mask.png", "geocoded", tif, "mask", mask)
                image["mask_info"] = "/render/mask.json"
        elif stem + ".tif" in self.files:
            image["render"] = self._render("image.png", "image", self.files[stem + ".tif"])
            image["render_info"] = self._render("image.json", "image_info", self.files[stem + ".tif"])
        if self.kind != "simulate" and stem + "_mask.tif" in self.files:
            image["mask"] = self._render("mask.png", "mask", self.files[stem + "_mask.tif"], None)
            image["mask_info"] = self._render("mask.json", "image_info", self.files[stem + "_mask.tif"])
        if self.kind == "geocode" and stem + ".tif" in self.files:
            image["mask"] = self._render("mask.png", "mask", self.files[stem + ".tif"], "layover_shadow")
            image["mask_info"] = "/render/mask.json"
            image["geotiff"] = "/files/" + urllib.parse.quote(stem + ".tif")
        for name, key in ((stem + ".png", "thumbnail"), (stem + "_quicklook.png", "quicklook")):
            if name in self.files:
                image[key] = "/files/" + urllib.parse.quote(name)
        item = _read_json(prefix + "_stac.json") or {}
        footprints = []
        if isinstance(item.get("geometry"), dict):
            footprints.append(_feature(item["geometry"], id=stem, status="done", image=image))
        centre = self.doc.get("scene_centre") or {}
        self.description.update({
            "image": image, "footprints": {"type": "FeatureCollection", "features": footprints},
            "poses": len(footprints),
            "centre": [centre.get("lon_deg"), centre.get("lat_deg")] if centre.get("lon_deg") is not None else None,
            "metadata": {k: self.doc.get(k) for k in ("command_line", "created_utc", "version", "geometry",
                                                      "sampling", "radiometry", "scene_centre", "grid", "bands")
                         if k in self.doc},
        })

    _build_geocode = _build_simulate

    # locate / evaluate ----------------------------------------------------------------------------------------
    def _build_locate(self):
        doc = self.doc
        prefix = self.json_path[: -len(".json")]
        stem = os.path.basename(prefix)
        for f in doc.get("outputs") or []:
            if isinstance(f, str):
                self._allow(os.path.basename(f))
        for suffix in ("_composite.png", "_stac.json"):
            self._allow(stem + suffix)
        markers, ellipse = [], None
        fix = doc.get("fix") or {}
        frame = fix.get("frame") or {}
        err = fix.get("error_against_annotated_track") or {}
        sensor = frame.get("sensor_lon_lat_height")
        track = frame.get("track_angle_deg", 0.0) or 0.0
        if sensor:
            lon, lat = sensor[0], sensor[1]
            markers.append(_feature({"type": "Point", "coordinates": [lon, lat]}, role="fix",
                                    label="fix" if doc.get("converged") else "fix (not converged)"))
            truth = None
            if err.get("along_cross_up_m"):
                a, c = err["along_cross_up_m"][:2]
                truth = _offset_lonlat(lon, lat, *_track_to_en(-a, -c, track))
                markers.append(_feature({"type": "Point", "coordinates": list(truth)}, role="truth",
                                        label="truth (annotated track)"))
            prior = None
            if truth and err.get("prior_along_cross_up_m"):
                a, c = err["prior_along_cross_up_m"][:2]
                prior = _offset_lonlat(truth[0], truth[1], *_track_to_en(a, c, track))
            elif fix.get("correction"):
                corr = fix["correction"]
                prior = _offset_lonlat(lon, lat, *_track_to_en(-corr.get("along_m", 0.0),
                                                               -corr.get("cross_m", 0.0), track))
            if prior:
                markers.insert(0, _feature({"type": "Point", "coordinates": list(prior)}, role="prior",
                                           label="prior (INS)"))
            cov = fix.get("covariance_along_cross_up_heading")
            if cov and len(cov) >= 2:
                ring, major, minor = _ellipse_ring(lon, lat, [row[:2] for row in cov[:2]], track)
                ellipse = _feature({"type": "Polygon", "coordinates": [ring]}, role="ellipse95",
                                   semi_major_m=major, semi_minor_m=minor)
        composite = stem + "_composite.png"
        self.description.update({
            "markers": {"type": "FeatureCollection", "features": markers}, "ellipse": ellipse,
            "composite": "/files/" + urllib.parse.quote(composite) if composite in self.files else None,
            "footprints": {"type": "FeatureCollection", "features": []}, "poses": 0,
            "metadata": {k: doc.get(k) for k in ("converged", "reason", "cell_m", "peak_ncc", "iterations",
                                                  "seconds", "command_line", "version", "success_rate",
                                                  "converged_rate", "position_error_m", "trials")
                         if k in doc and not isinstance(doc.get(k), list)},
        })
        if fix:
            self.description["metadata"]["time_utc"] = fix.get("time_utc")
            self.description["metadata"]["error_against_annotated_track"] = err
            self.description["metadata"]["sigma_along_cross_up_heading"] = fix.get("sigma_along_cross_up_heading")

    def _build_evaluate(self):
        """Every trial's fix (green: success, red: not), the truth (the annotated track at the fix time) and
        the success radius (success_cells x cell) around it."""
        self._build_locate()
        doc = self.doc
        markers, truth, cell = [], None, None
        for record in doc.get("trial_records") or []:
            if not isinstance(record, dict):
                continue
            fix = record.get("fix") or {}
            frame = fix.get("frame") or {}
            sensor = frame.get("sensor_lon_lat_height")
            if not sensor:
                continue
            track = frame.get("track_angle_deg", 0.0) or 0.0
            markers.append(_feature({"type": "Point", "coordinates": sensor[:2]}, role="trial",
                                    trial=record.get("trial"), success=bool(record.get("success")),
                                    position_error_m=record.get("position_error_m")))
            err = (fix.get("error_against_annotated_track") or {}).get("along_cross_up_m")
            if truth is None and err:
                truth = _offset_lonlat(sensor[0], sensor[1], *_track_to_en(-err[0], -err[1], track))
                cell = record.get("cell_m")
        if truth:
            markers.append(_feature({"type": "Point", "coordinates": list(truth)}, role="truth",
                                    label="truth (annotated track)"))
            radius = (doc.get("success_cells") or 2.0) * (cell or doc.get("resolution_cell_m") or 0.0)
            if radius > 0:
                ring = [list(_offset_lonlat(truth[0], truth[1], radius * math.sin(2 * math.pi * i / 72),
                                            radius * math.cos(2 * math.pi * i / 72))) for i in range(73)]
                markers.append(_feature({"type": "Polygon", "coordinates": [ring]}, role="success_radius",
                                        radius_m=radius))
        self.description["markers"] = {"type": "FeatureCollection", "features": markers}
        self.description["ellipse"] = None
        self.description["metadata"].update({k: doc.get(k) for k in ("success_rate", "converged_rate", "trials",
                                             "position_error_m", "position_error_cells", "success_definition")
                                             if k in doc})

    # renders -------------------------------------------------------------------------------------------------
    def render(self, key):
        """(bytes, content type) of a rendered key (cached on disk), or None for an unknown key."""
        stem, _, ext = key.rpartition(".")
        spec = self.renders.get(stem)
        if spec is None or ext not in ("png", "json"):
            return None
        what, *args = spec
        ident = json.dumps([what, args, [_stat_identity(a) for a in args if isinstance(a, str)]])
        name = hashlib.sha256(ident.encode()).hexdigest()[:24]
        with self.cache_lock:
            cache = _cache_dir(self.cache_dir)
            png, info = os.path.join(cache, name + ".png"), os.path.join(cache, name + ".json")
            if not (os.path.isfile(png) and os.path.isfile(info)):
                meta = _RENDERERS[what](png, *args)
                _write_atomic(info, json.dumps(meta).encode())
            if self._preload and ext == "png":
                self._preload = False
                threading.Thread(target=_preload_core, daemon=True).start()
        path = png if ext == "png" else info
        with open(path, "rb") as f:
            return f.read(), ("image/png" if ext == "png" else "application/json")


def _stat_identity(path):
    try:
        st = os.stat(path)
        return [st.st_size, st.st_mtime_ns]
    except OSError:
        return None


def _cache_dir(explicit):
    base = explicit or os.environ.get("GISSAR_VIEW_CACHE")
    if not base:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        base = os.path.join(xdg, "gissar", "view")
    try:
        os.makedirs(base, exist_ok=True)
        if os.access(base, os.W_OK):
            return base
    except OSError:
        pass
    base = os.path.join(tempfile.gettempdir(), f"gissar-view-{os.getuid()}")
    os.makedirs(base, mode=0o700, exist_ok=True)
    return base


def _write_atomic(path, data):
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix=".tmp-")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _png_of(out_path, mem):
    """Writes a MEM dataset as PNG (atomic); returns its WGS84 extent [w, s, e, n]."""
    from osgeo import gdal
    gt = mem.GetGeoTransform()
    w, h = mem.RasterXSize, mem.RasterYSize
    extent = [gt[0], gt[3] + gt[5] * h, gt[0] + gt[1] * w, gt[3]]
    tmp = out_path + f".tmp-{os.getpid()}-{threading.get_ident()}.png"
    gdal.Translate(tmp, mem, format="PNG")
    for aux in (tmp + ".aux.xml",):
        if os.path.exists(aux):
            os.unlink(aux)
    os.replace(tmp, out_path)
    return extent


def _warp_to_wgs84(src, resampling, nodata):
    from osgeo import gdal
    opts = dict(format="MEM", dstSRS="EPSG:4326", resampleAlg=resampling, srcNodata=nodata, dstAlpha=True,
                multithread=False)
    if src.GetGCPCount() > 0 and not src.GetProjection():
        opts["tps"] = True
    warped = gdal.Warp("", src, **opts)
    if max(warped.RasterXSize, warped.RasterYSize) > MAX_RENDER_PX:
        scale = MAX_RENDER_PX / max(warped.RasterXSize, warped.RasterYSize)
        warped = gdal.Warp("", src, width=max(1, int(warped.RasterXSize * scale)),
                           height=max(1, int(warped.RasterYSize * scale)), **opts)
    return warped


def _mem_like(src, bands, dtype):
    from osgeo import gdal
    h, w = bands[0].shape
    mem = gdal.GetDriverByName("MEM").Create("", w, h, len(bands), dtype)
    if src.GetGCPCount() > 0 and not src.GetProjection():
        mem.SetGCPs(src.GetGCPs(), src.GetGCPSpatialRef())
    else:
        mem.SetGeoTransform(src.GetGeoTransform())
        mem.SetProjection(src.GetProjection())
    for i, b in enumerate(bands):
        mem.GetRasterBand(i + 1).WriteArray(b)
    return mem


def _render_image(out_path, image_path):
    """The image's first band (`total`), dB stretch 2..98 %, warped to WGS84: grey + alpha PNG."""
    import numpy as np
    from osgeo import gdal
    src = gdal.Open(image_path)
    if src is None:
        raise OSError(f"cannot read {image_path}")
    band_index = 1
    for b in range(1, src.RasterCount + 1):
        if src.GetRasterBand(b).GetDescription() == "total":
            band_index = b
            break
    a = src.GetRasterBand(band_index).ReadAsArray().astype("float64")
    valid = np.isfinite(a) & (a > 0)
    db = np.full(a.shape, np.nan)
    db[valid] = 10 * np.log10(a[valid])
    lo, hi = (np.percentile(db[valid], [2, 98]) if valid.any() else (0.0, 1.0))
    hi = hi if hi > lo else lo + 1
    grey = np.zeros(a.shape, dtype="uint8")
    grey[valid] = np.clip(1 + (db[valid] - lo) / (hi - lo) * 254, 1, 255).astype("uint8")
    warped = _warp_to_wgs84(_mem_like(src, [grey], gdal.GDT_Byte), "bilinear", 0)
    extent = _png_of(out_path, warped)
    return {"extent": extent, "db_range": [float(lo), float(hi)], "unit": "dB (sigma0, 10 log10 of linear intensity)",
            "width": warped.RasterXSize, "height": warped.RasterYSize}


def _render_mask(out_path, image_path, band_name):
    """Layover (orange), shadow (blue), both (magenta) as RGBA, warped to WGS84 (nearest)."""
    import numpy as np
    from osgeo import gdal
    src = gdal.Open(image_path)
    if src is None:
        raise OSError(f"cannot read {image_path}")
    index = 1
    if band_name:
        for b in range(1, src.RasterCount + 1):
            if src.GetRasterBand(b).GetDescription() == band_name:
                index = b
    m = src.GetRasterBand(index).ReadAsArray()
    m = np.nan_to_num(m.astype("float64"), nan=0).astype("int64")
    m = np.where((m >= 0) & (m <= 3), m, 0)  # 255 = outside the footprint: not drawn
    colours = np.array([[0, 0, 0, 0], [255, 96, 0, 230], [0, 80, 255, 230], [230, 0, 230, 230]], dtype="uint8")
    rgba = colours[m]
    mem = _mem_like(src, [rgba[..., i] for i in range(4)], gdal.GDT_Byte)
    mem.GetRasterBand(4).SetColorInterpretation(gdal.GCI_AlphaBand)
    opts = dict(format="MEM", dstSRS="EPSG:4326", resampleAlg="near", multithread=False)
    if src.GetGCPCount() > 0 and not src.GetProjection():
        opts["tps"] = True
    warped = gdal.Warp("", mem, **opts)
    extent = _png_of(out_path, warped)
    return {"extent": extent, "legend": {"layover": "#ff6000", "shadow": "#0050ff", "both": "#e600e6"}}


def _render_hillshade(out_path, dem_path):
    """The DEM's hillshade (GDAL DEMProcessing), in WGS84, at most MAX_RENDER_PX a side: grey + alpha PNG."""
    from osgeo import gdal
    src = gdal.Open(dem_path)
    if src is None:
        raise OSError(f"cannot read {dem_path}")
    scale = min(1.0, MAX_RENDER_PX / max(src.RasterXSize, src.RasterYSize))
    warped = gdal.Warp("", src, format="MEM", dstSRS="EPSG:4326", resampleAlg="bilinear",
                       width=max(2, int(src.RasterXSize * scale)), height=max(2, int(src.RasterYSize * scale)),
                       outputType=gdal.GDT_Float32, multithread=False)
    shade = gdal.DEMProcessing("", warped, "hillshade", format="MEM", scale=111120, computeEdges=True,
                               zFactor=1.5)
    import numpy as np
    h = shade.GetRasterBand(1).ReadAsArray()
    alpha = np.where(h > 0, 255, 0).astype("uint8")
    h = np.clip(h, 1, 255).astype("uint8")
    mem = gdal.GetDriverByName("MEM").Create("", h.shape[1], h.shape[0], 2, gdal.GDT_Byte)
    mem.SetGeoTransform(warped.GetGeoTransform())
    mem.SetProjection(warped.GetProjection())
    mem.GetRasterBand(1).WriteArray(h)
    mem.GetRasterBand(2).WriteArray(alpha)
    mem.GetRasterBand(2).SetColorInterpretation(gdal.GCI_AlphaBand)
    extent = _png_of(out_path, mem)
    return {"extent": extent, "source": os.path.basename(dem_path)}


#: Class colours of a scene (as `gissar scene build`'s PREFIX_classes.png: image/class_map.cc) and the order
#: in which overlapping classes are painted (lowest priority first: scene_config.h's priorities).
CLASS_COLOURS = {"default": "#d2be96", "water": "#286edc", "forest": "#288c3c", "urban": "#a0a0a0",
                 "road": "#141414", "building": "#d23228", "sea": "#0f3282"}
CLASS_PRIORITY = {"default": 0, "water": 4, "forest": 2, "urban": 3, "road": 5, "building": 6, "sea": 1}


def _render_classes(out_path, scene_path):
    """The scene's classes seen from above (every triangle filled with its class; bare terrain, `default`,
    transparent over the hillshade), as RGBA in WGS84. The mesh is in the scene's ENU frame on WGS84: its
    east/north are taken as an ellipsoidal orthographic projection at the ENU origin (within metres of the
    true footprint over a scene some tens of km across), rasterised with GDAL (one multipolygon per class,
    painted in class priority) and warped to WGS84."""
    import struct

    import numpy as np
    from osgeo import gdal, ogr, osr
    scene = _core_module().load_scene(scene_path)
    v = np.asarray(scene["vertices_enu_m"], dtype="float64")[:, :2]
    tri = np.asarray(scene["triangles"], dtype="int64")
    cls = np.asarray(scene["classes"], dtype="int64")
    names = list(scene["class_names"])
    lon0, lat0 = scene["origin_lonlat_deg"]
    lo, hi = v.min(axis=0), v.max(axis=0)
    cell = max(float(max(hi - lo)) / MAX_RENDER_PX, 1.0)
    w, h = int(math.ceil((hi[0] - lo[0]) / cell)) + 1, int(math.ceil((hi[1] - lo[1]) / cell)) + 1
    srs = osr.SpatialReference()
    srs.ImportFromProj4(f"+proj=ortho +lat_0={lat0!r} +lon_0={lon0!r} +x_0=0 +y_0=0 +ellps=WGS84 +units=m "
                        "+no_defs")
    mem = gdal.GetDriverByName("MEM").Create("", w, h, 1, gdal.GDT_Byte)
    mem.SetGeoTransform((lo[0], cell, 0.0, hi[1] + cell, 0.0, -cell))
    mem.SetProjection(srs.ExportToWkt())
    layer_ds = ogr.GetDriverByName("Memory").CreateDataSource("")
    layer = layer_ds.CreateLayer("classes", srs, ogr.wkbMultiPolygon)
    layer.CreateField(ogr.FieldDefn("value", ogr.OFTInteger))
    present = {}
    order = sorted(set(cls.tolist()), key=lambda c: CLASS_PRIORITY.get(names[c] if c < len(names) else "", 9))
    for c in order:
        name = names[c] if c < len(names) else f"class {c}"
        sel = tri[cls == c]
        present[name] = int(len(sel))
        if name == "default" or not len(sel):
            continue
        # One WKB multipolygon of the class's triangles, built in one go: per polygon a header (byte order,
        # type 3, 1 ring, 4 points) and the closed ring's four (x, y).
        pts = v[np.concatenate([sel, sel[:, :1]], axis=1)]  # (n, 4, 2)
        head = np.frombuffer(struct.pack("<BIII", 1, 3, 1, 4), dtype="uint8")
        rec = np.empty((len(sel), 13 + 64), dtype="uint8")
        rec[:, :13] = head
        rec[:, 13:] = pts.reshape(len(sel), 8).astype("<f8").view("uint8").reshape(len(sel), 64)
        wkb = struct.pack("<BII", 1, 6, len(sel)) + rec.tobytes()
        feature = ogr.Feature(layer.GetLayerDefn())
        feature.SetGeometryDirectly(ogr.CreateGeometryFromWkb(wkb))
        feature.SetField("value", c + 1)
        layer.CreateFeature(feature)
    gdal.RasterizeLayer(mem, [1], layer, options=["ATTRIBUTE=value"])
    index = mem.GetRasterBand(1).ReadAsArray().astype("int64")
    palette = np.zeros((256, 4), dtype="uint8")
    for c, name in enumerate(names):
        colour = CLASS_COLOURS.get(name, "#ff00ff")
        palette[c + 1] = [int(colour[1:3], 16), int(colour[3:5], 16), int(colour[5:7], 16),
                          0 if name == "default" else 200]
    rgba = palette[index]
    out = gdal.GetDriverByName("MEM").Create("", w, h, 4, gdal.GDT_Byte)
    out.SetGeoTransform(mem.GetGeoTransform())
    out.SetProjection(mem.GetProjection())
    for i in range(4):
        out.GetRasterBand(i + 1).WriteArray(rgba[..., i])
    out.GetRasterBand(4).SetColorInterpretation(gdal.GCI_AlphaBand)
    warped = gdal.Warp("", out, format="MEM", dstSRS="EPSG:4326", resampleAlg="near", multithread=False)
    extent = _png_of(out_path, warped)
    legend = {n: CLASS_COLOURS.get(n, "#ff00ff") for n in names if present.get(n) and n != "default"}
    return {"extent": extent, "legend": legend, "triangles": present, "source": os.path.basename(scene_path),
            "cell_m": cell}


def _geocoded_copy(cache, image_path):
    """The map-geometry version of a slant-range image, made on demand with gissar's own geocode (the
    `gissar geocode` of the library, on the simulation's own terrain) and kept in CACHE/geocoded/ under a
    name keyed by the image's real path, size and modification time. Returns its path."""
    st = os.stat(image_path)
    ident = json.dumps([os.path.realpath(image_path), st.st_size, st.st_mtime_ns])
    directory = os.path.join(cache, "geocoded")
    os.makedirs(directory, exist_ok=True)
    prefix = os.path.join(directory, hashlib.sha256(ident.encode()).hexdigest()[:24])
    if not (os.path.isfile(prefix + ".tif") and os.path.isfile(prefix + ".json")):
        # The geocode request's fields (pipeline/geocode_fields.cc); the others keep their defaults.
        _core_module().geocode({"image": image_path, "out_prefix": prefix, "resampling": "bilinear"})
    return prefix + ".tif"


def _render_geocoded(out_path, image_path, part, mask_path):
    """A pose's image (part 'image') or layover/shadow mask (part 'mask') without a stored geocoded image:
    geocoded on demand (_geocoded_copy), else, when geocode cannot be used (its terrain moved or gone, the
    gissar module not importable), the slant-range image warped through its GCPs (thin-plate spline) as
    before, which the info records."""
    try:
        geocoded = _geocoded_copy(os.path.dirname(out_path), image_path)
        via, reason = "geocode (on demand, cached)", None
    except Exception as e:  # noqa: BLE001 (any geocode failure: fall back to the warp)
        geocoded, via, reason = None, "GCP warp (thin-plate spline)", f"{type(e).__name__}: {e}"
    if part == "image":
        meta = _render_image(out_path, geocoded or image_path)
    elif geocoded:
        meta = _render_mask(out_path, geocoded, "layover_shadow")
    elif mask_path:
        meta = _render_mask(out_path, mask_path, None)
    else:
        raise OSError("no mask for this image")
    meta["via"] = via
    if reason:
        meta["geocode_failed"] = reason
    return meta


_RENDERERS = {"image": _render_image, "mask": _render_mask, "hillshade": _render_hillshade,
              "classes": _render_classes, "geocoded": _render_geocoded}


# --------------------------------------------------------------------------------------------------------------
# The server

def assets_dir():
    """The bundled page: $GISSAR_VIEW_ASSETS, the package's web/ (build tree, installs), or the source tree's
    web/dist."""
    here = os.path.dirname(os.path.abspath(__file__))
    for c in (os.environ.get("GISSAR_VIEW_ASSETS"), os.path.join(here, "web"),
              os.path.join(here, "..", "..", "web", "dist")):
        if c and os.path.isfile(os.path.join(c, "index.html")):
            return os.path.realpath(c)
    return None


def _asset_files(directory):
    files = {}
    for dirpath, _, names in os.walk(directory):
        for n in names:
            full = os.path.join(dirpath, n)
            if os.path.islink(full):
                continue
            files[os.path.relpath(full, directory).replace(os.sep, "/")] = full
    return files


def _is_loopback(host):
    if host in ("localhost", "localhost.localdomain"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        try:
            return all(ipaddress.ip_address(a[4][0]).is_loopback for a in socket.getaddrinfo(host, None))
        except (OSError, ValueError):
            return False


class Handler(http.server.BaseHTTPRequestHandler):
    server_version = "gissar-view"
    sys_version = ""
    protocol_version = "HTTP/1.1"
    timeout = SOCKET_TIMEOUT_S
    view = None           # View
    assets = {}           # url name -> path
    allowed_hosts = None  # set of Host header values, or None (any)
    quiet = False

    # request reading with bounds --------------------------------------------------------------------------
    def handle_one_request(self):
        try:
            self.raw_requestline = self.rfile.readline(MAX_REQUEST_LINE + 1)
            if len(self.raw_requestline) > MAX_REQUEST_LINE:
                self.requestline, self.request_version, self.command = "", "HTTP/1.0", None
                self.close_connection = True
                self.send_error(414, "Request line too long")
                return
            if not self.raw_requestline:
                self.close_connection = True
                return
            head = io.BytesIO()
            lines = 0
            while True:
                line = self.rfile.readline(MAX_HEADER_BYTES + 1)
                head.write(line)
                lines += 1
                if head.tell() > MAX_HEADER_BYTES or lines > MAX_HEADER_LINES + 1:
                    self.requestline, self.request_version, self.command = "", "HTTP/1.0", None
                    self.close_connection = True
                    self.send_error(431, "Request header fields too large")
                    return
                if line in (b"\r\n", b"\n", b""):
                    break
            real = self.rfile
            self.rfile = io.BytesIO(head.getvalue())
            try:
                ok = self.parse_request()
            finally:
                self.rfile = real
            if not ok:
                return
            if self.command not in ("GET", "HEAD"):
                self.close_connection = True
                self.send_response(405)
                self.send_header("Allow", "GET, HEAD")
                self.send_header("Content-Length", "0")
                self.send_header("Connection", "close")
                self.end_headers()
                return
            self.respond()
            self.wfile.flush()
        except (socket.timeout, TimeoutError, ConnectionError):
            self.close_connection = True

    def log_message(self, fmt, *args):
        if not self.quiet:
            sys.stderr.write("gissar view: %s %s\n" % (self.address_string(), fmt % args))

    # responses -----------------------------------------------------------------------------------------------
    def _headers_common(self):
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Cache-Control", "no-cache")
        self.send_header("Referrer-Policy", "no-referrer")
        self.send_header("Content-Security-Policy",
                         "default-src 'self'; img-src 'self' data: blob:; style-src 'self' 'unsafe-inline'; "
                         "worker-src 'self' blob:; connect-src 'self'; object-src 'none'; frame-ancestors 'none'")

    def _error(self, code, text):
        body = (text + "\n").encode()
        self.send_response(code)
        self._headers_common()
        self.send_header("Content-Type", "text/plain; charset=utf-8")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _bytes(self, body, content_type):
        self.send_response(200)
        self._headers_common()
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _file(self, path):
        """A file with Range support (one byte range: 206; unsatisfiable: 416)."""
        try:
            f = open(path, "rb")
        except OSError:
            return self._error(404, "not found")
        with f:
            size = os.fstat(f.fileno()).st_size
            ctype = mimetypes.guess_type(path)[0] or "application/octet-stream"
            if path.endswith((".tif", ".tiff")):
                ctype = "image/tiff"
            start, end, status = 0, size - 1, 200
            rng = self.headers.get("Range")
            if rng is not None:
                m = re.fullmatch(r"\s*bytes\s*=\s*(\d*)\s*-\s*(\d*)\s*", rng)
                if m and (m.group(1) or m.group(2)):
                    if m.group(1):
                        start = int(m.group(1))
                        end = min(int(m.group(2)), size - 1) if m.group(2) else size - 1
                    else:
                        start, end = max(size - int(m.group(2)), 0), size - 1
                    if start >= size or start > end or (m.group(1) and m.group(2) and int(m.group(2)) < start):
                        self.send_response(416)
                        self._headers_common()
                        self.send_header("Content-Range", f"bytes */{size}")
                        self.send_header("Content-Length", "0")
                        self.end_headers()
                        return
                    status = 206
                elif not rng.strip().startswith("bytes="):
                    pass  # another unit: ignored, the whole file (RFC 9110)
                else:
                    self.send_response(416)  # malformed or several ranges
                    self._headers_common()
                    self.send_header("Content-Range", f"bytes */{size}")
                    self.send_header("Content-Length", "0")
                    self.end_headers()
                    return
            length = end - start + 1 if size else 0
            self.send_response(status)
            self._headers_common()
            self.send_header("Content-Type", ctype)
            self.send_header("Accept-Ranges", "bytes")
            self.send_header("Content-Length", str(length))
            if status == 206:
                self.send_header("Content-Range", f"bytes {start}-{end}/{size}")
            self.end_headers()
            if self.command == "HEAD":
                return
            f.seek(start)
            left = length
            while left > 0:
                chunk = f.read(min(left, 1 << 16))
                if not chunk:
                    break
                self.wfile.write(chunk)
                left -= len(chunk)

    def respond(self):
        if self.allowed_hosts is not None:
            host = (self.headers.get("Host") or "").strip().lower()
            if host not in self.allowed_hosts:
                return self._error(403, "forbidden host")
        raw = self.path
        if not raw.startswith("/"):
            return self._error(400, "bad request")
        path = raw.split("?", 1)[0].split("#", 1)[0]
        try:
            decoded = urllib.parse.unquote(path, errors="strict") if "%" in path else path
        except UnicodeDecodeError:
            return self._error(400, "bad path")
        # Refused outright: dot segments, backslashes, NUL, doubled slashes and encoded separators.
        if ("\x00" in decoded or "\\" in decoded or "//" in decoded
                or any(seg in ("..", ".") for seg in decoded.split("/"))
                or re.search(r"%(2f|5c|2e|00)", path, re.IGNORECASE)):
            return self._error(400, "bad path")
        if decoded in ("/", "/index.html"):
            return self._asset("index.html")
        if decoded == "/api/view.json":
            return self._bytes(json.dumps(self.view.description).encode(), "application/json")
        if decoded.startswith("/app/"):
            return self._asset(decoded[len("/app/"):])
        if decoded.startswith("/files/"):
            name = decoded[len("/files/"):]
            full = self.view.files.get(name)
            if full is None:
                return self._error(404, "not found")
            if not self.view.inside(full) or not os.path.isfile(full):
                return self._error(403, "forbidden")
            return self._file(full)
        if decoded.startswith("/render/"):
            key = decoded[len("/render/"):]
            try:
                out = self.view.render(key)
            except Exception as e:  # GDAL failure on one image: the page shows it, the server goes on
                return self._error(500, f"render failed: {type(e).__name__}: {e}")
            if out is None:
                return self._error(404, "not found")
            return self._bytes(*out)
        return self._error(404, "not found")

    def _asset(self, name):
        full = self.assets.get(name)
        if full is None:
            return self._error(404, "not found")
        return self._file(full)


class Server(http.server.ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = False
    request_queue_size = 64


def make_server(path, host="127.0.0.1", port=0, quiet=False, cache_dir=None):
    """(server, url) serving PATH; raises BadInput (no known kind, no bundle) and OSError (bind)."""
    view = View(path, cache_dir=cache_dir)
    assets = assets_dir()
    if assets is None:
        raise BadInput("the page's bundle is not built (web/: run `make build`, or set GISSAR_VIEW_ASSETS)")
    family = socket.AF_INET6 if ":" in host else socket.AF_INET

    class BoundServer(Server):
        address_family = family

    handler = type("ViewHandler", (Handler,), {"view": view, "assets": _asset_files(assets), "quiet": quiet})
    server = BoundServer((host, port), handler)
    bound_port = server.server_address[1]
    url_host = f"[{host}]" if ":" in host else host
    if _is_loopback(host):
        names = {host, "localhost", "127.0.0.1", "[::1]"}
        handler.allowed_hosts = {f"{n}:{bound_port}".lower() for n in names}
    return server, f"http://{url_host}:{bound_port}/"


# --------------------------------------------------------------------------------------------------------------
# Command line

class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise Usage(message)

    def parse_args(self, args=None, namespace=None):
        """Unknown flags are errors, with a suggestion (as every gissar command)."""
        import difflib
        args, unknown = self.parse_known_args(args, namespace)
        if unknown:
            flags = [o for a in self._actions for o in a.option_strings]
            close = difflib.get_close_matches(unknown[0].split("=", 1)[0], flags, n=1, cutoff=0.75)
            raise Usage(f"unrecognized argument: {unknown[0]}" + (f"; did you mean {close[0]}?" if close else ""))
        return args

    def format_help(self):
        lines = [self.description, f"Usage: {self.prog} [OPTIONS] PATH", "", "Positionals:",
                 "  PATH TEXT REQUIRED".ljust(_HELP_COLUMN) + "A corridor catalogue (PREFIX_catalog.json), a "
                 "simulate/geocode output, a locate/evaluate result, or a directory holding one", "", "Options:"]
        for a in self._actions:
            if not a.option_strings or a.help is argparse.SUPPRESS:
                continue
            names = ", ".join(a.option_strings)
            if a.nargs != 0:
                names += " " + ("UINT" if a.type is _port else "TEXT")
            left = "  " + names
            if len(left) >= _HELP_COLUMN:
                lines += [left, " " * _HELP_COLUMN + (a.help or "")]
            else:
                lines.append(left.ljust(_HELP_COLUMN) + (a.help or ""))
        return "\n".join(lines) + "\n"


class _Switch(argparse.Action):
    """--X / --no-X, the last one given wins (as every gissar switch)."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, not option_string.startswith("--no-"))


def _port(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r}") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"must be 0..65535, got {text}")
    return value


def make_parser():
    p = _Parser(prog="gissar view", add_help=False, allow_abbrev=False,
                description="Show a corridor catalogue, a simulation or a pose fix on a map in the browser "
                            "(a local web server; docs/view.md).")
    p.add_argument("-h", "--help", action="store_true", help="Print this help message and exit")
    p.add_argument("path", nargs="?", help=argparse.SUPPRESS)
    p.add_argument("--port", type=_port, default=0, help="TCP port (default: a free one)")
    p.add_argument("--host", default="127.0.0.1",
                   help="Address to bind (default: 127.0.0.1; another address is reachable from the network: "
                        "a warning)")
    p.add_argument("--browser", "--no-browser", dest="browser", action=_Switch, default=True,
                   help="Open the system browser at the URL (--no-browser: only print it) (default: on)")
    p.add_argument("--quiet", action="store_true",
                   help="Only warnings and errors on stderr (same as --log-level warning)")
    p.add_argument("--log-level", default="info", choices=["error", "warning", "info"],
                   help="error, warning or info (default: info)")
    p.add_argument("--threads", type=_port, default=0, help="Worker threads (default: all cores; the server uses "
                   "one per connection)")
    p.add_argument("--force", action="store_true", help="Accepted as by every command (nothing to force here)")
    p.add_argument("--options", default=None, help="JSON file of options: keys are the snake_case field names "
                   "(port, host, browser, quiet, log_level, cache_dir); flags on the command line win")
    p.add_argument("--cache-dir", default=None,
                   help="Directory for the rendered hillshade and images (default: ~/.cache/gissar/view)")
    return p


_OPTION_KEYS = ("port", "host", "browser", "quiet", "log_level", "cache_dir", "threads", "force")


def _apply_options_file(parser, args, argv):
    """--options FILE.json: its keys (snake_case) as defaults under the flags given on the command line."""
    try:
        with open(args.options, encoding="utf-8") as f:
            options = json.load(f)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise BadInput(f"{args.options}: cannot read the options file ({e}) (--options)") from None
    if not isinstance(options, dict):
        raise BadInput(f"{args.options}: the options file is no JSON object (--options)")
    unknown = sorted(set(options) - set(_OPTION_KEYS))
    if unknown:
        raise BadInput(f"{args.options}: unknown key {unknown[0]!r} (keys: {', '.join(_OPTION_KEYS)}) (--options)")
    parser.set_defaults(**options)
    again = parser.parse_args(list(argv))
    again.port = _port(str(again.port))
    return again


def run(argv):
    parser = make_parser()
    args = parser.parse_args(list(argv))
    if args.options and not args.help:
        args = _apply_options_file(parser, args, argv)
    if args.help:
        sys.stdout.write(parser.format_help())
        return 0
    if not args.path:
        raise Usage("the following arguments are required: PATH")
    quiet = args.quiet or args.log_level in ("warning", "error")
    if args.path.startswith("-"):
        raise Usage(f"unrecognized argument: {args.path}")
    try:
        server, url = make_server(args.path, host=args.host, port=args.port, quiet=quiet, cache_dir=args.cache_dir)
    except OSError as e:
        if e.errno == errno.EADDRINUSE:
            raise BadInput(f"port {args.port} on {args.host} is in use (--port: another port, or 0 for a free one)"
                           ) from None
        if e.errno in (errno.EADDRNOTAVAIL, errno.EACCES) or isinstance(e, socket.gaierror):
            raise BadInput(f"cannot listen on {args.host}:{args.port}: {e.strerror or e} (--host, --port)") from None
        raise BadInput(str(e)) from None
    if not _is_loopback(args.host) and args.log_level != "error":
        print(f"gissar: warning: --host {args.host} is not a loopback address: anyone who can reach it can read "
              "the files this view serves", file=sys.stderr)
    print(url, flush=True)
    if args.browser:
        graphical = (sys.platform in ("darwin", "win32") or os.environ.get("DISPLAY")
                     or os.environ.get("WAYLAND_DISPLAY"))
        if graphical:
            try:
                import webbrowser
                # In a thread: a browser that blocks until closed must not hold the server up.
                threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()
            except Exception:  # no browser: the URL is printed
                pass
        elif not quiet:
            # Without a display, webbrowser would run a text-mode browser in this terminal.
            print("gissar view: no display: open the URL above in a browser", file=sys.stderr)
    try:
        server.serve_forever(poll_interval=0.25)
    finally:
        server.server_close()
    return 0


def _raise_signal(signum, frame):
    raise _Signal(signum)


def _one_line(e):
    return " ".join(str(e).split())


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    for signum in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, _raise_signal)
    try:
        return run(argv)
    except Usage as e:
        print(f"gissar: error: {_one_line(e)} (command line)", file=sys.stderr)
        return 2
    except BadInput as e:
        print(f"gissar: error: {_one_line(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 0
    except _Signal as e:
        return 128 + e.signum


if __name__ == "__main__":
    sys.exit(main())
