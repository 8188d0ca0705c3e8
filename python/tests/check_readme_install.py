#!/usr/bin/env python3
"""README.md's Python install block runs as written where the first `python3` on PATH is not the interpreter the
module is built for (as with pyenv's python3 in front of Debian's): the block right after the
`<!-- python-install -->` line runs (bash, `set -euo pipefail`) in a temporary copy of the repository's top level
(links, so nothing lands in the repository; the venv it makes is in the temporary directory) with a PATH whose
first `python3` and `python` fail, reusing the CMake build tree BUILD_DIR (GISSAR_BUILD_DIR, as `make
install-python` passes it); then the environment's Python imports gissar, with NumPy, from another directory.

  check_readme_install.py SOURCE_DIR BUILD_DIR
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile

BLOCK = re.compile(r"^<!-- python-install -->\n```(?:sh|bash)\n(.*?)^```", re.M | re.S)
# Not linked into the copy: build trees, virtual environments, outputs, git.
SKIP = re.compile(r"^(\.git|\.venv|build|build-.*|out)$")
STUB = "#!/bin/sh\necho \"$0: not the python3 gissar is built for (README.md must name the interpreter)\" >&2\nexit 1\n"


def main():
    source, build = (os.path.abspath(a) for a in sys.argv[1:3])
    with open(os.path.join(source, "README.md"), encoding="utf-8") as f:
        blocks = BLOCK.findall(f.read())
    if len(blocks) != 1:
        print(f"check_readme_install: README.md needs one ```sh block after <!-- python-install --> "
              f"(found {len(blocks)})", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory(prefix="gissar_readme_") as work:
        repo = os.path.join(work, "gissar")
        os.makedirs(repo)
        for name in os.listdir(source):
            if not SKIP.match(name):
                os.symlink(os.path.join(source, name), os.path.join(repo, name))
        stubs = os.path.join(work, "stubs")
        os.makedirs(stubs)
        for name in ("python3", "python"):
            with open(os.path.join(stubs, name), "w") as f:
                f.write(STUB)
            os.chmod(os.path.join(stubs, name), 0o755)
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
        env.update(PATH=stubs + os.pathsep + env.get("PATH", ""), GISSAR_BUILD_DIR=build, PIP_NO_INPUT="1",
                   PIP_DISABLE_PIP_VERSION_CHECK="1")
        first = shutil.which("python3", path=env["PATH"])
        if first is None or os.path.realpath(first) == "/usr/bin/python3":
            print(f"check_readme_install: PATH's python3 is {first}", file=sys.stderr)
            return 1
        run = subprocess.run(["bash", "-c", "set -euo pipefail\n" + blocks[0]], cwd=repo, env=env,
                             capture_output=True, text=True)
        sys.stdout.write(run.stdout)
        sys.stderr.write(run.stderr)
        if run.returncode != 0:
            print(f"check_readme_install: README.md's python-install block failed with status {run.returncode}",
                  file=sys.stderr)
            return 1
        pythons = [os.path.join(root, "bin", "python") for root, dirs, files in os.walk(repo)
                   if "pyvenv.cfg" in files]
        if len(pythons) != 1:
            print(f"check_readme_install: the block made {len(pythons)} virtual environments in the repository "
                  "directory (expected one)", file=sys.stderr)
            return 1
        elsewhere = os.path.join(work, "elsewhere")
        os.makedirs(elsewhere)
        probe = subprocess.run([pythons[0], "-c", "import gissar, numpy; print(gissar.__file__, gissar.__version__)"],
                               cwd=elsewhere, env=env, capture_output=True, text=True)
        if probe.returncode != 0 or not probe.stdout.startswith(os.path.dirname(os.path.dirname(pythons[0]))):
            print(f"check_readme_install: `import gissar` with {pythons[0]} failed or imported another copy:\n"
                  f"{probe.stdout}{probe.stderr}", file=sys.stderr)
            return 1
        print(f"check_readme_install: README.md's block installed gissar: {probe.stdout.strip()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
