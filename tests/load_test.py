"""Load: 50 `gissar simulate` runs started at once in one directory, distinct prefixes, one shared memory budget
(docs/robustness.md "Load: many runs at once"; issue "Reliability, round three", item 7).

The budget is set so that about four runs fit at once; the runs share it through one ledger file
(GISSAR_MEMORY_LEDGER, this test's own, so other tests running beside it do not count). Every run must
succeed (those that find the budget full wait for it) and write the images the same run writes alone; the
ledger never holds more than the budget; some runs did wait; nothing is left behind.

Usage: load_test.py GISSAR_BINARY SOURCE_DIR
"""
import json
import os
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np
from osgeo import gdal

RUNS = 50


def main():
    binary, source = sys.argv[1], sys.argv[2]
    dem = os.path.join(source, "data", "andorra", "andorra_srtm3_dem_filled.tif")
    work = tempfile.mkdtemp(prefix="gissar-load-")
    ledger = os.path.join(work, "memory.ledger")
    env = dict(os.environ, GISSAR_MEMORY_LEDGER=ledger)

    def args(i, budget):
        # Distinct runs: heading, depression and seed vary with i.
        return [binary, "simulate", "--dem", dem, "--heading", str(7 * i % 360), "--depression", str(35 + i % 10),
                "--width", "160", "--height", "160", "--range-spacing", "60", "--azimuth-spacing", "60",
                "--speckle-looks", "4", "--seed", str(i), "--max-memory", str(budget), "--quiet"]

    alone_dir, many_dir = os.path.join(work, "alone"), os.path.join(work, "many")
    os.mkdir(alone_dir)
    os.mkdir(many_dir)
    # One at a time (the default budget: it changes no pixel); each run's need, from its sidecar.
    started = time.monotonic()
    needs = []
    for i in range(RUNS):
        run = subprocess.run(args(i, "8G") + ["--out", os.path.join(alone_dir, f"run{i:02d}")],
                             capture_output=True, text=True, env=env, timeout=300)
        assert run.returncode == 0, (i, run.stderr)
        with open(os.path.join(alone_dir, f"run{i:02d}.json")) as f:
            needs.append(json.load(f)["memory_reserved_bytes"])
    alone_s = time.monotonic() - started
    assert min(needs) > 0, needs
    budget = int(4.5 * max(needs))  # at least four runs fit at once
    print(f"load: one run needs {min(needs) / 2 ** 20:.1f}-{max(needs) / 2 ** 20:.1f} MiB; budget "
          f"{budget / 2 ** 20:.1f} MiB for {RUNS} runs at once")

    # The ledger, sampled while the 50 runs go: never more than the budget.
    peak = {"bytes": 0, "entries": 0}
    stop = threading.Event()

    def watch():
        while not stop.is_set():
            try:
                with open(ledger) as f:
                    rows = [line.split() for line in f if line.strip()]
                held = sum(int(r[3]) for r in rows if len(r) == 4)
                peak["bytes"] = max(peak["bytes"], held)
                peak["entries"] = max(peak["entries"], len(rows))
            except (OSError, ValueError, IndexError):
                pass
            time.sleep(0.005)

    watcher = threading.Thread(target=watch)
    watcher.start()
    started = time.monotonic()
    procs = [subprocess.Popen(args(i, budget) + ["--out", os.path.join(many_dir, f"run{i:02d}")],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
             for i in range(RUNS)]
    results = [(p.wait(timeout=600), p.stdout.read(), p.stderr.read()) for p in procs]
    many_s = time.monotonic() - started
    stop.set()
    watcher.join()

    failures = [(i, rc, err) for i, (rc, _, err) in enumerate(results) if rc != 0]
    assert not failures, failures[:3]
    assert peak["bytes"] <= budget, (peak, budget)
    assert 2 <= peak["entries"] <= budget // min(needs), (peak, budget, needs)
    waited = []
    for i in range(RUNS):
        name = f"run{i:02d}"
        with open(os.path.join(many_dir, name + ".json")) as f:
            timings = json.load(f).get("timings_s", {})
        waited.append(timings.get("memory_wait", 0.0))
        for suffix in (".tif", "_mask.tif"):
            a = gdal.Open(os.path.join(alone_dir, name + suffix))
            b = gdal.Open(os.path.join(many_dir, name + suffix))
            assert a.RasterCount == b.RasterCount, (name, suffix)
            for band in range(1, a.RasterCount + 1):
                x, y = a.GetRasterBand(band).ReadAsArray(), b.GetRasterBand(band).ReadAsArray()
                assert np.array_equal(x, y, equal_nan=True), (name, suffix, band)
    assert sum(1 for w in waited if w > 0) >= RUNS // 2, waited
    leftovers = [n for n in os.listdir(many_dir) if n.startswith(".gs-")]
    assert leftovers == [], leftovers
    with open(ledger) as f:
        assert f.read().strip() == "", "every reservation released"
    print(f"load: {RUNS} runs one at a time {alone_s:.1f} s; at once {many_s:.1f} s, all succeeded with the same "
          f"images; at most {peak['entries']} held the budget ({peak['bytes'] / 2 ** 20:.1f} of "
          f"{budget / 2 ** 20:.1f} MiB); {sum(1 for w in waited if w > 0)} waited, longest {max(waited):.1f} s")
    subprocess.run(["rm", "-rf", work])


if __name__ == "__main__":
    main()
