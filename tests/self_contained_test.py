#!/usr/bin/env python3
"""Fails when a tracked file builds a path into a directory beside the repository.

A user's clone has nothing beside it, so no test, script or document may read
the team's shared folder beside the checkout (a parent-directory path ending in
"shared"). This file excludes itself (it has to hold the pattern). Without git, every file under the tree
except build outputs is scanned.
"""
import os
import re
import subprocess
import sys

ROOT = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), ".."))
SELF = os.path.relpath(os.path.abspath(__file__), ROOT)
# A parent-directory step followed by "shared", in any quoting or join form:
# a slash or backslash path, os.path.join(ROOT, "..", "shared"), / ".." / "shared".
PATTERNS = [re.compile(r"\.\.[/\\]+shared"), re.compile(r"""["']\.\.["']\s*[,/]\s*["']shared""")]


def tracked_files():
    try:
        out = subprocess.run(["git", "-C", ROOT, "ls-files", "-z"], check=True, capture_output=True).stdout
        return [f for f in out.decode().split("\0") if f]
    except (OSError, subprocess.CalledProcessError):
        files = []
        for base, dirs, names in os.walk(ROOT):
            dirs[:] = [d for d in dirs if d not in (".git", "out") and not d.startswith("build")]
            files += [os.path.relpath(os.path.join(base, n), ROOT) for n in names]
        return files


def main():
    offenders = []
    for rel in tracked_files():
        if rel == SELF or rel.startswith(".ci/"):
            continue
        path = os.path.join(ROOT, rel)
        try:
            with open(path, "rb") as f:
                data = f.read()
        except OSError:
            continue
        if b"\0" in data[:8192]:
            continue  # binary
        text = data.decode("utf-8", "replace")
        for number, line in enumerate(text.splitlines(), 1):
            if any(p.search(line) for p in PATTERNS):
                offenders.append(f"{rel}:{number}: {line.strip()[:120]}")
    if offenders:
        print("files that build a path beside the repository:\n" + "\n".join(offenders))
        return 1
    print("self-contained: no path beside the repository")
    return 0


if __name__ == "__main__":
    sys.exit(main())
