#!/usr/bin/env python3
"""The layers point down (docs/architecture.md).

Fails when
- a file under src/gissar/<layer>/ includes "gissar/<other>/..." of a layer above its own;
- a library target gissar_<layer> links a gissar_<other> above it (src/gissar/<layer>/CMakeLists.txt);
- anything outside src/gissar/cli/, apps/ and fuzz/ (executables at the top, like apps/: the options-file
  harness fuzzes the command line's own reader) includes "gissar/cli/...";
- a C library is included outside the layer that owns it (GDAL/OGR/PROJ: geo; CGAL, GEOS: scene; Embree:
  render).
The Python door sits beside cli/ on top of the layers: its binding files (python/*.cc, python/bindings.h)
may include the headers of every library layer but not cli/'s (the rule above), and the pure-Python
package (python/gissar/*.py) fails when a module
- reaches the compiled core other than as gissar._core (`from . import _core`, `from ._core import ...`,
  `import gissar._core`, or through another module of the package): no `import _core`, no loading of the
  extension file by path (importlib, ctypes) except where CORE_FILE_LOADERS says why, and then registered as
  gissar._core;
- starts a process (subprocess, os.system/popen/exec*/spawn*, asyncio subprocesses, pty): the package, its
  programs included (corridor.py, distributed.py, distributed_evaluate.py, view.py), calls the library in
  its own process through gissar._core and never runs the gissar executable. A module that must start
  another program is named in PROCESS_STARTERS with the reason.
"""
import ast
import os
import re
import sys

LAYERS = ["util", "geo", "scene", "material", "sensor", "render", "image", "mvg", "nav", "pipeline", "cli"]
OWNERS = {  # include prefix -> the one layer that may include it
    "gdal": "geo", "ogr": "geo", "cpl_": "geo", "proj.h": "geo",
    "CGAL/": "scene", "geos_c.h": "scene", "geos/": "scene",
    "embree3/": "render", "png.h": "geo",
}
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]', re.M)
LINK = re.compile(r"\bgissar_(\w+)")
SOURCE_EXT = (".h", ".cc", ".hpp", ".cpp")
# The pure-Python package, and the modules allowed an exception, each with its reason.
PACKAGE = os.path.join("python", "gissar")
CORE_FILE_LOADERS = {
    "view.py": "`gissar view` loads the extension alone (0.5 s) rather than the package (xarray, pandas: 2 s "
               "of imports), registered as gissar._core so that a later `import gissar` reuses it",
}
PROCESS_STARTERS = {}  # none: no module of the package starts a process
OS_PROCESS = re.compile(r"^(system|popen|exec\w*|spawn\w*|posix_spawn\w*|fork\w*)$")
CORE_LOADING_CALLS = {"spec_from_file_location", "ExtensionFileLoader", "load_dynamic"}


def _call_name(func):
    """`name` of a call to name(...) or x.y.name(...)."""
    if isinstance(func, ast.Name):
        return func.id
    if isinstance(func, ast.Attribute):
        return func.attr
    return None


