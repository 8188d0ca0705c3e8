"""`gissar corridor`: a reference-image database along a route, on Dask (python3 -m gissar.corridor ARGS).

The C++ command line runs this module for `gissar corridor ARGS` (docs/distributed.md). Flags: the route,
terrain, pose spacing, headings and cluster, then the sensor flags of `gissar simulate` (the kebab-case of the
simulate request fields without their unit suffix, docs/conventions.md) and the common flags. Exit statuses:
0 done; 2 bad input or usage (one `gissar: error:` line); 3 no result (every pose skipped: one `gissar: no
result:` line per kind of skip, with the flags that fix it); 1 some poses failed (listed in the catalogue;
2 when one failed on a full disk: "no space left on the device holding DIR (FILE)"); 130 after Ctrl-C,
128 + N after SIGTERM/SIGHUP (finished poses are kept: a re-run resumes).
"""
import argparse
import difflib
import json
import logging
import math
import re
import signal
import sys
import warnings

import gissar
from gissar import ConfigError
from gissar import distributed as _distributed

#: Column of the flag names in --help (CLI11's, as in every other gissar command).
_HELP_COLUMN = 30
#: Simulate fields whose default `gissar simulate --help` does not show (0 or empty means "automatic").
_DEFAULT_NOT_SHOWN = ("range_spacing_m", "azimuth_spacing_m", "range_resolution_m", "azimuth_resolution_m",
                      "nesz_db", "vertical_units", "vertical_datum", "materials", "reflectors")
#: Simulate request fields the corridor sets itself or does not offer (per-pose or single-file outputs).
_NOT_FLAGS = ("dem", "scene", "product", "orbit", "radar_grid", "frequency", "swath", "burst", "product_window_px",
              "center_lonlat", "center_map", "heading_deg", "out_prefix", "contributions", "max_memory_bytes", "width",
              "height")


def flag_of_field(field):
    """The flag of a request field (docs/conventions.md): kebab case without the unit suffix."""
    return gissar._core.flag_of_field(field)


class _Usage(Exception):
    """A command-line error: printed as one `gissar: error: ... (command line)` line, exit 2."""


def _uint(text):
    """A non-negative integer (CLI11's UINT, e.g. --seed)."""
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {text!r}")
    return value


def _type_label(action):
    """CLI11's label of an option's value: TEXT, INT, UINT or FLOAT."""
    if action.type is _uint:
        return "UINT"
    if action.type is int:
        return "INT"
    if action.type is float or action.type is _byte_size:
        return "FLOAT" if action.type is float else "TEXT"
    return "TEXT"


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise _Usage(message)

    def format_help(self):
        """The help in the layout of every other gissar command (CLI11's, cli/cli.cc HelpFormatter): the names
        ("--x, --no-x"), the value's type and REQUIRED in a 30-column left column, the text with
        "(default: X)" on the right."""
        lines = [self.description, f"Usage: {self.prog} [OPTIONS]", ""]
        for group in self._action_groups:
            actions = [a for a in group._group_actions if a.help is not argparse.SUPPRESS]
            if not actions:
                continue
            lines.append(f"{group.title}:")
            shown = set()
            for a in actions:
                if id(a) in shown or getattr(a, "gissar_negation", False):
                    continue
                shown.add(id(a))
                names = ", ".join(a.option_strings + getattr(a, "gissar_negations", []))
                if a.nargs != 0:
                    names += " " + _type_label(a)
                if getattr(a, "gissar_required", False):
                    names += " REQUIRED"
                left = "  " + names
                text = a.help or ""
                if len(left) >= _HELP_COLUMN:
                    lines.append(left)
                    lines.append(" " * _HELP_COLUMN + text)
                else:
                    lines.append(left.ljust(_HELP_COLUMN) + text)
            lines.append("")
        return "\n".join(lines) + "\n"

    def parse_args(self, args=None, namespace=None):
        """Unknown flags first (with a suggestion), then the required ones (argparse does it the other way)."""
        args, unknown = self.parse_known_args(args, namespace)
        if unknown:
            flags = [o for a in self._actions for o in a.option_strings]
            close = difflib.get_close_matches(unknown[0].split("=", 1)[0], flags, n=1, cutoff=0.75)
            raise _Usage(f"unrecognized argument: {unknown[0]}" + (f"; did you mean {close[0]}?" if close else ""))
        missing = [a.option_strings[0] for a in self._actions if getattr(a, "gissar_required", False)
                   and getattr(args, a.dest) is None]
        if missing:
            raise _Usage("the following arguments are required: " + ", ".join(missing))
        return args


