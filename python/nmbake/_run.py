"""One-shot bakes through the `nmbake` binary: bake(), bake_job() and Job.

bake() writes a temporary job file (docs/reference/job-files.md) and runs
`nmbake bake JOB -q`; the job file's keys are the option table's
(src/bake/options.cpp), so every option nmbake has is a keyword here.
"""

import json
import os
import shutil
import subprocess
import tempfile

from . import _toml
from ._errors import Error, NotFound, error_for_code

# Keys whose values are paths. A job file resolves them against its own
# folder; bake()'s job file lives in a temp folder, so they are made
# absolute against the caller's working directory first.
_PATH_KEYS = ("low", "high", "cage", "id_palette", "debug_dump", "cache")

_ERROR_PREFIX = "nmbake: error: "


def find_binary(explicit=None):
    """The nmbake executable: `explicit`, else $NMBAKE, else `nmbake` on PATH.

    A name without a slash is looked up on PATH; a path must be an
    executable file. NotFound says where it looked.
    """
    for given, source in ((explicit, "the nmbake argument"), (os.environ.get("NMBAKE"), "$NMBAKE")):
        if not given:
            continue
        given = os.fspath(given)
        if os.sep in given or (os.altsep and os.altsep in given):
            if os.path.isfile(given) and os.access(given, os.X_OK):
                return os.path.abspath(given)
            raise NotFound("%s (%s) is not an executable file" % (given, source))
        found = shutil.which(given)
        if found:
            return found
        raise NotFound("%s (%s) is not on PATH" % (given, source))
    found = shutil.which("nmbake")
    if not found:
        raise NotFound("nmbake is not on PATH: pass nmbake=\"/path/to/nmbake\" or set NMBAKE")
    return found


def error_message(stderr, code):
    """What nmbake said: its "nmbake: error: " lines, without the prefix;
    else its last line of stderr; else the bare exit code."""
    lines = [line[len(_ERROR_PREFIX):] for line in stderr.splitlines() if line.startswith(_ERROR_PREFIX)]
    if lines:
        return "\n".join(lines)
    rest = [line for line in stderr.splitlines() if line.strip()]
    if rest:
        return rest[-1]
    return "nmbake exited with code %d" % code


def run_cli(binary, args):
    """Runs `binary args`; returns the CompletedProcess (text, decoded with
    replacement so that no file name can make this raise)."""
    try:
        return subprocess.run(
            [binary] + list(args),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            encoding="utf-8",
            errors="replace",
            check=False,
        )
    except (FileNotFoundError, PermissionError) as e:
        raise NotFound("cannot run %s: %s" % (binary, e)) from e


def _absolute(path):
    return os.path.abspath(os.fspath(path))


def _absolute_options(options):
    """`options` with every path made absolute (see _PATH_KEYS); a pack's
    path is the text before its '='."""
    out = dict(options)
    for k in _PATH_KEYS:
        v = out.get(k)
        if v is None:
            continue
        out[k] = [_absolute(p) for p in v] if isinstance(v, (list, tuple)) else _absolute(v)
    if out.get("pack") is not None:
        packs = out["pack"] if isinstance(out["pack"], (list, tuple)) else [out["pack"]]
        resolved = []
        for text in packs:
            path, sep, channels = str(text).partition("=")
            resolved.append(_absolute(path) + sep + channels if sep else text)
        out["pack"] = resolved
    return out


def _outputs(output, absolute):
    """`output` (a path, an { path, format } dict, or a list of them) as a
    job file's outputs list."""
    items = output if isinstance(output, (list, tuple)) else [output]
    if not items:
        raise ValueError("bake needs at least one output")
    out = []
    for item in items:
        if isinstance(item, dict):
            item = dict(item)
            if absolute:
                item["path"] = _absolute(item["path"])
            out.append(item)
        else:
            out.append(_absolute(item) if absolute else os.fspath(item))
    return out


def _flags(threads, max_miss_rate):
    """The command's own flags that are not job-file keys."""
    flags = ["-q"]
    if threads is not None:
        flags += ["--threads", str(int(threads))]
    if max_miss_rate is not None:
        flags += ["--max-miss-rate", repr(float(max_miss_rate))]
    return flags


