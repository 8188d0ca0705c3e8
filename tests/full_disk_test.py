"""A full disk, for real (issue 50, item 1; docs/robustness.md "A full disk"): every command that writes meets
ENOSPC at any point of its writing with exit 2, one line `gissar: error: ...` naming the final output and
"no space", the earlier outputs of the same prefix byte-identical, no `.gs-*` temporary left; a corridor
database stopped by a full disk completes when re-run with room, its catalogue intact.

The script re-executes itself in `unshare --user --map-root-user --mount` and mounts a 64 MiB tmpfs there.
For each command: one run with room (its outputs are "the earlier outputs", SHA-256 recorded), then the same
command on the same prefix with only F bytes free (a filler file takes the rest) for F in a sweep from 0 up
to the size of its outputs. Each run either succeeds or fails as promised; at least one F must fail.

Usage: full_disk_test.py GISSAR_BINARY SOURCE_DIR   (exit 77: no user namespace here, skipped)
"""
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

INNER = "GISSAR_FULL_DISK_INNER"
TMPFS_SIZE = 64 << 20
SWEEP = [0, 4 << 10, 8 << 10, 16 << 10, 32 << 10, 64 << 10, 128 << 10, 256 << 10, 1 << 20, 4 << 20, 16 << 20]

failures = []
report = []


def fail(what):
    failures.append(what)
    print("FAIL: " + what, flush=True)


def outer():
    if shutil.which("unshare") is None:
        print("skipped: no `unshare` here")
        sys.exit(77)
    probe = subprocess.run(["unshare", "--user", "--map-root-user", "--mount", "true"], capture_output=True,
                           text=True)
    if probe.returncode != 0:
        print("skipped: cannot make a user and mount namespace: " + probe.stderr.strip())
        sys.exit(77)
    env = dict(os.environ, **{INNER: "1"})
    sys.exit(subprocess.run(["unshare", "--user", "--map-root-user", "--mount", sys.executable,
                             os.path.abspath(__file__)] + sys.argv[1:], env=env).returncode)


