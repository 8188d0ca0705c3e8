"""gissar: simulate SAR images of real terrain from GIS data, and estimate an aircraft's pose from SAR
images with an affine SAR camera model.

The compiled core is ``gissar._core`` (C++, pybind11); this package gives it Python signatures, the
error classes users catch (``ValueError``/``OSError``/``RuntimeError`` subclasses) and the version.
Keyword names are the request field names of docs/conventions.md (``heading_deg``, ``range_spacing_m``):
the same names as the options-file keys and the sidecar keys of the command line.
"""
import inspect as _inspect

from . import _core
from ._core import *  # noqa: F401,F403  (the compiled API)
from ._core import (Cancelled, ConfigError, Error, GissarWarning, InputError, IoError,  # noqa: F401
                    MissingFileError)

#: The library version, as ``gissar --version`` prints it (``gissar 0.1.0 (describe)``: the middle word).
__version__ = _core.version().split()[1]

_UNITS = {"_deg": "degrees", "_m": "metres", "_db": "dB", "_bytes": "bytes", "_px": "pixels", "_s": "seconds"}


def _unit_of(name):
    for suffix, unit in _UNITS.items():
        if name.endswith(suffix):
            return unit
    return None


def _with_request_signature(function, defaults, leading, trailing, summary):
    """Gives `function` (a **kwargs wrapper of the core) the signature of its request: every field a
    keyword-only parameter with its default, units in the docstring."""
    params = [_inspect.Parameter(name, _inspect.Parameter.POSITIONAL_OR_KEYWORD, default=default)
              for name, default in leading]
    params += [_inspect.Parameter(name, _inspect.Parameter.KEYWORD_ONLY, default=value)
               for name, value in defaults.items() if name not in dict(leading) and name != "out_prefix"]
    params += [_inspect.Parameter(name, _inspect.Parameter.KEYWORD_ONLY, default=default)
               for name, default in trailing]
    function.__signature__ = _inspect.Signature(params)
    lines = [summary, "", "Parameters (units from the name's suffix):"]
    for p in params:
        unit = _unit_of(p.name)
        lines.append(f"    {p.name}: default {p.default!r}" + (f" ({unit})" if unit else ""))
    function.__doc__ = "\n".join(lines)
    return function


def simulate(dem=None, **kwargs):
    return _core.simulate(**({"dem": dem} if dem is not None else {}), **kwargs)


_with_request_signature(
    simulate, _core.simulate_request_defaults(),
    leading=[("dem", None)],
    trailing=[("transform", None), ("crs", None), ("nodata", None), ("progress", None)],
    summary="\n".join((_core.simulate.__doc__ or "").strip().splitlines()[1:]).strip())
simulate.__module__ = "gissar"
