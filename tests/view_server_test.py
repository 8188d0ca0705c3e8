"""The web server of `gissar view` (docs/view.md, "Security"): every refusal, Range requests, the exit statuses.

    python3 tests/view_server_test.py --gissar build/bin/gissar --source .

Plain HTTP over sockets (http.client and raw requests), against `gissar view PATH --no-browser` run as a user
runs it, on a small corridor catalogue built with the real binary.
"""
import http.client
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import view_common as vc  # noqa: E402


class ServerTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.work = tempfile.mkdtemp(prefix="gissar-view-server-")
        cls.catalog = vc.build_corridor(os.path.join(cls.work, "corridor"))
        cls.dir = os.path.dirname(cls.catalog)
        # Files beside the catalogue that it does not name, and a symlink leading out of the directory.
        cls.secret = os.path.join(cls.work, "secret.txt")
        with open(cls.secret, "w") as f:
            f.write("not to be served\n")
        with open(os.path.join(cls.dir, "unnamed.txt"), "w") as f:
            f.write("beside the catalogue, not named by it\n")
        with open(cls.catalog) as f:
            catalog = json.load(f)
        cls.first = catalog["gissar:poses"][0]
        cls.last = catalog["gissar:poses"][-1]
        # The first pose's quicklook PNG becomes a symlink to the secret: named, but leading out.
        cls.linked = f"db_{cls.first['id']}_quicklook.png"
        os.unlink(os.path.join(cls.dir, cls.linked))
        os.symlink(cls.secret, os.path.join(cls.dir, cls.linked))
        cls.tif = f"db_{cls.first['id']}.tif"
        with open(os.path.join(cls.dir, cls.tif), "rb") as f:
            cls.tif_bytes = f.read()
        cls.server = vc.Server(cls.catalog)

    @classmethod
    def tearDownClass(cls):
        status = cls.server.stop()
        shutil.rmtree(cls.work, ignore_errors=True)
        assert status == 0, f"gissar view exits {status} on Ctrl-C"

    def request(self, method, path, headers=None):
        c = http.client.HTTPConnection("127.0.0.1", self.server.port, timeout=20)
        c.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
        c.putheader("Host", f"127.0.0.1:{self.server.port}")
        for k, v in (headers or {}).items():
            c.putheader(k, v)
        c.endheaders()
        r = c.getresponse()
        body = r.read()
        c.close()
        return r.status, dict(r.getheaders()), body

    def raw(self, data):
        """The status code of a raw request (bytes), or None when the server closed without answering."""
        s = socket.create_connection(("127.0.0.1", self.server.port), timeout=20)
        try:
            s.sendall(data)
            reply = b""
            while b"\r\n" not in reply:
                chunk = s.recv(4096)
                if not chunk:
                    break
                reply += chunk
        except (ConnectionResetError, BrokenPipeError):
            return None
        finally:
            s.close()
        parts = reply.split(b" ", 2)
        return int(parts[1]) if len(parts) > 1 and parts[1].isdigit() else None

    # What is served --------------------------------------------------------------------------------------------
    def test_page_and_description(self):
        status, headers, body = self.request("GET", "/")
        self.assertEqual(status, 200)
        self.assertIn(b"/app/main.js", body)
        self.assertIn("default-src 'self'", headers.get("Content-Security-Policy", ""))
        status, _, body = self.request("GET", "/app/main.js")
        self.assertEqual(status, 200)
        status, headers, body = self.request("GET", "/api/view.json")
        self.assertEqual(status, 200)
        description = json.loads(body)
        self.assertEqual(description["kind"], "corridor")
        self.assertEqual(len(description["footprints"]["features"]), description["poses"])

    def test_named_file_and_head(self):
        status, headers, body = self.request("GET", "/files/" + self.tif)
        self.assertEqual((status, body), (200, self.tif_bytes))
        self.assertEqual(headers.get("Accept-Ranges"), "bytes")
        status, headers, body = self.request("HEAD", "/files/" + self.tif)
        self.assertEqual((status, body, headers.get("Content-Length")), (200, b"", str(len(self.tif_bytes))))

    def test_range_requests(self):
        n = len(self.tif_bytes)
        for header, start, end in (("bytes=0-99", 0, 99), ("bytes=100-", 100, n - 1), ("bytes=-50", n - 50, n - 1),
                                   (f"bytes=10-{n + 1000}", 10, n - 1)):
            status, headers, body = self.request("GET", "/files/" + self.tif, {"Range": header})
            self.assertEqual(status, 206, header)
            self.assertEqual(body, self.tif_bytes[start:end + 1], header)
            self.assertEqual(headers["Content-Range"], f"bytes {start}-{end}/{n}", header)
            self.assertEqual(headers["Content-Length"], str(end - start + 1), header)
        for header in (f"bytes={n}-", f"bytes={n + 5}-{n + 10}", "bytes=50-10", "bytes=0-1,5-9", "bytes=x-y"):
            status, headers, _ = self.request("GET", "/files/" + self.tif, {"Range": header})
            self.assertEqual(status, 416, header)
            self.assertEqual(headers.get("Content-Range"), f"bytes */{n}", header)

    def test_200_concurrent_range_requests_are_all_answered_in_bounded_memory(self):
        """200 clients at once (a barrier releases them together), each asking for its own byte range of the
        GeoTIFF: every one gets its 206 and exactly its bytes; the server's peak RSS (VmHWM) grows by less than
        64 MiB (ranges are streamed in 64 KiB chunks, one thread per connection)."""
        import random
        import threading
        n = len(self.tif_bytes)
        rng = random.Random(7)
        ranges = []
        for _ in range(200):
            start = rng.randrange(0, n - 1)
            ranges.append((start, min(n - 1, start + rng.randrange(1, 1 << 20))))

        def hwm_kib():
            with open(f"/proc/{self.server.proc.pid}/status") as f:
                return next(int(line.split()[1]) for line in f if line.startswith("VmHWM:"))

        before = hwm_kib()
        barrier = threading.Barrier(len(ranges))
        results = [None] * len(ranges)

        def fetch(i):
            start, end = ranges[i]
            barrier.wait(timeout=60)
            try:
                results[i] = self.request("GET", "/files/" + self.tif, {"Range": f"bytes={start}-{end}"})
            except OSError as e:
                results[i] = e

        threads = [threading.Thread(target=fetch, args=(i,)) for i in range(len(ranges))]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=120)
        grown_kib = hwm_kib() - before
        for (start, end), result in zip(ranges, results):
            self.assertIsInstance(result, tuple, f"bytes={start}-{end}: {result!r}")
            status, headers, body = result
            self.assertEqual(status, 206)
            self.assertEqual(headers["Content-Range"], f"bytes {start}-{end}/{n}")
            self.assertEqual(body, self.tif_bytes[start:end + 1])
        self.assertLess(grown_kib, 64 * 1024, f"peak RSS grew by {grown_kib} KiB")
        print(f"200 concurrent range requests: all answered; peak RSS grew by {grown_kib / 1024:.1f} MiB",
              file=sys.stderr)

    def test_rendered_images(self):
        for key in ("hillshade", f"pose_{self.first['id']}"):
            status, headers, body = self.request("GET", f"/render/{key}.json")
            self.assertEqual(status, 200, key)
            extent = json.loads(body)["extent"]
            self.assertTrue(extent[0] < extent[2] and extent[1] < extent[3], key)
            status, headers, body = self.request("GET", f"/render/{key}.png")
            self.assertEqual((status, headers["Content-Type"], body[:4]), (200, "image/png", b"\x89PNG"), key)
        self.assertEqual(self.request("GET", "/render/nothing.png")[0], 404)

    def test_on_demand_geocode_cached(self):
        """A pose without a geocoded image is geocoded on demand (gissar's geocode), cached in the cache
        directory's geocoded/ under a name keyed by the image, never beside the catalogue."""
        key = f"pose_{self.first['id']}"
        status, _, body = self.request("GET", f"/render/{key}.json")
        self.assertEqual(status, 200)
        self.assertEqual(json.loads(body).get("via"), "geocode (on demand, cached)", body)
        cached = os.listdir(os.path.join(self.server.cache, "geocoded"))
        self.assertTrue(any(n.endswith(".tif") for n in cached), cached)
        self.assertFalse([n for n in os.listdir(self.dir) if "geocoded" in n], "nothing written beside it")
        status, _, body = self.request("GET", f"/render/{key}_mask.png")
        self.assertEqual((status, body[:4]), (200, b"\x89PNG"))

    def test_missing_files_listed(self):
        """The pose whose image was deleted is described as missing (the page draws it), not an error."""
        status, _, body = self.request("GET", "/api/view.json")
        self.assertEqual(status, 200)
        features = json.loads(body)["footprints"]["features"]
        missing = {f["properties"]["id"]: f["properties"] for f in features
                   if f["properties"]["status"] == "missing"}
        last = f"db_{self.last['id']}.tif"
        self.assertIn(self.last["id"], missing)
        self.assertIn(last, missing[self.last["id"]]["reason"])

    # Refusals -------------------------------------------------------------------------------------------------
    def test_methods_other_than_get_and_head(self):
        for method in ("POST", "PUT", "DELETE", "PATCH", "OPTIONS", "TRACE", "CONNECT", "PROPFIND"):
            status, headers, _ = self.request(method, "/files/" + self.tif)
            self.assertEqual(status, 405, method)
            self.assertEqual(headers.get("Allow"), "GET, HEAD", method)

    def test_path_traversal(self):
        secret = os.path.relpath(self.secret, self.dir)  # ../secret.txt
        for path in ("/files/" + secret, "/files/../secret.txt", "/files/%2e%2e/secret.txt",
                     "/files/%2E%2E%2Fsecret.txt", "/files/..%2fsecret.txt", "/files/..%5csecret.txt",
                     "/files/%252e%252e/secret.txt", "/app/../../../etc/passwd", "/app/%2e%2e/%2e%2e/etc/passwd",
                     "/files//etc/passwd", "/files/" + self.secret, "/files/.%2e/secret.txt",
                     "/files/db_catalog.json%00.png", "/files/./db_catalog.json", "/files\\..\\secret.txt",
                     "/render/../../secret.txt"):
            status, _, body = self.request("GET", path)
            self.assertIn(status, (400, 403, 404), path)
            self.assertNotIn(b"not to be served", body, path)
        # Absolute-form and non-slash targets.
        self.assertEqual(self.raw(b"GET http://127.0.0.1/etc/passwd HTTP/1.1\r\nHost: x\r\n\r\n") in (400, 403), True)

    def test_symlink_leading_out(self):
        status, _, body = self.request("GET", "/files/" + self.linked)
        self.assertIn(status, (403, 404))
        self.assertNotIn(b"not to be served", body)

    def test_unnamed_file_and_no_listing(self):
        for path in ("/files/unnamed.txt", "/files/route.csv", "/files/", "/files", "/app/", "/render/",
                     "/corridor/", "/db_catalog.json"):
            status, _, body = self.request("GET", path)
            self.assertEqual(status, 404, path)
            self.assertNotIn(b"db_p0000", body, path)

    def test_oversize_request_line_and_headers(self):
        self.assertEqual(self.raw(b"GET /" + b"a" * 9000 + b" HTTP/1.1\r\nHost: x\r\n\r\n"), 414)
        big = b"X-Big: " + b"b" * 20000 + b"\r\n"
        self.assertEqual(self.raw(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n" + big + b"\r\n"), 431)
        many = b"".join(b"X-%d: 1\r\n" % i for i in range(100))
        self.assertEqual(self.raw(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n" + many + b"\r\n"), 431)

    def test_foreign_host_header(self):
        """DNS rebinding: on loopback only the bound address's Host is answered."""
        c = http.client.HTTPConnection("127.0.0.1", self.server.port, timeout=20)
        c.putrequest("GET", "/api/view.json", skip_host=True)
        c.putheader("Host", "attacker.example:80")
        c.endheaders()
        self.assertEqual(c.getresponse().status, 403)
        c.close()

    def test_socket_timeout(self):
        """A client that sends nothing is dropped (the server's socket timeout, 10 s)."""
        s = socket.create_connection(("127.0.0.1", self.server.port), timeout=30)
        s.sendall(b"GET / HTTP/1.1\r\n")
        try:
            self.assertEqual(s.recv(10), b"")  # closed without an answer
        finally:
            s.close()
        self.assertEqual(self.request("GET", "/")[0], 200)  # and the server still serves others


class CommandTest(unittest.TestCase):
    """Exit statuses: bad PATH, port in use (2, one error line), a non-loopback host (warning), SIGTERM."""

    @classmethod
    def setUpClass(cls):
        cls.work = tempfile.mkdtemp(prefix="gissar-view-command-")
        cls.catalog = vc.build_corridor(os.path.join(cls.work, "corridor"), missing_one=False)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.work, ignore_errors=True)

    def test_no_known_kind(self):
        text = os.path.join(self.work, "note.json")
        with open(text, "w") as f:
            f.write('{"hello": 1}\n')
        for path in (text, os.path.join(self.work, "nothing_here"), self.work + "/empty_dir"):
            if path.endswith("empty_dir"):
                os.makedirs(path, exist_ok=True)
            r = vc.run("view", path, "--no-browser", timeout=60)
            self.assertEqual(r.returncode, 2, path)
            lines = r.stderr.strip().splitlines()
            self.assertEqual(len(lines), 1, r.stderr)
            self.assertTrue(lines[0].startswith("gissar: error: "), r.stderr)
            self.assertEqual(r.stdout, "")

    def test_port_in_use(self):
        s = socket.socket()
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        try:
            r = vc.run("view", self.catalog, "--no-browser", "--port", str(s.getsockname()[1]), timeout=60)
        finally:
            s.close()
        self.assertEqual(r.returncode, 2)
        self.assertRegex(r.stderr, r"^gissar: error: port \d+ on 127\.0\.0\.1 is in use")
        self.assertEqual(len(r.stderr.strip().splitlines()), 1)

    def test_directory_and_sigterm(self):
        server = vc.Server(os.path.dirname(self.catalog))
        self.assertEqual(server.proc.poll(), None)
        server.proc.send_signal(signal.SIGTERM)
        self.assertEqual(server.proc.wait(timeout=20), 128 + signal.SIGTERM)
        server.stop()

    def test_non_loopback_host_warns(self):
        proc = subprocess.Popen([vc.ARGS["gissar"], "view", self.catalog, "--no-browser", "--host", "0.0.0.0"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            url = proc.stdout.readline()
            self.assertTrue(url.startswith("http://0.0.0.0:"), url)
            proc.send_signal(signal.SIGINT)
            self.assertEqual(proc.wait(timeout=20), 0)
            self.assertIn("gissar: warning: --host 0.0.0.0 is not a loopback address", proc.stderr.read())
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.stdout.close()
            proc.stderr.close()


class _ServedOutputTest(unittest.TestCase):
    """One output built in a temporary directory (`work`) and served by `gissar view` (`server`) for the
    class's tests; stopped and removed after them."""

    @classmethod
    def serve(cls, prefix, build):
        """Builds the output with build(directory) -> path to serve, in a new temporary directory."""
        cls.work = tempfile.mkdtemp(prefix=prefix)
        served = build(cls.work)
        cls.server = vc.Server(served)
        return served

    @classmethod
    def tearDownClass(cls):
        status = cls.server.stop()
        shutil.rmtree(cls.work, ignore_errors=True)
        assert status == 0, f"gissar view exits {status} on Ctrl-C"


class GeocodedCorridorTest(_ServedOutputTest):
    """`gissar corridor --geocode`: each pose's geocoded image is named in the catalogue and served as is."""

    @classmethod
    def setUpClass(cls):
        cls.catalog = cls.serve("gissar-view-geocoded-", lambda work: vc.build_corridor(
            os.path.join(work, "corridor"), missing_one=False, geocode=True))
        with open(cls.catalog) as f:
            cls.poses = json.load(f)["gissar:poses"]

    def test_stored_geocoded_image_used(self):
        c = http.client.HTTPConnection("127.0.0.1", self.server.port, timeout=30)
        c.request("GET", "/api/view.json")
        description = json.loads(c.getresponse().read())
        for feature, pose in zip(description["footprints"]["features"], self.poses):
            image = feature["properties"]["image"]
            self.assertEqual(image.get("geocoded"), "stored", pose["id"])
            self.assertEqual(image.get("geotiff"), "/files/" + pose["geocoded"])
        first = description["footprints"]["features"][0]["properties"]["image"]
        for url in (first["render_info"], first["geotiff"], first["mask"]):
            c.request("GET", url)
            r = c.getresponse()
            r.read()
            self.assertEqual(r.status, 200, url)
        c.request("GET", first["render_info"])
        info = json.loads(c.getresponse().read())
        self.assertNotIn("via", info, "a stored geocoded image needs no geocode on demand")
        self.assertFalse(os.path.isdir(os.path.join(self.server.cache, "geocoded")))


class SimulationTest(_ServedOutputTest):
    """A `gissar simulate` output: its image and mask geocoded on demand (exact on the simulation's terrain,
    cached), not warped through its GCPs (which keep only the 12 x 12 lattice by default)."""

    @classmethod
    def setUpClass(cls):
        cls.serve("gissar-view-simulate-", lambda work: vc.build_simulate(os.path.join(work, "simulate")) + ".json")

    def test_image_and_mask_geocoded_on_demand(self):
        c = http.client.HTTPConnection("127.0.0.1", self.server.port, timeout=60)
        c.request("GET", "/api/view.json")
        image = json.loads(c.getresponse().read())["image"]
        for key in ("render_info", "mask_info"):
            c.request("GET", image[key])
            r = c.getresponse()
            info = json.loads(r.read())
            self.assertEqual(r.status, 200, key)
            self.assertEqual(info.get("via"), "geocode (on demand, cached)", (key, info))
            extent = info["extent"]
            self.assertTrue(extent[0] < extent[2] and extent[1] < extent[3], (key, extent))
        for key in ("render", "mask"):
            c.request("GET", image[key])
            r = c.getresponse()
            self.assertEqual((r.status, r.read()[:4]), (200, b"\x89PNG"), key)
        c.close()
        self.assertTrue(any(n.endswith(".tif") for n in os.listdir(os.path.join(self.server.cache, "geocoded"))))


if __name__ == "__main__":
    unittest.main(argv=vc.parse_args(sys.argv), verbosity=2)
