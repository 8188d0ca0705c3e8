"""Shared by tests/view_server_test.py and tests/view_browser_test.py: the inputs `gissar view` is tested on,
built with the real binary (a small corridor on data/andorra, a simulation, a pose fix on data/uavsar), and a
running `gissar view` server."""
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

ARGS = {"gissar": None, "source": None}


def parse_args(argv):
    """--gissar BIN --source DIR (the test's own flags), the rest for unittest."""
    rest = [argv[0]]
    i = 1
    while i < len(argv):
        if argv[i] in ("--gissar", "--source") and i + 1 < len(argv):
            ARGS[argv[i][2:]] = argv[i + 1]
            i += 2
        else:
            rest.append(argv[i])
            i += 1
    here = os.path.dirname(os.path.abspath(__file__))
    ARGS["source"] = ARGS["source"] or os.path.dirname(here)
    ARGS["gissar"] = ARGS["gissar"] or os.environ.get("GISSAR_CLI") or os.path.join(ARGS["source"], "build", "bin",
                                                                                    "gissar")
    return rest


def run(*args, timeout=600, cwd=None):
    return subprocess.run([ARGS["gissar"], *args], capture_output=True, text=True, timeout=timeout, cwd=cwd)


def build_corridor(directory, missing_one=True, geocode=False):
    """A 4-pose corridor (2 poses x headings 90/270, 32 x 32 px): returns the catalogue path. With
    missing_one, the last pose's image is deleted afterwards (shown as missing); with geocode, `--geocode`
    writes each pose's geocoded image."""
    os.makedirs(directory, exist_ok=True)
    route = os.path.join(directory, "route.csv")
    with open(route, "w") as f:
        f.write("lon,lat\n1.55,42.55\n1.57,42.55\n")
    dem = os.path.join(ARGS["source"], "data", "andorra", "andorra_srtm3_dem_filled.tif")
    out = os.path.join(directory, "db")
    r = run("corridor", "--route", route, "--dem", dem, "--pose-step", "1000", "--headings", "90,270",
            "--width", "32", "--height", "32", "--range-spacing", "90", "--azimuth-spacing", "90",
            "--rays-per-cell", "1", "--workers", "2", "--threads", "1", "--quiet", "--out", out,
            *(["--geocode"] if geocode else []))
    if r.returncode != 0:
        raise RuntimeError(f"gissar corridor failed ({r.returncode}): {r.stderr}")
    if missing_one:
        with open(out + "_catalog.json") as f:
            catalog = json.load(f)
        last = catalog["gissar:poses"][-1]["id"]
        os.unlink(f"{out}_{last}.tif")
    return out + "_catalog.json"


def build_simulate(directory):
    """A 60 m simulation of Andorra (heading 0, depression 40: layover and shadow in the mask): its prefix."""
    os.makedirs(directory, exist_ok=True)
    dem = os.path.join(ARGS["source"], "data", "andorra", "andorra_srtm3_dem_filled.tif")
    out = os.path.join(directory, "sim")
    r = run("simulate", "--dem", dem, "--heading", "0", "--depression", "40", "--slant-range", "20000",
            "--range-spacing", "60", "--azimuth-spacing", "60", "--out", out, "--quiet")
    if r.returncode != 0:
        raise RuntimeError(f"gissar simulate failed ({r.returncode}): {r.stderr}")
    return out


def build_scene_simulation(directory):
    """A scene of Andorra with its OpenStreetMap classes (`gissar scene build`) and a small simulation of it:
    the simulation's prefix (its sidecar names the .gscene, whose classes the page draws)."""
    os.makedirs(directory, exist_ok=True)
    data = os.path.join(ARGS["source"], "data", "andorra")
    scene = os.path.join(directory, "andorra")
    r = run("scene", "build", "--dem", os.path.join(data, "andorra_srtm3_dem_filled.tif"), "--vectors",
            os.path.join(data, "andorra_osm.gpkg"), "--out", scene, "--quiet")
    if r.returncode != 0:
        raise RuntimeError(f"gissar scene build failed ({r.returncode}): {r.stderr}")
    out = os.path.join(directory, "sim")
    r = run("simulate", "--scene", scene + ".gscene", "--heading", "0", "--depression", "40", "--slant-range",
            "15000", "--range-spacing", "60", "--azimuth-spacing", "60", "--width", "96", "--height", "96",
            "--rays-per-cell", "1", "--out", out, "--quiet")
    if r.returncode != 0:
        raise RuntimeError(f"gissar simulate --scene failed ({r.returncode}): {r.stderr}")
    return out


def build_locate(directory):
    """The demo's pose fix on UAVSAR SanAnd (prior offset -60, 30, 0 m): the result JSON."""
    os.makedirs(directory, exist_ok=True)
    data = os.path.join(ARGS["source"], "data", "uavsar")
    out = os.path.join(directory, "fix")
    r = run("locate", "--product", os.path.join(data, "SanAnd_129.h5"), "--dem", os.path.join(data, "SanAnd_dem.tif"),
            "--dem-oversample", "4", "--prior-offset-track", "-60,30,0", "--out", out,
            "--composite", out + "_composite.png", "--quiet")
    if r.returncode != 0:
        raise RuntimeError(f"gissar locate failed ({r.returncode}): {r.stderr}")
    return out + ".json"


def build_evaluate(directory, trials=3):
    """A 3-trial Monte-Carlo evaluation of locate on UAVSAR SanAnd: the result JSON."""
    os.makedirs(directory, exist_ok=True)
    data = os.path.join(ARGS["source"], "data", "uavsar")
    out = os.path.join(directory, "ev")
    r = run("evaluate", "--product", os.path.join(data, "SanAnd_129.h5"), "--dem", os.path.join(data, "SanAnd_dem.tif"),
            "--trials", str(trials), "--no-compare", "--out", out, "--quiet")
    if r.returncode != 0:
        raise RuntimeError(f"gissar evaluate failed ({r.returncode}): {r.stderr}")
    return out + ".json"


class Server:
    """`gissar view PATH --no-browser` in the background; .url once it prints it."""

    def __init__(self, path, *extra, cache_dir=None):
        env = dict(os.environ)
        self.cache = cache_dir or tempfile.mkdtemp(prefix="gissar-view-cache-")
        env["GISSAR_VIEW_CACHE"] = self.cache
        self.proc = subprocess.Popen([ARGS["gissar"], "view", path, "--no-browser", "--quiet", *extra],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        line = self.proc.stdout.readline().strip()
        if not re.match(r"^http://[^/]+:\d+/$", line):
            self.proc.kill()
            raise RuntimeError(f"gissar view printed {line!r}: {self.proc.stderr.read()}")
        self.url = line
        self.port = int(line.rsplit(":", 1)[1].rstrip("/"))

    def stop(self):
        """Ctrl-C: returns the exit status (0 expected)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(timeout=20)
        finally:
            self.proc.stdout.close()
            self.proc.stderr.close()
            shutil.rmtree(self.cache, ignore_errors=True)


def chromium_paths():
    """(chromium, chromedriver) or None."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver") or ("/usr/bin/chromedriver" if os.path.exists("/usr/bin/chromedriver")
                                              else None)
    if browser and driver:
        return browser, driver
    return None


def ci():
    return bool(os.environ.get("CI"))


def log(*parts):
    print(*parts, file=sys.stderr, flush=True)


def wait_for(predicate, timeout=20.0, step=0.05):
    end = time.time() + timeout
    while time.time() < end:
        value = predicate()
        if value:
            return value
        time.sleep(step)
    return predicate()
