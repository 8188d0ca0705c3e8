#!/usr/bin/env python3
"""The layers point down (docs/architecture.md).

Fails when
- a file under src/gissar/<layer>/ includes "gissar/<other>/..." of a layer above its own;
- a library target gissar_<layer> links a gissar_<other> above it (src/gissar/<layer>/CMakeLists.txt);
- anything outside src/gissar/cli/, apps/ and fuzz/ (executables at the top, like apps/: the options-file
  harness fuzzes the command line's own reader) includes "gissar/cli/...";
- a C library is included outside the layer that owns it (GDAL/OGR/PROJ: geo; CGAL, GEOS: scene; Embree:
  render).
"""
import os
import re
import sys

LAYERS = ["util", "geo", "scene", "material", "sensor", "render", "image", "mvg", "nav", "pipeline", "cli"]
OWNERS = {  # include prefix -> the one layer that may include it
    "gdal": "geo", "ogr": "geo", "cpl_": "geo", "proj.h": "geo",
    "CGAL/": "scene", "geos_c.h": "scene", "geos/": "scene",
    "embree3/": "render",
}
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]', re.M)
LINK = re.compile(r"\bgissar_(\w+)")
SOURCE_EXT = (".h", ".cc", ".hpp", ".cpp")


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
    for p in problems:
        print("layering:", p, file=sys.stderr)
    print(f"layering: {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
