"""`gissar view` in a real browser (docs/view.md): headless Debian chromium through python3-selenium and
chromedriver, on a corridor catalogue, a simulation and a pose fix this test builds with the real binary.

    python3 tests/view_browser_test.py --gissar build/bin/gissar --source .

Skips only when chromium/chromedriver/selenium are absent and the CI environment variable is unset (in CI a
missing browser is a failure). --screenshot PNG additionally saves the corridor page with a selected pose
(docs/view.png is made so).
"""
import json
import math
import os
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import view_common as vc  # noqa: E402

SCREENSHOT = None


def _selenium():
    try:
        from selenium import webdriver  # noqa: F401
        return True
    except ImportError:
        return False


def _browser_missing():
    if vc.chromium_paths() is None:
        return "chromium or chromedriver not installed (scripts/install-deps.sh installs them)"
    if not _selenium():
        return "python3-selenium not installed (scripts/install-deps.sh installs it)"
    return None


def _inside(point, ring):
    x, y = point
    inside = False
    for (x1, y1), (x2, y2) in zip(ring, ring[1:]):
        if (y1 > y) != (y2 > y) and x < (x2 - x1) * (y - y1) / (y2 - y1) + x1:
            inside = not inside
    return inside


# Pixels of the map's composite canvas inside a pixel polygon: [r, g, b] per pixel (sampled on a grid).
PIXELS_JS = """
const [poly, step] = arguments;
const {context, ratio} = window.gissarView.composite();
const xs = poly.map(p => p[0]), ys = poly.map(p => p[1]);
const inside = (x, y) => { let c = false;
  for (let i = 0, j = poly.length - 1; i < poly.length; j = i++) {
    const [xi, yi] = poly[i], [xj, yj] = poly[j];
    if ((yi > y) !== (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi) c = !c; }
  return c; };
const out = [];
for (let y = Math.floor(Math.min(...ys)); y <= Math.max(...ys); y += step)
  for (let x = Math.floor(Math.min(...xs)); x <= Math.max(...xs); x += step)
    if (inside(x, y)) { const d = context.getImageData(Math.round(x * ratio), Math.round(y * ratio), 1, 1).data;
                        out.push([d[0], d[1], d[2]]); }
return out;
"""


