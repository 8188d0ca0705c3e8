#!/usr/bin/env python3
"""The result figures a document quotes, kept equal to a run.

A figure is marked in the Markdown source by an HTML comment right after it, naming a key of a results
file: `499<!--=f_inliers-->` (invisible when rendered). A block introduced by
`<!-- output: examples/tutorial.py -->` holds the script's printed output.

  docs_numbers.py --results R.json [--output LOG] --update DOC   rewrite the figures (same decimals)
  docs_numbers.py --results R.json [--output LOG] --check DOC    exit 1 when a figure is off

A figure agrees when it differs from the run by at most 2 units of its last printed digit or 1 %
(the runs are seeded; the slack covers floating-point differences between machines). Timings (the
`[  4.1 s]` prefixes of the output block) are not compared.
"""
import argparse
import json
import re
import sys

MARK = re.compile(r"(-?\d+(?:\.\d+)?)<!--=(\w+)-->")
OUTPUT_BLOCK = re.compile(r"(<!-- output: [^>]*-->\n```\n)(.*?)(\n```)", re.S)
NUMBER = re.compile(r"-?\d+(?:\.\d+)?")
TIMING = re.compile(r"^\[\s*[\d.]+ s\] ", re.M)


def decimals(text):
    return len(text.split(".")[1]) if "." in text else 0


def agrees(quoted, value):
    slack = max(2 * 10 ** -decimals(quoted), 0.01 * abs(value))
    return abs(float(quoted) - value) <= slack


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--results", required=True)
    parser.add_argument("--output", help="the script's printed output, for the output block")
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--update", metavar="DOC")
    mode.add_argument("--check", metavar="DOC")
    args = parser.parse_args()
    doc = args.update or args.check
    with open(args.results) as f:
        results = json.load(f)
    with open(doc) as f:
        text = f.read()
    problems = []

    def figure(match):
        quoted, key = match.group(1), match.group(2)
        if key not in results:
            problems.append(f"{doc}: no result named '{key}' in {args.results}")
            return match.group(0)
        value = results[key]
        if args.check and not agrees(quoted, value):
            problems.append(f"{doc}: {key} is quoted as {quoted}, the run gives {value}")
        return f"{value:.{decimals(quoted)}f}<!--={key}-->"

    new_text = MARK.sub(figure, text)
    if args.output:
        with open(args.output) as f:
            # The progress lines ("[  4.1 s] ..."), without the closing list of pictures and its paths.
            printed = "\n".join(line for line in f.read().splitlines()
                                if TIMING.match(line) and " pictures in " not in line)
        block = OUTPUT_BLOCK.search(new_text)
        if block is None:
            problems.append(f"{doc}: no '<!-- output: ... -->' block")
        elif args.update:
            new_text = new_text[:block.start(2)] + printed + new_text[block.end(2):]
        else:
            quoted = NUMBER.findall(TIMING.sub("", block.group(2)))
            ran = NUMBER.findall(TIMING.sub("", printed))
            if len(quoted) != len(ran):
                problems.append(f"{doc}: the output block has {len(quoted)} figures, the run printed {len(ran)}")
            else:
                for q, r in zip(quoted, ran):
                    if not agrees(q, float(r)):
                        problems.append(f"{doc}: output block quotes {q}, the run printed {r}")
    for p in problems:
        print("docs_numbers:", p, file=sys.stderr)
    if args.update and not problems:
        with open(doc, "w") as f:
            f.write(new_text)
        print(f"docs_numbers: {doc} updated")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
