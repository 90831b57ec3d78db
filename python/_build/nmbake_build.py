"""The package's build backend (PEP 517, PEP 660): standard library only.

Why not setuptools: Debian 12's `python3 -m venv` bundles pip and
setuptools 66 but not `wheel`, and setuptools 66 cannot build a wheel
without it ("error: invalid command 'bdist_wheel'"), so
`pip install ./python` failed offline. This backend needs nothing: it
zips the `nmbake` package with its metadata into a wheel (PEP 427), so
the install works offline with or without build isolation.
"""

import base64
import hashlib
import os
import re
import zipfile

NAME = "nmbake"
SUMMARY = "Bake normal maps with nmbake from Python: one-shot bakes, job files, and a serve session"
REQUIRES_PYTHON = ">=3.9"
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TAG = "py3-none-any"


def _version():
    """__version__ of nmbake/__init__.py: the one place it is written."""
    with open(os.path.join(ROOT, NAME, "__init__.py"), encoding="utf-8") as f:
        found = re.search(r'^__version__ = "([^"]+)"', f.read(), re.M)
    if not found:
        raise RuntimeError("no __version__ in nmbake/__init__.py")
    return found.group(1)


def _metadata(version):
    return ("Metadata-Version: 2.1\nName: %s\nVersion: %s\nSummary: %s\nRequires-Python: %s\n"
            % (NAME, version, SUMMARY, REQUIRES_PYTHON))


def _record_line(path, data):
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode("ascii")
    return "%s,sha256=%s,%d" % (path, digest, len(data))


def _write_wheel(directory, files):
    """Writes the wheel of `files` ({archive path: bytes}) plus its
    dist-info; returns the wheel's file name."""
    version = _version()
    dist_info = "%s-%s.dist-info" % (NAME, version)
    files = dict(files)
    files[dist_info + "/METADATA"] = _metadata(version).encode("utf-8")
    files[dist_info + "/WHEEL"] = ("Wheel-Version: 1.0\nGenerator: nmbake_build\nRoot-Is-Purelib: true\nTag: %s\n"
                                   % TAG).encode("utf-8")
    record_path = dist_info + "/RECORD"
    record = [_record_line(path, data) for path, data in sorted(files.items())] + [record_path + ",,"]
    files[record_path] = ("\n".join(record) + "\n").encode("utf-8")
    name = "%s-%s-%s.whl" % (NAME, version, TAG)
    with zipfile.ZipFile(os.path.join(directory, name), "w", zipfile.ZIP_DEFLATED) as wheel:
        for path in sorted(files):
            # A fixed date: the same sources give the same wheel.
            info = zipfile.ZipInfo(path, date_time=(1980, 1, 1, 0, 0, 0))
            info.external_attr = 0o644 << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            wheel.writestr(info, files[path])
    return name


def _package_files():
    files = {}
    for entry in sorted(os.listdir(os.path.join(ROOT, NAME))):
        if entry.endswith(".py"):
            with open(os.path.join(ROOT, NAME, entry), "rb") as f:
                files["%s/%s" % (NAME, entry)] = f.read()
    return files


def get_requires_for_build_wheel(config_settings=None):
    return []


def get_requires_for_build_editable(config_settings=None):
    return []


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    return _write_wheel(wheel_directory, _package_files())


def build_editable(wheel_directory, config_settings=None, metadata_directory=None):
    """`pip install -e ./python`: a .pth file that puts python/ on sys.path."""
    return _write_wheel(wheel_directory, {"_nmbake_editable.pth": (ROOT + "\n").encode("utf-8")})
