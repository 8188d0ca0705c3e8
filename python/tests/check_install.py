#!/usr/bin/env python3
"""`pip install --no-build-isolation --no-index .` works offline into a fresh virtual environment made with
--system-site-packages, reusing the CMake build tree; then, from a directory outside the repository,
`import gissar` works and `gissar.__version__` equals the version `gissar --version` prints; and the
tests of the package's doors pass against the installed package (run from outside the repository, without
PYTHONPATH): the functions and their results (test_gissar.py), native threads, progress and Ctrl-C
(test_native.py), lazily opened products (test_open_product.py) and the messages a new user meets
(test_first_hour_python.py). The whole suite runs against the build tree as ctest's python_tests (the same
compiled core and modules), so it is not run twice.

  check_install.py SOURCE_DIR BUILD_DIR GISSAR_BINARY
"""
import os
import subprocess
import sys
import tempfile

# The test files run against the installed package (see the docstring).
INSTALLED_PACKAGE_TESTS = ("test_gissar.py", "test_native.py", "test_open_product.py", "test_first_hour_python.py")


def main():
    source, build, binary = sys.argv[1:4]
    with tempfile.TemporaryDirectory(prefix="gissar_install_") as work:
        venv = os.path.join(work, "venv")
        subprocess.run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", venv], check=True)
        python = os.path.join(venv, "bin", "python")
        env = dict(os.environ, GISSAR_BUILD_DIR=os.path.abspath(build))
        env.pop("PYTHONPATH", None)
        subprocess.run([python, "-m", "pip", "install", "-q", "--no-build-isolation", "--no-index", source],
                       check=True, env=env, cwd=work)
        elsewhere = os.path.join(work, "elsewhere")
        os.makedirs(elsewhere)
        probe = ("import gissar, inspect; print(gissar.__version__); print(gissar.__file__); "
                 "p = list(inspect.signature(gissar.simulate).parameters); print(p[0], 'heading_deg' in p, len(p))")
        out = subprocess.run([python, "-c", probe], check=True, env=env, cwd=elsewhere, capture_output=True,
                             text=True).stdout.splitlines()
        cli = subprocess.run([binary, "--version"], check=True, capture_output=True, text=True).stdout.split()
        problems = []
        if out[0] != cli[1]:
            problems.append(f"gissar.__version__ is {out[0]}, `gissar --version` says {cli[1]}")
        if not out[1].startswith(venv):
            problems.append(f"imported {out[1]}, not the installed package in {venv}")
        if not out[2].startswith("dem True"):
            problems.append(f"signature of gissar.simulate starts {out[2]}")
        tests = os.path.join(source, "python", "tests")
        suite = subprocess.run([python, "-m", "pytest", "-q", "-p", "no:cacheprovider"] +
                               [os.path.join(tests, name) for name in INSTALLED_PACKAGE_TESTS],
                               env=dict(env, GISSAR_CLI=binary, GISSAR_SOURCE_DIR=source), cwd=elsewhere)
        if suite.returncode != 0:
            problems.append(f"the package's tests fail against the installed package (pytest exit {suite.returncode})")
        for p in problems:
            print("check_install:", p, file=sys.stderr)
        print(f"check_install: gissar {out[0]} installed and imported from {out[1]}")
        return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
