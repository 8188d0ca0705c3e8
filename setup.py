"""Builds the compiled core (gissar._core) with the project's CMake build and packages it.

The CMake build tree is $GISSAR_BUILD_DIR, else build/ in the repository (the one `make build` makes): when
it is already built, pip reuses it and compiles nothing twice.
"""
import glob
import os
import re
import shutil
import subprocess

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = os.path.dirname(os.path.abspath(__file__))


def project_version():
    with open(os.path.join(ROOT, "CMakeLists.txt")) as f:
        return re.search(r"project\(gissar VERSION ([0-9.]+)", f.read()).group(1)


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build_dir = BUILD_DIR
        if not os.path.exists(os.path.join(build_dir, "CMakeCache.txt")):
            subprocess.check_call(["cmake", "-S", ROOT, "-B", build_dir, "-DCMAKE_BUILD_TYPE=Release"])
        subprocess.check_call(["cmake", "--build", build_dir, "--target", "gissar_python",
                               "-j", str(os.cpu_count() or 2)])
        built = glob.glob(os.path.join(build_dir, "python", "gissar", "_core*.so"))
        if len(built) != 1:
            raise RuntimeError(f"expected one gissar/_core*.so in {build_dir}/python, found {built}")
        target = self.get_ext_fullpath(ext.name)
        os.makedirs(os.path.dirname(target), exist_ok=True)
        shutil.copyfile(built[0], target)
        # The `gissar view` page, bundled by the build (web/, esbuild) into the package directory.
        page = os.path.join(build_dir, "python", "gissar", "web")
        if os.path.isdir(page):
            shutil.copytree(page, os.path.join(os.path.dirname(target), "web"), dirs_exist_ok=True)


BUILD_DIR = os.environ.get("GISSAR_BUILD_DIR", os.path.join(ROOT, "build"))
# setuptools' own scratch files go inside the CMake build tree, not into the sources.
SCRATCH = os.path.join(BUILD_DIR, "pip")

setup(version=project_version(),
      options={"build": {"build_base": SCRATCH}, "egg_info": {"egg_base": SCRATCH}},
      ext_modules=[Extension("gissar._core", sources=[])],
      cmdclass={"build_ext": CMakeBuild})