def package_problems(root):
    """What the modules of python/gissar/ do that the Python door's place in the layers forbids."""
    problems = []
    package = os.path.join(root, PACKAGE)
    for name in sorted(os.listdir(package)):
        if not name.endswith(".py"):
            continue
        rel = os.path.join(PACKAGE, name)
        with open(os.path.join(package, name)) as f:
            tree = ast.parse(f.read(), rel)
        modules = {}  # local name -> module, of `import os as _os`
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    modules[alias.asname or alias.name.split(".")[0]] = alias.name
        starts = []
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.split(".")[-1] == "_core" and alias.name != "gissar._core":
                        problems.append(f"{rel}:{node.lineno}: import {alias.name}; the core is gissar._core")
                    if alias.name.split(".")[0] in ("subprocess", "pty", "ctypes"):
                        starts.append((node.lineno, f"import {alias.name}"))
            elif isinstance(node, ast.ImportFrom):
                module = node.module or ""
                names = [alias.name for alias in node.names]
                if node.level == 0:
                    if module.split(".")[-1] == "_core" and module != "gissar._core":
                        problems.append(f"{rel}:{node.lineno}: from {module} import ...; the core is gissar._core")
                    elif "_core" in names and module != "gissar":
                        problems.append(f"{rel}:{node.lineno}: from {module} import _core; the core is gissar._core")
                    if module.split(".")[0] in ("subprocess", "pty", "ctypes"):
                        starts.append((node.lineno, f"from {module} import ..."))
                    if module == "os" and any(OS_PROCESS.match(n) for n in names):
                        starts.append((node.lineno, f"from os import {', '.join(names)}"))
            elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
                owner = modules.get(node.value.id)
                if (owner == "os" and OS_PROCESS.match(node.attr)) or (
                        owner == "asyncio" and node.attr.startswith("create_subprocess")):
                    starts.append((node.lineno, f"{owner}.{node.attr}"))
            elif isinstance(node, ast.Call):
                called = _call_name(node.func)
                first = node.args[0].value if node.args and isinstance(node.args[0], ast.Constant) else None
                if called in ("import_module", "__import__") and isinstance(first, str) and \
                        first.split(".")[-1] == "_core" and first != "gissar._core":
                    problems.append(f"{rel}:{node.lineno}: {called}({first!r}); the core is gissar._core")
                if called in CORE_LOADING_CALLS:
                    if name not in CORE_FILE_LOADERS:
                        problems.append(f"{rel}:{node.lineno}: loads a module from a file ({called}); the "
                                        "compiled core is imported as gissar._core (or named in CORE_FILE_LOADERS "
                                        "with the reason)")
                    elif first != "gissar._core":
                        problems.append(f"{rel}:{node.lineno}: {called} must register the core as gissar._core")
        for lineno, what in starts:
            if name not in PROCESS_STARTERS:
                problems.append(f"{rel}:{lineno}: {what}: the package calls the library through gissar._core "
                                "in its own process, never by running the gissar executable (a module that must "
                                "start another program: name it in PROCESS_STARTERS with the reason)")
    return problems


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    problems = []
    rank = {layer: i for i, layer in enumerate(LAYERS)}
    for top in ("src", "python", "bench", "apps", "tests", "fuzz"):
        for dirpath, _, files in os.walk(os.path.join(root, top)):
            for name in files:
                path = os.path.join(dirpath, name)
                rel = os.path.relpath(path, root)
                parts = rel.split(os.sep)
                layer = parts[2] if len(parts) > 3 and parts[:2] == ["src", "gissar"] else None
                if name == "CMakeLists.txt" and layer in rank:
                    with open(path) as f:
                        text = f.read()
                    library = re.search(r"gissar_library\s*\((.*?)\)", text, re.S)
                    for other in LINK.findall(library.group(1) if library else ""):
                        if other in rank and rank[other] > rank[layer]:
                            problems.append(f"{rel}: gissar_{layer} links gissar_{other}, a layer above it")
                    continue
                if not name.endswith(SOURCE_EXT):
                    continue
                with open(path, errors="replace") as f:
                    includes = INCLUDE.findall(f.read())
                for inc in includes:
                    m = re.match(r"gissar/(\w+)/", inc)
                    if m:
                        other = m.group(1)
                        if other == "cli" and layer != "cli" and parts[0] not in ("apps", "fuzz"):
                            problems.append(f"{rel}: includes {inc} (only cli/, apps/ and fuzz/ may)")
                        elif layer in rank and other in rank and rank[other] > rank[layer]:
                            problems.append(f"{rel}: layer {layer} includes {inc} of the layer above, {other}")
                    for prefix, owner in OWNERS.items():
                        if inc.startswith(prefix) and layer != owner and not rel.startswith("fuzz"):
                            problems.append(f"{rel}: includes {inc}; only the {owner} layer may")
    problems += package_problems(root)
    for p in problems:
        print("layering:", p, file=sys.stderr)
    print(f"layering: {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
