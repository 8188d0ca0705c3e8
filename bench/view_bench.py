#!/usr/bin/env python3
"""`gissar view` on a 202-pose corridor in headless Chromium (issue 49: first paint with all footprints <= 2 s,
a reference image on the map <= 1 s after a click).

Builds a real corridor catalogue with the binary: the bundled Andorra DEM, a route along lat 42.55 N from lon
1.45 to 1.70 E, a pose every 205 m, headings 80 and 100 deg (202 poses), 32 x 32 px at 90 m, 1 ray per cell.
Then, twice: without geocoded images (the viewer geocodes a clicked pose on demand) and after `gissar corridor
--geocode` on the same prefix (the poses are complete: only their geocoded images are written), each with a
cold render cache: `gissar view CATALOG --no-browser`, Chromium (selenium, 1280 x 760) loads the page; first
paint = the page's data-ready-ms (navigation start to the map's first rendercomplete with every footprint and
the hillshade drawn); then a real click at the centre of N poses' footprints, each timed by the page
(data-image-ms: click to the rendercomplete with the image drawn) and by selenium (click to data-image-loaded).
A second page load measures first paint with a warm cache.

usage: python3 bench/view_bench.py [--gissar build/bin/gissar] [--clicks 8] [--out DIR] [--json F]
"""
import argparse
import json
import os
import platform
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
DEM = os.path.join(ROOT, "data", "andorra", "andorra_srtm3_dem_filled.tif")


def corridor(binary, prefix, geocode):
    route = prefix + "_route.csv"
    with open(route, "w") as f:
        f.write("lon,lat\n1.45,42.55\n1.70,42.55\n")
    cmd = ["corridor", "--route", route, "--dem", DEM, "--pose-step", "205", "--headings", "80,100",
           "--width", "32", "--height", "32", "--range-spacing", "90", "--azimuth-spacing", "90",
           "--rays-per-cell", "1", "--workers", "2", "--threads", "1", "--quiet", "--out", prefix]
    if geocode:
        cmd.append("--geocode")
    start = time.perf_counter()
    r = subprocess.run([binary, *cmd], capture_output=True, text=True)
    if r.returncode not in (0, 1):
        sys.exit(f"view_bench: gissar corridor failed ({r.returncode}): {r.stderr}")
    return time.perf_counter() - start, "gissar " + " ".join(cmd)


class Viewer:
    def __init__(self, binary, path, cache):
        env = dict(os.environ, GISSAR_VIEW_CACHE=cache)
        self.log = tempfile.TemporaryFile(mode="w+")
        self.proc = subprocess.Popen([binary, "view", path, "--no-browser", "--quiet"], stdout=subprocess.PIPE,
                                     stderr=self.log, text=True, env=env)
        line = self.proc.stdout.readline().strip()
        if not re.match(r"^http://[^/]+:\d+/$", line):
            self.proc.kill()
            self.log.seek(0)
            sys.exit(f"view_bench: gissar view printed {line!r}: {self.log.read()}")
        self.url = line

    def stop(self):
        # SIGTERM (exit 143), not Ctrl-C: a benchmark started in the background has SIGINT ignored.
        self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.log.close()


def wait(predicate, timeout=30.0):
    end = time.time() + timeout
    while time.time() < end:
        v = predicate()
        if v:
            return v
        time.sleep(0.01)
    return predicate()