def bake(low, high, output, *, nmbake=None, threads=None, max_miss_rate=None, **options):
    """Bakes one map set and returns the bake report (a dict).

    low, high (a path or a list of paths), output (a path, a list of paths,
    or { "path": .., "format": .. } dicts); every other keyword is a job
    file key (size, samples, maps, preset, front, back, cage, pack, ...).
    Relative paths are the caller's working directory's. threads and
    max_miss_rate are the command's --threads and --max-miss-rate; a
    `report` path also gets the report's JSON. Raises BadInput, GateFailed, InternalError, Cancelled or NotFound.
    """
    binary = find_binary(nmbake)
    # The report is always written (to a temp file, to return it); a
    # `report` path given as well gets a copy.
    wanted_report = options.pop("report", None)
    first = output[0] if isinstance(output, (list, tuple)) and output else output
    name = first.get("path") if isinstance(first, dict) else first
    entries = {"name": os.fspath(name) if name is not None else None}
    entries.update(_absolute_options(dict(options, low=low, high=high)))
    entries["outputs"] = _outputs(output, absolute=True)
    with tempfile.TemporaryDirectory(prefix="nmbake-") as folder:
        job_path = os.path.join(folder, "job.toml")
        report_path = os.path.join(folder, "report.json")
        # `--report` is the flag bake's: a job file names its report itself.
        entries["report"] = report_path
        with open(job_path, "w", encoding="utf-8", newline="\n") as f:
            f.write(_toml.table("[[bake]]", entries))
        done = run_cli(binary, ["bake", job_path] + _flags(threads, max_miss_rate))
        report = None
        if os.path.exists(report_path):
            with open(report_path, encoding="utf-8") as f:
                report = json.load(f)
            if wanted_report is not None:
                shutil.copyfile(report_path, _absolute(wanted_report))
    if done.returncode != 0:
        raise error_for_code(done.returncode, error_message(done.stderr, done.returncode), done.stderr, report)
    if report is None:
        raise Error("nmbake succeeded but wrote no report", 0, done.stderr)
    return report


def bake_job(path, *, nmbake=None, only=None, keep_going=False, threads=None, max_miss_rate=None):
    """Runs every bake of the job file at `path` (or only the bake named
    `only`) and returns the job report: {"bakes": [{"name", "status",
    "outputs", ...}]}. Errors as bake(); the job report of a failed job is
    the exception's `job_report`."""
    binary = find_binary(nmbake)
    with tempfile.TemporaryDirectory(prefix="nmbake-") as folder:
        job_report = os.path.join(folder, "job-report.json")
        args = ["bake", os.fspath(path), "--job-report", job_report] + _flags(threads, max_miss_rate)
        if only is not None:
            args += ["--only", only]
        if keep_going:
            args.append("--keep-going")
        done = run_cli(binary, args)
        result = None
        if os.path.exists(job_report):
            with open(job_report, encoding="utf-8") as f:
                result = json.load(f)
    if done.returncode != 0:
        error = error_for_code(done.returncode, error_message(done.stderr, done.returncode), done.stderr)
        error.job_report = result
        raise error
    return result if result is not None else {"bakes": []}


class Job:
    """A job file being built: [defaults] and one [[bake]] per add().

    Values are written as given: paths stay relative, and nmbake resolves
    them against the folder the job file is written to.
    """

    def __init__(self, defaults=None):
        self.defaults = dict(defaults or {})
        self.bakes = []

    def add(self, name=None, low=None, high=None, outputs=None, **options):
        """Adds a [[bake]]; returns its dict of keys (to change later).
        low, high and outputs are required, as nmbake requires them."""
        if low is None or high is None or not outputs:
            raise ValueError("a bake needs low, high and outputs")
        entry = {"name": name, "low": low, "high": high, "outputs": _outputs(outputs, absolute=False)}
        entry.update(options)
        self.bakes.append(entry)
        return entry

    def text(self):
        """The job file's text (TOML)."""
        parts = []
        if self.defaults:
            parts.append(_toml.table("[defaults]", self.defaults))
        for entry in self.bakes:
            parts.append(_toml.table("[[bake]]", entry))
        return "\n".join(parts)

    def write(self, path):
        """Writes the job file (UTF-8) to `path`."""
        with open(path, "w", encoding="utf-8", newline="\n") as f:
            f.write(self.text())
