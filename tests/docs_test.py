#!/usr/bin/env python3
"""A document's runnable blocks run as written, and its quoted figures match the run.

  docs_test.py --source SRC --build BUILD DOC [--results out/tutorial/results.json --output-of examples/tutorial.py]

Every fenced block right after a `<!-- runnable -->` line is run, in the order of the page, as one bash
script (`set -euo pipefail`; Python blocks through /usr/bin/python3) in a fresh directory that holds only
links to the repository's `data/` and `examples/` and to the build tree as `build/` — what a user who
cloned the repository and ran `make build` has. With --results, the figures the page quotes
(scripts/docs_numbers.py) are compared with the results file the blocks wrote.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

BLOCK = re.compile(r"^<!-- runnable -->\n```(\w+)\n(.*?)^```", re.M | re.S)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--source", required=True)
    parser.add_argument("--build", required=True)
    parser.add_argument("--results", help="results file the blocks write (relative to the run directory)")
    parser.add_argument("--output-of", help="the command whose printed output the page quotes")
    parser.add_argument("doc")
    args = parser.parse_args()
    with open(os.path.join(args.source, args.doc)) as f:
        blocks = BLOCK.findall(f.read())
    if not blocks:
        print(f"docs_test: {args.doc} has no runnable block", file=sys.stderr)
        return 1
    script = ["set -euo pipefail"]
    for language, body in blocks:
        if language in ("sh", "bash"):
            script.append(body)
        elif language == "python":
            script.append("PYTHONPATH=build/python /usr/bin/python3 - <<'GISSAR_DOC_PYTHON'\n" + body +
                          "GISSAR_DOC_PYTHON")
        else:
            print(f"docs_test: {args.doc}: cannot run a '{language}' block", file=sys.stderr)
            return 1
    with tempfile.TemporaryDirectory(prefix="gissar_docs_") as work:
        os.symlink(os.path.join(args.source, "data"), os.path.join(work, "data"))
        os.symlink(os.path.join(args.source, "examples"), os.path.join(work, "examples"))
        os.symlink(os.path.abspath(args.build), os.path.join(work, "build"))
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
        run = subprocess.run(["bash", "-c", "\n".join(script)], cwd=work, env=env, capture_output=True, text=True)
        sys.stdout.write(run.stdout)
        sys.stderr.write(run.stderr)
        if run.returncode != 0:
            print(f"docs_test: the runnable blocks of {args.doc} failed with status {run.returncode}",
                  file=sys.stderr)
            return 1
        if args.results:
            command = [sys.executable, os.path.join(args.source, "scripts", "docs_numbers.py"),
                       "--results", os.path.join(work, args.results), "--check",
                       os.path.join(args.source, args.doc)]
            if args.output_of:
                log = os.path.join(work, "printed.txt")
                with open(log, "w") as f:
                    f.write(run.stdout)
                command += ["--output", log]
            if subprocess.run(command).returncode != 0:
                print(f"docs_test: {args.doc} quotes figures the run does not give; "
                      "`make docs-numbers` rewrites them", file=sys.stderr)
                return 1
    print(f"docs_test: {len(blocks)} runnable blocks of {args.doc} ran" +
          (", figures agree" if args.results else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