def measure(driver, binary, catalog, clicks):
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    cache = tempfile.mkdtemp(prefix="gissar-view-bench-cache-")
    viewer = Viewer(binary, catalog, cache)
    try:
        out = {}
        for label in ("cold", "warm"):
            driver.get("about:blank")
            driver.get(viewer.url)
            wait(lambda: driver.execute_script("return document.body.dataset.ready") != "0")
            data = driver.execute_script("return Object.assign({}, document.body.dataset)")
            if data.get("ready") != "1":
                sys.exit(f"view_bench: the page did not become ready: {data}")
            out[f"first_paint_{label}_s"] = int(data["readyMs"]) / 1000.0
            out["footprints"] = int(data["footprints"])
        description = driver.execute_script("return fetch('/api/view.json').then(r => r.json())")
        done = [f for f in description["footprints"]["features"] if f["properties"]["status"] in ("done", "cached")]
        out["geocoded"] = sorted({f["properties"]["image"].get("geocoded") for f in done})
        element = driver.find_element(By.ID, "map")
        size = element.size
        page_ms, seen_s, hit = [], [], []
        step = max(1, len(done) // clicks)
        for feature in done[::step][:clicks]:
            ring = feature["geometry"]["coordinates"][0][:-1]
            lon = sum(p[0] for p in ring) / len(ring)
            lat = sum(p[1] for p in ring) / len(ring)
            x, y = driver.execute_script("return window.gissarView.pixelOf(arguments[0], arguments[1])", lon, lat)
            driver.execute_script("document.body.dataset.imageLoaded = '0'; delete document.body.dataset.imageMs;")
            start = time.perf_counter()
            ActionChains(driver).move_to_element_with_offset(element, int(x - size["width"] / 2),
                                                             int(y - size["height"] / 2)).click().perform()
            wait(lambda: driver.execute_script("return document.body.dataset.imageMs"), 20)
            seen_s.append(time.perf_counter() - start)
            data = driver.execute_script("return Object.assign({}, document.body.dataset)")
            if data.get("imageLoaded") != "1":
                sys.exit(f"view_bench: no image after the click: {data}")
            page_ms.append(int(data["imageMs"]))
            hit.append(data.get("selected"))
        out["click_to_image_s"] = [m / 1000.0 for m in page_ms]
        out["click_to_image_selenium_s"] = seen_s
        out["clicked"] = hit
        return out
    finally:
        viewer.stop()
        shutil.rmtree(cache, ignore_errors=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--gissar", default=os.environ.get("GISSAR_CLI") or os.path.join(ROOT, "build", "bin", "gissar"))
    p.add_argument("--clicks", type=int, default=8)
    p.add_argument("--out", default=None)
    p.add_argument("--json", default=None)
    args = p.parse_args()
    sys.path.insert(0, os.path.join(ROOT, "tests"))
    import view_common as vc
    paths = vc.chromium_paths()
    if paths is None:
        sys.exit("view_bench: chromium and chromedriver are needed (scripts/install-deps.sh)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    options = webdriver.ChromeOptions()
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1280,760",
              "--disable-dev-shm-usage", "--force-device-scale-factor=1", "--no-first-run"):
        options.add_argument(a)
    options.binary_location = paths[0]
    work = args.out or tempfile.mkdtemp(prefix="gissar-view-bench-")
    os.makedirs(work, exist_ok=True)
    driver = webdriver.Chrome(service=Service(paths[1]), options=options)
    try:
        version = driver.capabilities.get("browserVersion")
        prefix = os.path.join(work, "db")
        build_s, command = corridor(args.gissar, prefix, geocode=False)
        with open(prefix + "_catalog.json") as f:
            poses = len(json.load(f)["gissar:poses"])
        on_demand = measure(driver, args.gissar, prefix + "_catalog.json", args.clicks)
        geocode_s, geocode_command = corridor(args.gissar, prefix, geocode=True)
        stored = measure(driver, args.gissar, prefix + "_catalog.json", args.clicks)
    finally:
        driver.quit()
        if args.out is None:
            shutil.rmtree(work, ignore_errors=True)
    def shown(text):
        return text.replace(work + "/", "").replace(ROOT + "/", "")

    result = {"poses": poses, "corridor_command": shown(command), "corridor_s": build_s,
              "geocode_command": shown(geocode_command), "geocode_s": geocode_s,
              "on_demand": on_demand, "stored": stored, "chromium": version, "window": "1280x760",
              "load_average": list(os.getloadavg()), "cores": os.cpu_count(), "machine": platform.machine(),
              "date": time.strftime("%Y-%m-%d")}
    print(f"{poses} poses (corridor {build_s:.1f} s, --geocode afterwards {geocode_s:.1f} s), chromium {version}")
    print("| geocoded images | footprints drawn | first paint cold s | first paint warm s "
          "| click to image median s | max s | selenium median s |")
    print("|---|---|---|---|---|---|---|")
    for label, m in (("on demand", on_demand), ("stored (--geocode)", stored)):
        print(f"| {label} | {m['footprints']} | {m['first_paint_cold_s']:.2f} | {m['first_paint_warm_s']:.2f} | "
              f"{statistics.median(m['click_to_image_s']):.2f} | {max(m['click_to_image_s']):.2f} | "
              f"{statistics.median(m['click_to_image_selenium_s']):.2f} |")
    print(f"load average {', '.join(f'{x:.2f}' for x in result['load_average'])} ({result['cores']} cores)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
