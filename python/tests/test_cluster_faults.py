"""A cluster that fails (docs/distributed.md "Resuming and faults", docs/robustness.md "Clusters").

`gissar corridor` and gissar.distributed_evaluate against: a scheduler nobody listens at (a clear error within
30 s), a worker killed by its nanny at its memory limit (that pose failed with the reason, the others done), a
scheduler that dies mid-run (a clear error, the finished poses kept, a re-run resumes), two runs on one prefix
at once (the second refused by the prefix lock), and a truncated or hand-edited catalogue (set aside, never
overwritten silently, and rebuilt from the per-pose records).
"""
import glob
import json
import os
import socket
import subprocess
import sys
import threading
import time
import warnings

import pytest

import gissar
from gissar import distributed as gd

distributed = pytest.importorskip("distributed")

ROOT = os.environ.get("GISSAR_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
DEM = os.path.join(ROOT, "data", "andorra", "andorra_srtm3_dem_filled.tif")
# Four poses along lat 42.60 at heading 80 deg: the first one's 64 x 64 px footprint leaves the DEM (skipped),
# the other three are simulated (see test_corridor.py for the geometry).
ROUTE = [(1.42, 42.60), (1.61, 42.60)]
IMAGE = dict(width=64, height=64, range_spacing_m=90.0, azimuth_spacing_m=90.0, rays_per_cell=1.0,
             depression_deg=40.0)
ARGS = dict(dem=DEM, pose_step_m=4000.0, headings_deg=[80.0], threads=1, progress=None, **IMAGE)
# The long corridor of test_corridor.py (26 poses to simulate): long enough to lose its scheduler mid-run.
LONG_ROUTE_CSV = "lon,lat\n1.42,42.60\n1.61,42.60\n1.80,42.60\n"
LONG_FLAGS = ["--dem", DEM, "--pose-step", "2000", "--headings", "80,100", "--width", "64", "--height", "64",
              "--range-spacing", "90", "--azimuth-spacing", "90", "--rays-per-cell", "1", "--depression", "40"]


def cli(*args, timeout=300):
    return subprocess.run([os.environ["GISSAR_CLI"], "corridor", *args], capture_output=True, text=True,
                          timeout=timeout)


def closed_port():
    """A loopback port nobody listens at (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def statuses(catalog):
    return {p["id"]: p["status"] for p in catalog["gissar:poses"]}


def temporaries(directory):
    return [n for n in os.listdir(directory) if n.startswith(".gs-")]


@pytest.mark.skipif("GISSAR_CLI" not in os.environ, reason="needs the gissar executable (GISSAR_CLI)")
def test_an_unreachable_scheduler_is_a_clear_error_within_30_s(tmp_path):
    import gissar.distributed_evaluate as de
    address = f"tcp://127.0.0.1:{closed_port()}"
    route = tmp_path / "route.csv"
    route.write_text(LONG_ROUTE_CSV)
    started = time.monotonic()
    # The command line and the distributed evaluate at once (each waits 20 s for the scheduler).
    run = subprocess.Popen([os.environ["GISSAR_CLI"], "corridor", "--route", str(route), *LONG_FLAGS,
                            "--scheduler", address, "--quiet", "--out", str(tmp_path / "db")],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    with pytest.raises(gissar.IoError, match="cannot connect to the Dask scheduler") as caught:
        de.evaluate(dem=DEM, trials=2, seed=1, scheduler=address)
    assert isinstance(caught.value, OSError) and address in str(caught.value)
    out, err = run.communicate(timeout=60)
    assert time.monotonic() - started < 30.0
    assert run.returncode == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gissar: error: cannot connect to the Dask scheduler"), err
    assert address in lines[0]
    assert os.listdir(tmp_path) == ["route.csv"], "nothing written"


def test_a_worker_killed_at_its_memory_limit_fails_that_pose_and_the_others_finish(client, tmp_path):
    """A worker plugin makes the worker that starts pose p0002_h080 allocate until its nanny kills it at the
    worker memory limit (a real kill: RSS over 95 % of 400 MiB); the scheduler gives the pose to the other worker
    (allowed_failures=1), which dies the same way. That pose is failed with the reason, the others are done,
    and a re-run on a healthy cluster simulates exactly that pose."""
    from distributed import Client, LocalCluster, WorkerPlugin

    class Hog(WorkerPlugin):
        name = "gissar-test-memory-hog"

        def transition(self, key, start, finish, **kwargs):
            if finish == "executing" and "gissar-pose-p0002_h080-" in str(key):
                hold = []
                while True:  # until the nanny kills this process at its memory limit
                    hold.append(bytearray(b"x" * (32 << 20)))

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, memory_limit="400MiB", scheduler_kwargs={"allowed_failures": 1})
    hog_client = Client(cluster)
    try:
        hog_client.wait_for_workers(2, timeout=120)
        hog_client.register_worker_plugin(Hog())
        catalog = gd.build_corridor(ROUTE, out_prefix=str(tmp_path / "m"), client=hog_client, retries=0, **ARGS)
        hog_client.wait_for_workers(2, timeout=120)  # the nannies restarted the killed workers
    finally:
        hog_client.close()
        cluster.close()
    assert statuses(catalog) == {"p0000_h080": "skipped", "p0001_h080": "done", "p0002_h080": "failed",
                                 "p0003_h080": "done"}
    failed = next(p for p in catalog["gissar:poses"] if p["status"] == "failed")
    assert failed["reason"].startswith("KilledWorker: the worker process died each time it simulated this pose "
                                       "(2 attempts): killed by its nanny at the worker memory limit of 400 MiB per "
                                       "worker"), failed["reason"]
    assert not glob.glob(str(tmp_path / "m_p0002_h080*")), "nothing of the killed pose"
    assert temporaries(tmp_path) == []
    with open(tmp_path / "m_index.csv") as f:
        assert "p0002_h080" in f.read()
    again = gd.build_corridor(ROUTE, out_prefix=str(tmp_path / "m"), client=client, **ARGS)
    s = again["gissar:summary"]
    assert (s["simulated"], s["cached"], s["failed"], s["done"]) == (1, 2, 0, 3), s


@pytest.mark.skipif("GISSAR_CLI" not in os.environ, reason="needs the gissar executable (GISSAR_CLI)")
def test_a_scheduler_that_dies_mid_run_ends_the_command_and_a_rerun_resumes(client, tmp_path):
    """A scheduler and two workers in their own processes; the scheduler is killed (SIGKILL) once three poses
    are done. The command exits 2 with one line saying so and how to resume; the catalogue lists the finished
    poses as done and the rest as not run; a re-run on another cluster simulates only those."""
    python = sys.executable
    scheduler_file = tmp_path / "scheduler.json"
    logs = open(tmp_path / "cluster.log", "w")
    scheduler = subprocess.Popen([python, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port",
                                  "0", "--no-dashboard", "--scheduler-file", str(scheduler_file)],
                                 stdout=logs, stderr=logs)
    workers = None
    try:
        deadline = time.monotonic() + 60
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(0.2)  # the file is written whole before the scheduler listens; read it once complete
        address = json.loads(scheduler_file.read_text())["address"]
        workers = subprocess.Popen([python, "-m", "distributed.cli.dask_worker", address, "--nworkers", "2",
                                    "--nthreads", "1", "--no-dashboard", "--death-timeout", "30"],
                                   stdout=logs, stderr=logs)
        from distributed import Client
        with Client(address, timeout="30s") as probe:
            probe.wait_for_workers(2, timeout=120)
        route = tmp_path / "route.csv"
        route.write_text(LONG_ROUTE_CSV)
        prefix = str(tmp_path / "out" / "c")
        os.mkdir(tmp_path / "out")
        run = subprocess.Popen([os.environ["GISSAR_CLI"], "corridor", "--route", str(route), *LONG_FLAGS,
                                "--scheduler", address, "--threads", "1", "--quiet", "--out", prefix],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 120
        while len(glob.glob(prefix + "_*_done.json")) < 3 and time.monotonic() < deadline and run.poll() is None:
            time.sleep(0.02)
        assert run.poll() is None, "the corridor ended before its scheduler was killed"
        scheduler.kill()
        killed = time.monotonic()
        out, err = run.communicate(timeout=120)
        assert time.monotonic() - killed < 30.0
    finally:
        scheduler.kill()
        scheduler.wait()
        if workers is not None:
            workers.terminate()
            workers.wait(timeout=60)
        logs.close()
    assert run.returncode == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gissar: error: lost the Dask scheduler mid-run"), err
    assert "poses are done and kept" in lines[0] and "run the same command again" in lines[0]
    with open(prefix + "_catalog.json") as f:
        catalog = json.load(f)
    done = {p["id"] for p in catalog["gissar:poses"] if p["status"] == "done"}
    not_run = {p["id"] for p in catalog["gissar:poses"] if p.get("reason", "").startswith("not run: the Dask "
                                                                                        "scheduler")}
    assert len(done) >= 3 and len(done) + len(not_run) == 26, (len(done), len(not_run))
    # Workers that were simulating when their scheduler died finish that pose (its files and marker appear
    # after the catalogue was written); the workers were stopped above, so the markers now are final.
    markers = {os.path.basename(m)[2:-len("_done.json")] for m in glob.glob(prefix + "_*_done.json")}
    assert done <= markers and len(markers) < 26
    # The same command on a new cluster: only the poses without a marker are simulated (a worker stopped
    # mid-pose left temporaries, which that pose's simulation sweeps).
    again = gd.build_corridor(os.fspath(route), out_prefix=prefix, dem=DEM, pose_step_m=2000.0,
                              headings_deg=[80.0, 100.0], client=client, threads=1, progress=None, **IMAGE)
    s = again["gissar:summary"]
    assert (s["done"], s["cached"], s["simulated"], s["failed"]) == (26, len(markers), 26 - len(markers), 0), s
    assert temporaries(tmp_path / "out") == []


def test_two_runs_on_one_prefix_the_second_is_refused(client, tmp_path):
    """The first run holds the prefix's lock from before its cluster starts until its catalogue is written; its
    progress callback keeps it mid-run while a second run on the same prefix is tried."""
    prefix = str(tmp_path / "two")
    outcome = {}
    running, second_tried = threading.Event(), threading.Event()

    def progress(stage, done, total):
        running.set()
        second_tried.wait(timeout=120)

    def first():
        try:
            outcome["catalog"] = gd.build_corridor(ROUTE, out_prefix=prefix, client=client,
                                                   **dict(ARGS, progress=progress))
        except BaseException as e:  # noqa: B902 (reported below)
            outcome["error"] = e

    thread = threading.Thread(target=first)
    thread.start()
    try:
        assert running.wait(timeout=120), "the first run never reported progress"
        with pytest.raises(gissar.IoError, match="another gissar run is writing outputs with this prefix"):
            gd.build_corridor(ROUTE, out_prefix=prefix, client=client, **ARGS)
    finally:
        second_tried.set()
        thread.join(timeout=300)
    assert "error" not in outcome, outcome.get("error")
    s = outcome["catalog"]["gissar:summary"]
    assert (s["done"], s["failed"]) == (3, 0), s
    assert temporaries(tmp_path) == [], "the lock file exists only while a run holds it"
    # Once the first run is over, the prefix is free.
    assert gd.build_corridor(ROUTE, out_prefix=prefix, client=client, **ARGS)["gissar:summary"]["cached"] == 3


def test_a_truncated_or_edited_catalogue_is_set_aside_and_rebuilt(client, tmp_path):
    prefix = str(tmp_path / "cat")
    path = prefix + "_catalog.json"
    first = gd.build_corridor(ROUTE, out_prefix=prefix, client=client, **ARGS)
    assert first[gd.CHECKSUM_KEY] == gd._catalogue_checksum(first)
    with open(path) as f:
        assert json.load(f)[gd.CHECKSUM_KEY] == first[gd.CHECKSUM_KEY]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an intact catalogue: no warning
        gd.build_corridor(ROUTE, out_prefix=prefix, client=client, **ARGS)
    assert gd.catalogue_damage(path) is None
    text = open(path).read()
    damaged = {"truncated or not JSON": text[: len(text) // 2]}
    edited = json.loads(text)
    edited["gissar:poses"][1]["status"] = "skipped"
    damaged["edited since gissar wrote it"] = json.dumps(edited, indent=2)
    for kind, content in damaged.items():
        with open(path, "w") as f:
            f.write(content)
        assert gd.catalogue_damage(path).startswith(kind)
        with pytest.warns(gissar.GissarWarning, match=f"the catalogue was {kind}.*kept as cat_catalog.json.damaged-"):
            rebuilt = gd.build_corridor(ROUTE, out_prefix=prefix, client=client, **ARGS)
        assert statuses(rebuilt) == statuses(first)
        assert rebuilt["gissar:summary"]["simulated"] == 0
        assert gd.catalogue_damage(path) is None
        kept = sorted(glob.glob(path + ".damaged-*"), key=os.path.getmtime)[-1]
        assert open(kept).read() == content, "the damaged catalogue is kept as it was"
    assert len(glob.glob(path + ".damaged-*")) == 2
    # A catalogue written before the checksum existed counts as intact.
    old = json.loads(open(path).read())
    del old[gd.CHECKSUM_KEY]
    with open(path, "w") as f:
        json.dump(old, f)
    assert gd.catalogue_damage(path) is None


@pytest.mark.skipif("GISSAR_CLI" not in os.environ, reason="needs the gissar executable (GISSAR_CLI)")
def test_the_command_line_says_a_damaged_catalogue_was_set_aside_in_one_warning_line(client, tmp_path):
    route = tmp_path / "route.csv"
    route.write_text("lon,lat\n1.42,42.60\n1.61,42.60\n")
    flags = ["--route", str(route), "--dem", DEM, "--pose-step", "4000", "--headings", "80", "--width", "64",
             "--height", "64", "--range-spacing", "90", "--azimuth-spacing", "90", "--rays-per-cell", "1",
             "--depression", "40", "--scheduler", client.scheduler.address, "--threads", "1", "--quiet",
             "--out", str(tmp_path / "c")]
    assert cli(*flags).returncode == 0
    (tmp_path / "c_catalog.json").write_text("{\"type\": \"Coll")
    run = cli(*flags)
    assert run.returncode == 0, run.stderr
    warned = [line for line in run.stderr.splitlines() if "catalogue" in line]
    assert len(warned) == 1 and warned[0].startswith("gissar: warning: the catalogue was truncated or not JSON"), \
        run.stderr
