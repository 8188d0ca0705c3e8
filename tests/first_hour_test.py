"""A new user's first hour, walked as a user would (issue "A new user's first hour"): a fresh directory, the
README's own set-up lines, `--help` of every command, the results printed on the terminal. Fails when one of
the friction points comes back:
- `gissar --help` lists every command (corridor included);
- every command's --help: switches read "--x, --no-x" with their real default, no CLI11 "{false}";
  (the names are the parser's own, so both forms are accepted);
- fmatrix and resect print their headline (heading change, inliers; the camera) on stdout;
- `make demo` builds only what the demo runs (the binary), and the README states its measured time;
- the README starts with the two set-up commands.

Usage: first_hour_test.py GISSAR_BINARY SOURCE_DIR
"""
import csv
import os
import re
import shutil
import subprocess
import sys
import tempfile

COMMANDS = ["simulate", "scene build", "scene info", "sequence", "ortho", "fmatrix", "resect", "register",
            "epipolar", "composite", "locate", "evaluate", "matchpair", "validate", "geocode", "pta", "polsar",
            "view"]
failures = []
checks = [0]


def check(condition, what):
    checks[0] += 1
    if not condition:
        failures.append(what)


def run(args, cwd):
    return subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=600)


def options_of(help_text):
    """(names, description) of each option line of a CLI11 help."""
    rows = []
    for line in help_text.splitlines():
        if line.startswith("  -"):
            # CLI11's layout: names in a 30-column left column, or alone on their line when longer.
            if "  " in line[2:30]:
                names, _, description = line[2:].partition("  ")
            elif len(line) > 30 and line[29] == " ":
                names, description = line[:30], line[30:]
            else:
                names, description = line, ""
            rows.append([names.strip(), description.strip()])
        elif rows and line.startswith(" " * 30) and line.strip():  # the text of a long name, on its own line
            rows[-1][1] = (rows[-1][1] + " " + line.strip()).strip()
    return [tuple(r) for r in rows]


def main(gissar, source):
    work = tempfile.mkdtemp(prefix="gissar-first-hour-")
    # The command list.
    top = run([gissar, "--help"], work)
    check(top.returncode == 0, "gissar --help exits 0")
    for command in COMMANDS + ["corridor"]:
        check(re.search(r"^\s+" + command.split()[0] + r"\b", top.stdout, re.M) is not None,
              f"gissar --help lists {command}")
    # Every command's help: switches with both forms and their real default; each form accepted.
    for command in COMMANDS:
        words = command.split()
        helped = run([gissar, *words, "--help"], work)
        check(helped.returncode == 0, f"gissar {command} --help exits 0")
        check("{false}" not in helped.stdout and "{true}" not in helped.stdout,
              f"gissar {command} --help shows no CLI11 '{{false}}'")
        for names, description in options_of(helped.stdout):
            flags = [n.strip().split()[0] for n in names.split(",")]
            negated = [f for f in flags if f.startswith("--no-")]
            if not negated:
                continue
            positive = flags[0]
            check(negated[0] == "--no-" + positive[2:], f"{command}: {names} pairs --X with --no-X")
            check(description.endswith("(default: on)") or description.endswith("(default: off)"),
                  f"{command}: {positive} states its real default ({description!r})")
    # Results on the terminal: fmatrix and resect on a thesis case (heading change 30 deg, depression 40 deg).
    case = os.path.join(source, "tests", "data", "affine", "case2_thesis_dpsi30_dep40_noisefree_points.csv")
    fm = run([gissar, "fmatrix", "--matches", case, "--range-spacing", "1,1", "--azimuth-spacing", "1,1",
              "--depressions", "40,40", "--out", "f", "--quiet"], work)
    check(fm.returncode == 0, f"fmatrix runs ({fm.stderr.strip()})")
    headline = [line for line in fm.stdout.splitlines() if line.startswith("fmatrix: ")]
    check(len(headline) == 1 and re.search(r"heading change (29\.9\d|30\.0\d) deg", headline[0])
          and "50 of 50 matches inliers" in headline[0], f"fmatrix prints its headline ({fm.stdout!r})")
    with open(case) as f, open(os.path.join(work, "points.csv"), "w", newline="") as g:
        rows = list(csv.DictReader(f))
        w = csv.writer(g)
        w.writerow(["X", "Y", "Z", "x", "y"])
        for r in rows:
            w.writerow([r["X"], r["Y"], r["Z"], r["x1"], r["y1"]])
    rs = run([gissar, "resect", "--points", "points.csv", "--out", "r", "--quiet"], work)
    check(rs.returncode == 0, f"resect runs ({rs.stderr.strip()})")
    headline = [line for line in rs.stdout.splitlines() if line.startswith("resect: ")]
    check(len(headline) == 1 and re.search(r"depression 40\.000", headline[0]) is not None,
          f"resect prints its headline ({rs.stdout!r})")
    # locate on a real product prints its fix and its error against the annotated track.
    data = os.path.join(source, "data", "uavsar")
    lo = run([gissar, "locate", "--product", os.path.join(data, "SanAnd_129.h5"), "--dem",
              os.path.join(data, "SanAnd_dem.tif"), "--dem-oversample", "4", "--prior-offset-track", "-60,30,0",
              "--out", "fix", "--quiet"], work)
    headline = [line for line in lo.stdout.splitlines() if line.startswith("locate: ")]
    check(lo.returncode == 0 and len(headline) == 1 and "error against the annotated track" in headline[0]
          and headline[0].endswith("; converged"), f"locate prints its fix ({lo.stdout!r}, {lo.stderr.strip()})")
    # `make demo` builds only the binary and the Python package.
    dry = run(["make", "-n", "-C", source, "demo", "BUILD_DIR=build-first-hour-dry-run"], work)
    build_lines = [line for line in dry.stdout.splitlines() if "cmake --build" in line]
    check(len(build_lines) == 1 and build_lines[0].count("--target") == 1 and "--target gissar " in build_lines[0] + " ",
          f"make demo builds only the gissar binary ({build_lines})")
    # The README: the two set-up commands first, the demo's measured time.
    with open(os.path.join(source, "README.md")) as f:
        readme = f.read()
    first_block = readme.split("```sh", 1)[1].split("```", 1)[0].split()
    check(first_block == ["make", "demo", "make", "test"], f"the README starts with make demo, make test ({first_block})")
    check(re.search(r"`make demo`[^.]*measured", readme) is not None,
          "the README states the fresh-clone `make demo` time as measured")
    check(re.search(r"examples/tutorial\.py\)[^.]*measured [0-9.–]+ s", readme) is not None,
          "the README states the tutorial's run time as measured")
    shutil.rmtree(work, ignore_errors=True)
    for f in failures:
        print("FAILED:", f)
    print(f"first hour: {checks[0] - len(failures)} passed, {len(failures)} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])))