def sha(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def snapshot(disk):
    return {name: sha(os.path.join(disk, name)) for name in sorted(os.listdir(disk)) if name != "filler"}


def free_bytes(disk):
    st = os.statvfs(disk)
    return st.f_bavail * st.f_frsize


def leave_free(disk, amount):
    """Fills the tmpfs so that `amount` bytes (a multiple of its block) are left."""
    filler = os.path.join(disk, "filler")
    if os.path.exists(filler):
        os.unlink(filler)
    take = free_bytes(disk) - amount
    if take > 0:
        fd = os.open(filler, os.O_WRONLY | os.O_CREAT, 0o600)
        try:
            os.posix_fallocate(fd, 0, take)
        finally:
            os.close(fd)
    left = free_bytes(disk)
    if left != amount:
        fail(f"could not leave {amount} bytes free on the tmpfs ({left} left)")


def clear(disk):
    for name in os.listdir(disk):
        path = os.path.join(disk, name)
        shutil.rmtree(path) if os.path.isdir(path) else os.unlink(path)


def run(args, env=None):
    return subprocess.run(args, capture_output=True, text=True, timeout=300, env=env)


def check_failure(label, p, disk, prefix_name, free):
    """A failed run: exit 2 and one line naming an output of the prefix and 'no space'."""
    lines = p.stderr.splitlines()
    ok = True
    if p.returncode != 2:
        fail(f"{label} F={free}: exit {p.returncode}, not 2: {p.stderr.strip()[-600:]}")
        ok = False
    elif len(lines) != 1 or not lines[0].startswith("gissar: error:"):
        fail(f"{label} F={free}: stderr is not one 'gissar: error:' line: {p.stderr.strip()[-600:]}")
        ok = False
    else:
        line = lines[0]
        if "no space" not in line.lower():
            fail(f"{label} F={free}: no 'no space' in: {line}")
            ok = False
        if os.path.join(disk, prefix_name) not in line:
            fail(f"{label} F={free}: the output path {os.path.join(disk, prefix_name)}* not named in: {line}")
            ok = False
        if ".gs-" in line:
            fail(f"{label} F={free}: a temporary named in: {line}")
            ok = False
    return ok


def sweep_command(label, args, disk, prefix_name, ok_status=(0,)):
    clear(disk)
    t0 = time.time()
    first = run(args)
    if first.returncode not in ok_status:
        fail(f"{label}: the run with room failed ({first.returncode}): {first.stderr.strip()[-600:]}")
        return
    earlier = snapshot(disk)
    if not earlier:
        fail(f"{label}: no output written")
        return
    size = sum(os.path.getsize(os.path.join(disk, n)) for n in earlier)
    failed = []
    example = ""
    for free in [f for f in SWEEP if f < size + (4 << 10)]:
        leave_free(disk, free)
        p = run(args)
        left = [n for n in os.listdir(disk) if n.startswith(".gs-")]
        if left:
            fail(f"{label} F={free}: temporaries left: {left}")
        if p.returncode in ok_status:
            now = snapshot(disk)
            if set(now) != set(earlier):
                fail(f"{label} F={free}: a successful run wrote {sorted(set(now) ^ set(earlier))}")
            earlier = now
            continue
        failed.append(free)
        example = p.stderr.strip()
        if check_failure(label, p, disk, prefix_name, free):
            now = snapshot(disk)
            if now != earlier:
                changed = sorted(n for n in set(now) | set(earlier) if now.get(n) != earlier.get(n))
                fail(f"{label} F={free}: earlier outputs changed or files added: {changed}")
    if not failed:
        fail(f"{label}: no free-space amount made it fail (outputs {size} bytes)")
    report.append(f"{label}: outputs {len(earlier)} files {size} B; failed at F = "
                  f"{', '.join(human(f) for f in failed)}; {time.time() - t0:.1f} s; e.g. {example}")
    clear(disk)


def human(n):
    if isinstance(n, str):
        return n
    return f"{n >> 20} MiB" if n >= 1 << 20 else f"{n >> 10} KiB" if n >= 1 << 10 else f"{n}"


def corridor(gissar, source, disk, route):
    """Fresh database with F free: exit 0 or a full-disk failure; then with room, the re-run completes it."""
    dem = os.path.join(source, "data/andorra/andorra_srtm3_dem_filled.tif")
    env = dict(os.environ)
    args = [gissar, "corridor", "--route", route, "--dem", dem, "--pose-step", "1000", "--headings", "0",
            "--width", "48", "--height", "48", "--depression", "40", "--slant-range", "8000", "--workers", "1",
            "--threads", "1", "--quiet", "--out", os.path.join(disk, "db")]
    sys.path.insert(0, os.environ.get("PYTHONPATH", "").split(os.pathsep)[0])
    from gissar.distributed import catalogue_damage
    t0 = time.time()
    failed = []
    example = ""
    for free in [0, 16 << 10, 96 << 10]:
        clear(disk)
        leave_free(disk, free)
        p = run(args, env)
        left = [n for n in os.listdir(disk) if n.startswith(".gs-")]
        if left:
            fail(f"corridor F={free}: temporaries left: {left}")
        if p.returncode != 0:
            failed.append(free)
            example = p.stderr.strip()
            print(f"  corridor F={human(free)}: {example}", flush=True)
            check_failure("corridor", p, disk, "db", free)
        os.unlink(os.path.join(disk, "filler"))
        again = run(args, env)
        if again.returncode != 0:
            fail(f"corridor F={free}: the re-run with room failed ({again.returncode}): {again.stderr.strip()[-600:]}")
            continue
        catalogue = os.path.join(disk, "db_catalog.json")
        damage = catalogue_damage(catalogue)
        if damage is not None or not os.path.exists(catalogue):
            fail(f"corridor F={free}: catalogue after the re-run: {damage or 'missing'}")
            continue
        with open(catalogue) as f:
            entries = json.load(f)
        text = json.dumps(entries)
        for pose in ("p0000_h000", "p0001_h000"):
            if not os.path.exists(os.path.join(disk, f"db_{pose}_done.json")) or pose not in text:
                fail(f"corridor F={free}: pose {pose} not complete after the re-run")
    # The complete database run again with no room: nothing to simulate, the catalogue and index rewritten
    # (or the run fails as promised, the earlier ones byte-identical).
    earlier = snapshot(disk)
    leave_free(disk, 0)
    p = run(args, env)
    if [n for n in os.listdir(disk) if n.startswith(".gs-")]:
        fail("corridor, complete, F=0: temporaries left")
    if p.returncode != 0:
        failed.append("0 (complete database)")
        print(f"  corridor complete F=0: {p.stderr.strip()}", flush=True)
        if check_failure("corridor (complete)", p, disk, "db", 0) and snapshot(disk) != earlier:
            fail("corridor, complete, F=0: the earlier outputs changed")
    if catalogue_damage(os.path.join(disk, "db_catalog.json")) is not None:
        fail("corridor, complete, F=0: catalogue damaged")
    if not failed:
        fail("corridor: no free-space amount made it fail")
    report.append(f"corridor: failed at F = {', '.join(human(f) for f in failed)}, each completed by a re-run; "
                  f"{time.time() - t0:.1f} s; e.g. {example}")
    clear(disk)


def inner(gissar, source):
    import numpy as np
    from osgeo import gdal
    gdal.UseExceptions()
    gissar = os.path.abspath(gissar)
    top = tempfile.mkdtemp(prefix="gissar_full_disk_")
    try:
        work = os.path.join(top, "work")
        disk = os.path.join(top, "disk")
        os.makedirs(work)
        os.makedirs(disk)
        mount = run(["mount", "-t", "tmpfs", "-o", f"size={TMPFS_SIZE}", "tmpfs", disk])
        if mount.returncode != 0:
            print("skipped: cannot mount a tmpfs in the namespace: " + mount.stderr.strip())
            return 77
        try:
            return inner_on(gissar, source, work, disk, np, gdal)
        finally:
            run(["umount", disk])
    finally:
        shutil.rmtree(top, ignore_errors=True)


def inner_on(gissar_built, source, work, disk, np, gdal):
    # A copy of the binary: a concurrent rebuild relinking it must not fail a run half-way through the sweep.
    gissar = os.path.join(work, "gissar")
    shutil.copy2(gissar_built, gissar)
    dem = os.path.join(source, "data/andorra/andorra_srtm3_dem_filled.tif")
    uavsar = os.path.join(source, "data/uavsar")
    w = lambda name: os.path.join(work, name)
    d = lambda name: os.path.join(disk, name)
    small = ["--dem", dem, "--depression", "40", "--range-spacing", "400", "--azimuth-spacing", "400"]
    # Inputs, outside the tmpfs.
    for args in (["simulate"] + small + ["--heading", "0", "--out", w("a")],
                 ["simulate"] + small + ["--heading", "10", "--out", w("b")],
                 ["simulate"] + small + ["--heading", "0", "--coherent", "--wavelength", "0.031", "--out", w("c")],
                 ["simulate", "--dem", dem, "--heading", "0", "--depression", "40", "--slant-range", "10000",
                  "--range-spacing", "60", "--azimuth-spacing", "60", "--width", "96", "--height", "96",
                  "--out", w("l")]):
        p = run([gissar] + args + ["--quiet"])
        if p.returncode != 0:
            fail(f"making the inputs: {args}: {p.stderr}")
            return 1
    with open(w("m.csv"), "w") as f:
        f.write("x1,y1,x2,y2\n201.1928,459.1345,257.5498,290.3027\n586.2530,637.7226,526.1969,678.8616\n"
                "252.9946,880.4800,145.7588,665.9560\n663.8595,695.3968,571.8048,777.0798\n"
                "543.8155,402.7325,574.6005,471.2878\n398.3509,755.0147,317.1414,664.6256\n"
                "548.1761,612.2923,497.7031,657.6045\n500.5640,926.9936,334.8127,904.5212\n"
                "102.9936,635.0824,102.7296,390.2036\n504.9125,545.6704,488.9249,556.2186\n"
                "603.1741,986.0136,409.3357,982.3369\n509.2588,539.6465,496.6571,545.7471\n"
                "788.6135,410.4373,788.5699,613.7752\n650.5381,949.7060,458.7368,1008.7201\n"
                "372.7500,956.0723,215.2716,835.1379\n243.5055,184.0169,397.1649,91.3782\n")
    with open(w("p.csv"), "w") as f:
        f.write("X,Y,Z,x,y\n0,0,0,100,100\n100,0,5,140,100\n0,100,10,100,160\n100,100,0,150,150\n50,20,30,120,120\n")
    with open(w("cp.csv"), "w") as f:
        f.write("x1,y1,x2,y2\n1,1,6,-2\n12,2,17,-1\n3,14,8,11\n13,12,18,9\n7,5,12,2\n2,9,7,6\n")
    with open(w("prior.json"), "w") as f:
        f.write('{"heading_deg": 0.5, "slant_range_m": 10000.0, "depression_deg": 40.0, '
                '"centre_lonlat": [1.6, 42.546]}\n')
    with open(w("r.csv"), "w") as f:
        f.write("type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n"
                "trihedral,1.5996,42.5454,0,2.5,270,35.26\n")
    with open(w("route.csv"), "w") as f:
        f.write("lon,lat\n1.55,42.53\n1.57,42.53\n")
    rng = np.random.default_rng(1)
    quad = gdal.GetDriverByName("GTiff").Create(w("quad.tif"), 64, 64, 4, gdal.GDT_CFloat32)
    for i, name in enumerate(("HH", "HV", "VH", "VV")):
        band = quad.GetRasterBand(i + 1)
        band.SetDescription(name)
        band.WriteArray((rng.normal(size=(64, 64)) + 1j * rng.normal(size=(64, 64))).astype(np.complex64))
    quad = None

    commands = [
        ("simulate", ["simulate"] + small + ["--heading", "0", "--out", d("sim")], "sim"),
        ("scene build", ["scene", "build", "--dem", dem, "--out", d("scene")], "scene"),
        ("sequence", ["sequence"] + small + ["--heading-from", "0", "--heading-to", "20", "--frames", "2",
                                             "--out", d("seq")], "seq"),
        ("ortho", ["ortho"] + small + ["--heading", "0", "--out", d("o")], "o"),
        ("geocode", ["geocode", "--image", w("a.tif"), "--out", d("map")], "map"),
        ("fmatrix", ["fmatrix", "--matches", w("m.csv"), "--range-spacing", "1,1", "--azimuth-spacing", "1,1",
                     "--depressions", "40,40", "--out", d("f")], "f"),
        ("resect", ["resect", "--points", w("p.csv"), "--out", d("r")], "r"),
        ("register", ["register", "--fixed", w("a.tif"), "--moving", w("b.tif"), "--points", w("cp.csv"),
                      "--out", d("reg")], "reg"),
        ("epipolar", ["epipolar", "--matches", w("m.csv"), "--image1", w("a.tif"), "--image2", w("b.tif"),
                      "--out", d("epi")], "epi"),
        ("composite", ["composite", "--green", w("a.tif"), "--magenta", w("c.tif"), "--out", d("comp")], "comp"),
        ("matchpair", ["matchpair", "--fixed", w("a.tif"), "--moving", w("c.tif"), "--warp", "1.5,1.02,3.3,-2.7",
                       "--out", d("mp")], "mp"),
        ("locate", ["locate", "--image", w("l.tif"), "--dem", dem, "--prior", w("prior.json"), "--out", d("fix"),
                    "--composite", d("fix_composite.png")], "fix"),
        ("evaluate", ["evaluate", "--dem", dem, "--trials", "1", "--size", "64", "--spacing", "60",
                      "--out", d("ev")], "ev"),
        ("validate", ["validate", "--product", os.path.join(uavsar, "SanAnd_129.h5"), "--dem",
                      os.path.join(uavsar, "SanAnd_dem.tif"), "--looks", "1", "--rays-per-cell", "1", "--bounces",
                      "1", "--out", d("val")], "val"),
        # pta: the reflector stands 12 dB above this small image's background: found at a 10 dB threshold.
        ("pta", ["pta", "--image", w("c_slc.tif"), "--reflectors", w("r.csv"), "--detection-threshold", "10",
                 "--out", d("pta")], "pta"),
        ("polsar", ["polsar", "--image", w("quad.tif"), "--multilook", "2,2", "--out", d("pol")], "pol"),
    ]
    only = os.environ.get("GISSAR_FULL_DISK_ONLY")
    for entry in commands:
        label, args, prefix_name = entry[:3]
        if only and label not in only.split(","):
            continue
        ok_status = entry[3] if len(entry) > 3 else (0,)
        sweep_command(label, [gissar] + args + ["--quiet", "--threads", "1"], disk, prefix_name, ok_status)
        print(report[-1] if report and report[-1].startswith(label + ":") else f"{label}: -", flush=True)
    if not only or "corridor" in only.split(","):
        corridor(gissar_built, source, disk, w("route.csv"))
        print(report[-1], flush=True)
    return 0


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 1
    if os.environ.get(INNER) != "1":
        outer()
    t0 = time.time()
    status = inner(sys.argv[1], sys.argv[2])
    if status == 77:
        return 77
    print(f"{len(report)} commands in {time.time() - t0:.0f} s; {len(failures)} failures")
    for line in failures:
        print("FAIL: " + line)
    return 1 if failures or status else 0


if __name__ == "__main__":
    sys.exit(main())
