#!/usr/bin/env bash
# Installs the Debian bookworm packages gissar needs to build, test and run.
# Idempotent: packages already installed are left alone; when all are present
# nothing is run at all (no apt-get update, no network).
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config ninja-build   # ninja: the build trees' generator (Makefile)
  libgdal-dev gdal-bin libproj-dev proj-bin proj-data  # geo: raster/vector I/O, CRS, EGM96 grid
  libhdf5-dev                                  # geo: NISAR RSLC products (HDF5)
  libxml2-dev                                  # geo: Sentinel-1 SAFE annotations (XML)
  libpng-dev                                   # geo: PNG pictures (quicklooks)
  libcgal-dev libgeos-dev                      # scene: triangulation, buffers
  libembree-dev                                # render: ray tracing (Embree 3)
  libeigen3-dev                                # linear algebra
  libtbb-dev                                   # parallelism
  libcli11-dev nlohmann-json3-dev              # CLI, config and JSON
  libgtest-dev libgmock-dev libbenchmark-dev   # tests and benchmarks
  libopencv-dev                                # image processing, features
  libfftw3-dev                                 # FFT
  libopenblas0-serial                          # BLAS behind GDAL's thin-plate splines (GCP refinement):
                                               # 2.3x faster product writing than the reference BLAS; serial,
                                               # so it adds no threads to TBB's or a Dask worker's
  libgif-dev                                   # animated GIF (heading sequences)
  povray                                       # benchmarks: POV-Ray side by side (make bench)
  libssl-dev python3
  python3-venv python3-pip python3-setuptools          # pip install . (make install-python)
  pybind11-dev python3-dev python3-numpy python3-pytest python3-gdal  # Python API
  python3-jsonschema                                   # STAC Items against the published schemas (tests/stac_test.py)
  python3-xarray python3-rioxarray python3-tqdm       # Python results as xarray (rioxarray: CRS), progress bars
  python3-mypy                                         # type stubs checked in the tests
  python3-dask python3-distributed python3-pyproj     # gissar corridor: Dask workers, geodesic pose spacing
  nodejs                                               # gissar view: the page's bundle (web/: npm ci + esbuild)
  chromium chromium-driver python3-selenium            # gissar view: its tests in headless chromium (label browser)
)
# npm (gissar view's bundle): Debian's package, unless the installed nodejs brings its own (NodeSource's nodejs
# provides and conflicts with npm: asking apt for Debian's would fail).
command -v npm >/dev/null 2>&1 || PACKAGES+=(npm)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "install-deps: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done" >&2
