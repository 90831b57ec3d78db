"""A small TOML writer: what nmbake's job files need and nothing more.

Strings, integers, floats, booleans, lists of those, and inline tables
(an output's `{ path = .., format = .. }`). Strings are TOML basic strings
with every character TOML forbids raw escaped (TOML 1.0, "String"):
the quote, the backslash, and the control characters U+0000-U+001F and
U+007F. Everything else, non-ASCII included, is written as UTF-8.
"""

import math
import re

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")
_SHORT_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}
_INT64 = (-(2**63), 2**63 - 1)


def string(text):
    """`text` as a TOML basic string, quotes included.

    A lone surrogate (what os.fsdecode makes of a file name that is not
    UTF-8) cannot be in a TOML file, which must be UTF-8: ValueError.
    """
    out = ['"']
    for ch in text:
        code = ord(ch)
        if ch in _SHORT_ESCAPES:
            out.append(_SHORT_ESCAPES[ch])
        elif code < 0x20 or code == 0x7F:
            out.append("\\u%04X" % code)
        elif 0xD800 <= code <= 0xDFFF:
            raise ValueError("%r: a string with a lone surrogate cannot be written in TOML (UTF-8)" % text)
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def key(name):
    """A key: bare when TOML allows it, else quoted."""
    if not isinstance(name, str):
        raise TypeError("TOML keys are strings, not %r" % (name,))
    return name if _BARE_KEY.match(name) else string(name)


def value(v):
    """One value. bool is tested before int: in Python it is one."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        if not _INT64[0] <= v <= _INT64[1]:
            raise ValueError("%d does not fit TOML's 64-bit integers" % v)
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        # repr() is the shortest text that reads back as the same double,
        # and always has a '.' or an exponent, as a TOML float must.
        return repr(v)
    if isinstance(v, str):
        return string(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(value(item) for item in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join("%s = %s" % (key(k), value(item)) for k, item in v.items()) + " }"
    if hasattr(v, "__fspath__"):
        return string(str(v.__fspath__()))
    raise TypeError("cannot write %r (%s) in a job file" % (v, type(v).__name__))


def table(header, entries):
    """A `[header]` or `[[header]]` (header given with its brackets) and its
    `key = value` lines; entries whose value is None are left out."""
    lines = [header]
    for k, v in entries.items():
        if v is not None:
            lines.append("%s = %s" % (key(k), value(v)))
    return "\n".join(lines) + "\n"