@unittest.skipIf(_browser_missing() is not None and not vc.ci(), _browser_missing() or "")
class BrowserTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        missing = _browser_missing()
        if missing:
            raise AssertionError(f"CI is set but {missing}")
        cls.work = tempfile.mkdtemp(prefix="gissar-view-browser-")
        cls.catalog = vc.build_corridor(os.path.join(cls.work, "corridor"))
        cls.simulation = vc.build_simulate(os.path.join(cls.work, "simulate"))
        cls.fix = vc.build_locate(os.path.join(cls.work, "locate"))
        cls.evaluation = vc.build_evaluate(os.path.join(cls.work, "evaluate"))
        cls.geocoded = vc.build_corridor(os.path.join(cls.work, "geocoded"), missing_one=False, geocode=True)
        cls.scene_simulation = vc.build_scene_simulation(os.path.join(cls.work, "scene"))
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
        browser, driver = vc.chromium_paths()
        options = webdriver.ChromeOptions()
        for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1280,800",
                  "--disable-dev-shm-usage", "--force-device-scale-factor=1", "--no-first-run"):
            options.add_argument(a)
        options.binary_location = browser
        options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
        cls.driver = webdriver.Chrome(service=Service(driver), options=options)
        cls.driver.set_page_load_timeout(60)

    @classmethod
    def tearDownClass(cls):
        cls.driver.quit()
        import shutil
        shutil.rmtree(cls.work, ignore_errors=True)

    def open(self, path):
        server = vc.Server(path)
        self.addCleanup(lambda: self.assertEqual(server.stop(), 0, "gissar view exits 0 on Ctrl-C"))
        self.driver.get_log("browser")  # drop the previous page's messages
        start = time.perf_counter()
        self.driver.get(server.url)
        vc.wait_for(lambda: self.driver.execute_script("return document.body.dataset.ready") != "0", 30)
        seconds = time.perf_counter() - start
        self.assertEqual(self.driver.execute_script("return document.body.dataset.ready"), "1", "page ready")
        return server, seconds

    def assert_no_console_errors(self):
        severe = [e for e in self.driver.get_log("browser") if e.get("level") == "SEVERE"]
        self.assertEqual(severe, [], "no console errors")

    def dataset(self):
        return self.driver.execute_script("return Object.assign({}, document.body.dataset)")

    def pixel_ring(self, ring):
        return [self.driver.execute_script("return window.gissarView.pixelOf(arguments[0], arguments[1])", *p)
                for p in ring]

    def test_corridor(self):
        server, seconds = self.open(self.catalog)
        vc.log(f"corridor page ready in {seconds:.2f} s")
        with open(self.catalog) as f:
            catalog = json.load(f)
        data = self.dataset()
        self.assertEqual(int(data["footprints"]), len(catalog["gissar:poses"]), "one footprint per pose")
        description = self.driver.execute_script("return fetch('/api/view.json').then(r => r.json())")
        statuses = [f["properties"]["status"] for f in description["footprints"]["features"]]
        self.assertEqual(statuses.count("missing"), 1, f"the pose without its image is shown as missing: {statuses}")
        self.assertEqual(description["footprints"]["features"][0]["properties"]["image"].get("geocoded"),
                         "on demand", "a pose without a geocoded image is geocoded on demand")
        self.click_first_footprint(catalog, description)
        if SCREENSHOT:
            self.driver.save_screenshot(SCREENSHOT)

    def test_corridor_geocoded(self):
        """`gissar corridor --geocode`: the page lays the stored geocoded image on the map."""
        self.open(self.geocoded)
        with open(self.geocoded) as f:
            catalog = json.load(f)
        description = self.driver.execute_script("return fetch('/api/view.json').then(r => r.json())")
        first = description["footprints"]["features"][0]["properties"]["image"]
        self.assertEqual(first.get("geocoded"), "stored")
        self.assertEqual(first.get("geotiff"), "/files/" + catalog["gissar:poses"][0]["geocoded"])
        self.click_first_footprint(catalog, description)

    def test_scene_classes(self):
        """A simulation of a scene: its classes drawn as a base layer with a legend; the toggle hides them."""
        self.open(self.scene_simulation)
        vc.wait_for(lambda: self.driver.execute_script("return document.body.dataset.classesLoaded"), 20)
        data = self.dataset()
        self.assertEqual(data.get("classesLoaded"), "1", "the class layer's picture loaded")
        self.assertGreaterEqual(int(data.get("classes", "0")), 2, "the legend names the scene's classes")
        from selenium.webdriver.common.by import By
        legend = self.driver.find_element(By.ID, "class-legend").text
        self.assertIn("forest", legend)
        size = self.driver.execute_script("return window.gissarView.map.getSize()")
        frame = [[0, 0], [size[0] - 1, 0], [size[0] - 1, size[1] - 1], [0, size[1] - 1]]
        before = self.driver.execute_script(PIXELS_JS, frame, 6)
        self.driver.find_element(By.ID, "classes-toggle").click()
        vc.wait_for(lambda: not self.driver.execute_script("return window.gissarView.classLayer.getVisible()"), 5)
        time.sleep(0.5)
        after = self.driver.execute_script(PIXELS_JS, frame, 6)
        changed = sum(1 for a, b in zip(before, after) if a != b)
        vc.log(f"class layer toggle: {changed} of {len(after)} sampled pixels changed")
        self.assertGreater(changed, 20, "the class layer covers part of the map")
        self.assert_no_console_errors()

    def click_first_footprint(self, catalog, description):
        # The first footprint: a point inside it and no other footprint, then a real click there.
        rings = [f["geometry"]["coordinates"][0] for f in description["footprints"]["features"]]
        first = rings[0]
        lon0, lat0 = min(p[0] for p in first), min(p[1] for p in first)
        lon1, lat1 = max(p[0] for p in first), max(p[1] for p in first)
        candidates = [(lon0 + (lon1 - lon0) * i / 20, lat0 + (lat1 - lat0) * j / 20)
                      for i in range(1, 20) for j in range(1, 20)]
        candidates = [c for c in candidates if _inside(c, first) and not any(_inside(c, r) for r in rings[1:])]
        self.assertTrue(candidates, "the first footprint has a part no other covers")
        centre = (sum(c[0] for c in candidates) / len(candidates), sum(c[1] for c in candidates) / len(candidates))
        point = min(candidates, key=lambda c: math.hypot(c[0] - centre[0], c[1] - centre[1]))
        poly = self.pixel_ring(first)
        before = self.driver.execute_script(PIXELS_JS, poly, 3)
        self.assertGreater(len(before), 50, "the footprint covers enough pixels to compare")
        x, y = self.driver.execute_script("return window.gissarView.pixelOf(arguments[0], arguments[1])", *point)
        from selenium.webdriver.common.action_chains import ActionChains
        from selenium.webdriver.common.by import By
        element = self.driver.find_element(By.ID, "map")
        size = element.size
        clicked = time.perf_counter()
        ActionChains(self.driver).move_to_element_with_offset(element, int(x - size["width"] / 2),
                                                              int(y - size["height"] / 2)).click().perform()
        vc.wait_for(lambda: self.driver.execute_script("return document.body.dataset.imageLoaded") != "0", 20)
        shown = time.perf_counter() - clicked
        vc.log(f"reference image shown {shown:.2f} s after the click")
        self.assertEqual(self.dataset().get("selected"), catalog["gissar:poses"][0]["id"])
        self.assertEqual(self.dataset().get("imageLoaded"), "1")
        after = self.driver.execute_script(PIXELS_JS, poly, 3)
        changed = sum(1 for a, b in zip(before, after) if sum(abs(u - v) for u, v in zip(a, b)) > 30)
        vc.log(f"{changed} of {len(after)} sampled pixels inside the first footprint changed")
        self.assertGreater(changed, 0.3 * len(after), "the image covers the footprint")
        self.assert_no_console_errors()

    def test_simulate_mask_toggle(self):
        self.open(self.simulation)
        vc.wait_for(lambda: self.driver.execute_script("return document.body.dataset.imageLoaded") != "0", 20)
        self.assertEqual(self.dataset().get("imageLoaded"), "1", "the simulation's image is on the map")
        size = self.driver.execute_script("return window.gissarView.map.getSize()")
        frame = [[0, 0], [size[0] - 1, 0], [size[0] - 1, size[1] - 1], [0, size[1] - 1]]
        before = self.driver.execute_script(PIXELS_JS, frame, 4)
        from selenium.webdriver.common.by import By
        self.driver.find_element(By.ID, "mask").click()
        vc.wait_for(lambda: self.driver.execute_script("return document.body.dataset.maskShown") == "1", 20)
        after = self.driver.execute_script(PIXELS_JS, frame, 4)
        changed = sum(1 for a, b in zip(before, after) if a != b)
        vc.log(f"mask toggle: {changed} of {len(after)} sampled pixels changed")
        self.assertGreater(changed, 20, "the mask toggle changes pixels")
        self.assert_no_console_errors()

    def test_locate_markers(self):
        self.open(self.fix)
        self.assertEqual(self.dataset()["markers"], "3", "prior, fix and truth")
        roles = self.driver.execute_script(
            "return window.gissarView.markerSource.getFeatures().map(f => f.get('role')).sort()")
        self.assertEqual(roles, ["ellipse95", "fix", "prior", "truth"])
        self.assert_no_console_errors()

    def test_evaluate_scatter(self):
        self.open(self.evaluation)
        with open(self.evaluation) as f:
            records = json.load(f)["trial_records"]
        self.assertEqual(self.dataset()["trials"], str(len(records)), "one point per trial")
        roles = self.driver.execute_script(
            "return window.gissarView.markerSource.getFeatures().map(f => f.get('role'))")
        self.assertIn("truth", roles)
        self.assertIn("success_radius", roles)
        self.assert_no_console_errors()


if __name__ == "__main__":
    argv = vc.parse_args(sys.argv)
    if _browser_missing() and not vc.ci():
        print(f"view_browser_test: skipped: {_browser_missing()} (set CI to make this a failure)")
        sys.exit(77)  # ctest: SKIP_RETURN_CODE
    if "--screenshot" in argv:
        i = argv.index("--screenshot")
        SCREENSHOT = os.path.abspath(argv[i + 1])
        del argv[i:i + 2]
    unittest.main(argv=argv, verbosity=2)