def _required(action):
    action.gissar_required = True
    return action


def _byte_size(text):
    m = re.fullmatch(r"\s*([0-9]+(?:\.[0-9]+)?)\s*([KMGT]?)i?B?\s*", text, re.IGNORECASE)
    if not m:
        raise argparse.ArgumentTypeError(f"not a size like 4G: {text!r}")
    return int(float(m.group(1)) * 1024 ** "_KMGT".index(m.group(2).upper() or "_"))


def _headings(text):
    try:
        values = [float(h) for h in text.split(",") if h.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of degrees like 0,90,180: {text!r}") from None
    if not values or not all(math.isfinite(h) for h in values):
        raise argparse.ArgumentTypeError(f"not a list of degrees like 0,90,180: {text!r}")
    return values


def _switch(group, flag, dest, text, default, extra_negations=()):
    """An on/off flag as every gissar command has it: --X and --no-X (the last one given wins), shown as
    "--x, --no-x" with its real default."""
    negations = ["--no-" + flag[2:]] + list(extra_negations)
    on = group.add_argument(flag, dest=dest, action="store_const", const=True, default=None,
                            help=text + (" (default: on)" if default else " (default: off)"))
    on.gissar_negations = negations
    off = group.add_argument(*negations, dest=dest, action="store_const", const=False, default=None, help=text)
    off.gissar_negation = True
    return on


def make_parser():
    """The argparse parser of `gissar corridor` (its --help is the command's help)."""
    p = _Parser(prog="gissar corridor", add_help=False, allow_abbrev=False,
                description="Build a reference-image database along a route on Dask: one simulated image per "
                            "pose (every --pose-step metres along the route) and heading, PREFIX_<id>.* "
                            "(ids like p0007_h090), PREFIX_catalog.json (a STAC Collection: every pose, its "
                            "status, the run summary) and PREFIX_index.csv. A re-run skips the poses already "
                            "done (docs/distributed.md).")
    p.add_argument("-h", "--help", action="help", help="Print this help message and exit")
    g = p.add_argument_group("corridor")
    _required(g.add_argument("--route", metavar="ROUTE", help="The sensor's ground track, WGS84: "
                             "GeoJSON LineString (.geojson) or CSV of lon,lat rows"))
    g.add_argument("--dem", metavar="DEM", help="DEM raster (any GDAL format and CRS), readable by every worker")
    g.add_argument("--scene", metavar="SCENE", help="Scene file from `gissar scene build` (instead of --dem)")
    _required(g.add_argument("--pose-step", metavar="METRES", type=float, dest="pose_step_m",
                             help="Distance between poses along the route, metres (geodesic, WGS84)"))
    _required(g.add_argument("--headings", metavar="H1,H2,...", type=_headings, dest="headings_deg",
                             help="Headings simulated at every pose, degrees clockwise from north"))
    g.add_argument("--width", metavar="PX", type=int, default=None,
                   help="Image columns (range), the same for every pose; default: with --height not given either, "
                        "the largest square up to 512 px whose footprint fits the DEM at every pose")
    g.add_argument("--height", metavar="PX", type=int, default=None,
                   help="Image rows (azimuth), the same for every pose; default: as --width (512 when only "
                        "--width is given)")
    _required(g.add_argument("--out", metavar="PREFIX", dest="out_prefix",
                             help="Output prefix: PREFIX_<id>.* per pose, PREFIX_catalog.json, "
                                  "PREFIX_index.csv"))
    _switch(g, "--geocode", "geocode", "Also write each done pose's image in map geometry, PREFIX_<id>_geocoded.tif "
            "(as gissar geocode; named in the catalogue; gissar view lays it on the map)", False)
    c = p.add_argument_group("cluster")
    c.add_argument("--scheduler", metavar="ADDRESS", help="Address of a running Dask scheduler (tcp://host:8786); default: an "
                                       "embedded LocalCluster")
    c.add_argument("--workers", metavar="N", type=int, help="Worker processes of the embedded cluster (default: one per core)")
    c.add_argument("--retries", metavar="N", type=int, default=2, help="Dask retries of a pose whose worker died (default: 2)")
    c.add_argument("--hash-inputs", choices=("sha256", "stat"), default="sha256",
                   help="How a re-run recognises the inputs: sha256 of their bytes or stat (path, size, mtime) "
                        "(default: sha256)")
    s = p.add_argument_group("sensor and simulation (as gissar simulate)")
    defaults = gissar._core.simulate_request_defaults()
    texts = gissar._core.simulate_request_help()
    for field in sorted(defaults):
        if field in _NOT_FLAGS or field not in texts:
            continue
        value = defaults[field]
        flag = flag_of_field(field)
        text = texts[field]
        if field == "depression_deg":  # simulate requires it; a corridor has a default
            text = text.replace(" (required without --product/--orbit)", "")
        metavar = flag[2:].upper().replace("-", "_")
        if isinstance(value, bool):
            _switch(s, flag, field, text, value, ["--fixed-sampling"] if field == "adaptive_sampling" else [])
            continue
        shown = field not in _DEFAULT_NOT_SHOWN and value is not None and value != "" and not (
            isinstance(value, float) and math.isnan(value))
        if shown:
            text += f" (default: {value:g})" if isinstance(value, float) else f" (default: {value})"
        kind = int if isinstance(value, int) else float if (isinstance(value, float) or value is None) else None
        if field == "seed":
            kind = _uint  # an unsigned request field, as simulate's --seed
        if kind is None:
            s.add_argument(flag, dest=field, default=None, metavar=metavar, help=text)
        else:
            s.add_argument(flag, dest=field, type=kind, default=None, metavar=metavar, help=text)
    s.add_argument("--max-memory", metavar="SIZE", dest="max_memory_bytes", type=_byte_size, default=None,
                   help="Memory budget, e.g. 4G (default: 3/4 of physical memory); larger jobs fail early")
    m = p.add_argument_group("common")
    _switch(m, "--quiet", "quiet", "Only warnings and errors on stderr (same as --log-level warning)", False)
    m.add_argument("--log-level", choices=("error", "warning", "info"), default="info",
                   help="error, warning or info (default: info)")
    m.add_argument("--threads", metavar="N", type=int, default=None,
                   help="Threads of each simulation (default: cores / workers on the embedded cluster)")
    _switch(m, "--force", "force", "Run even when the job exceeds the memory budget (--max-memory) or the 2^28-pixel image limit", False)
    m.add_argument("--options", metavar="FILE.json", help="JSON file of options: keys are the snake_case names (docs/conventions.md); "
                                     "flags on the command line win")
    return p


def _apply_options_file(parser, argv):
    """--options FILE.json: its keys (the parser's destinations) become defaults the command line overrides."""
    pre = _Parser(add_help=False)
    pre.add_argument("--options")
    known, _ = pre.parse_known_args(argv)
    if not known.options:
        return
    try:
        with open(known.options, encoding="utf-8") as f:
            values = json.load(f)
    except FileNotFoundError:
        raise gissar.MissingFileError(f"options file does not exist ({known.options})") from None
    except (OSError, ValueError) as e:
        raise gissar.InputError(f"cannot read the options file: {e} ({known.options})") from None
    if not isinstance(values, dict):
        raise gissar.InputError(f"an options file is a JSON object ({known.options})")
    destinations = {a.dest for a in parser._actions}
    for key, value in values.items():
        if key not in destinations or key in ("help", "options"):
            close = difflib.get_close_matches(key, sorted(destinations - {"help", "options"}), n=1, cutoff=0.75)
            raise ConfigError(f"unknown key '{key}'" + (f"; did you mean {close[0]}?" if close else "")
                              + f" ({known.options})")
        if value is not None:
            if key == "headings_deg" and isinstance(value, (int, float)):
                value = [value]
            parser.set_defaults(**{key: value})
            for action in parser._actions:
                if action.dest == key:
                    action.gissar_required = False


def run(argv):
    """Runs the command (argv without the program name); returns the exit status."""
    parser = make_parser()
    _apply_options_file(parser, argv)
    args = parser.parse_args(argv)
    quiet = bool(args.quiet) or args.log_level in ("warning", "error")
    if (args.dem is None) == (args.scene is None):
        raise ConfigError("give --dem or --scene (--dem/--scene)")
    if args.threads is not None and args.threads < 0:
        raise ConfigError(f"must be a non-negative number, got {args.threads} (--threads)")
    keywords = {field: value for field, value in vars(args).items() if value is not None
                and field in gissar._core.simulate_request_defaults()
                and (field not in _NOT_FLAGS or field == "max_memory_bytes")}
    if args.force:
        keywords["max_memory_bytes"] = 2 ** 62
    for field in ("range_spacing_m", "azimuth_spacing_m", "pose_step_m"):
        value = keywords.get(field, getattr(args, field, None))
        if value is not None and not value > 0:
            raise ConfigError(f"must be a positive number, got {value:g} ({flag_of_field(field)})")
    if args.pose_step_m is None or not args.pose_step_m > 0:
        raise ConfigError(f"must be a positive number of metres, got {args.pose_step_m} (--pose-step)")

    def log(text):
        if not quiet:
            print(text, file=sys.stderr, flush=True)

    catalog = _distributed.build_corridor(
        args.route, dem=args.dem, scene=args.scene, pose_step_m=args.pose_step_m,
        headings_deg=args.headings_deg, out_prefix=args.out_prefix, width=args.width, height=args.height,
        scheduler=args.scheduler, workers=args.workers, threads=args.threads, retries=args.retries,
        hash_inputs=args.hash_inputs, progress=not quiet, log=log, report_summary=False,
        geocode=bool(args.geocode), **keywords)
    print(args.out_prefix + "_catalog.json")
    print(args.out_prefix + "_index.csv")
    # The run's result, on stdout even with --quiet; why poses were skipped, on stderr even with --quiet.
    print(_distributed.summary_line(catalog), flush=True)
    summary = catalog["gissar:summary"]
    if summary["poses"] and summary["skipped"] == summary["poses"]:
        for line in summary["skip_reasons"]:
            print(f"gissar: no result: {line}", file=sys.stderr)
        return 3
    for line in summary["skip_reasons"]:
        print(f"gissar: warning: {line}", file=sys.stderr)
    if summary["failed"]:
        failed = [p for p in catalog["gissar:poses"] if p["status"] == "failed"]
        # A full disk is the run's error, not the poses': exit 2 like every command, naming a pose's output.
        full = [p for p in failed if "no space left" in p.get("reason", "")]
        first = (full or failed)[0]
        print(f"gissar: error: {summary['failed']} of {summary['poses']} poses failed, e.g. {first['id']}: "
              f"{first.get('reason', '')} ({args.out_prefix}_catalog.json)", file=sys.stderr)
        return 2 if full else 1
    return 0


class _Signal(BaseException):
    """SIGTERM/SIGHUP: stop like Ctrl-C (the cluster is closed, finished poses are kept), exit 128 + N."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


def _raise_signal(signum, frame):
    raise _Signal(signum)


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """gissar's warnings as the other commands print them: one `gissar: warning: ...` line on stderr."""
    if issubclass(category, gissar.GissarWarning):
        print(f"gissar: warning: {_one_line(message)}", file=sys.stderr, flush=True)
    else:
        sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


def _one_line(text):
    return " ".join(str(text).split())


def main(argv=None):
    """Entry point: maps gissar's errors (ValueError/OSError subclasses) and usage errors to one
    `gissar: error: ...` line and exit status 2."""
    argv = sys.argv[1:] if argv is None else list(argv)
    for signum in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, _raise_signal)
    warnings.showwarning = _show_warning
    # asyncio's own reports come from Dask's event loop, never from the command: above all "Future exception
    # was never retrieved: TimeoutError", a close-time message to the scheduler that timed out under load
    # after every pose was done. A pose's failure reaches the catalogue and the exit status through its
    # future; Dask's own errors keep their loggers (distributed.*).
    logging.getLogger("asyncio").setLevel(logging.CRITICAL + 1)
    try:
        return run(argv)
    except _Usage as e:
        print(f"gissar: error: {_one_line(e)} (command line)", file=sys.stderr)
        return 2
    except (gissar.Error, ValueError, OSError) as e:
        print(f"gissar: error: {_one_line(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("gissar: interrupted (finished poses are kept; run again to resume)", file=sys.stderr)
        return 130
    except _Signal as e:
        print(f"gissar: stopped by signal {e.signum} (finished poses are kept; run again to resume)",
              file=sys.stderr)
        return 128 + e.signum


if __name__ == "__main__":
    sys.exit(main())
