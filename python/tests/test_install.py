"""`pip install` of the package into a fresh venv (Debian's python3 when
there is one), offline (no index), then one bake with the installed
package. Skipped only when no venv can be made here."""

import os
import shutil
import subprocess
import sys
import tempfile
import unittest

from meshes import nmbake_binary, write_pair

PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BINARY = nmbake_binary()


def python_for_venv():
    """Debian's own python3 when there is one (what the README promises),
    else the one running the tests."""
    return "/usr/bin/python3" if os.path.isfile("/usr/bin/python3") else sys.executable


class InstallTest(unittest.TestCase):
    def test_pip_install_offline_and_bake(self):
        folder = tempfile.mkdtemp(prefix="nmbake-py-venv-")
        try:
            venv = os.path.join(folder, "venv")
            made = subprocess.run([python_for_venv(), "-m", "venv", venv], capture_output=True, text=True)
            if made.returncode != 0:
                self.skipTest("cannot create a venv here (%s -m venv): %s"
                              % (python_for_venv(), made.stderr.strip().splitlines()[-1:]))
            # A copy: an in-tree setuptools build writes build/ and
            # *.egg-info beside the sources.
            source = os.path.join(folder, "src")
            shutil.copytree(PACKAGE, source, ignore=shutil.ignore_patterns("tests", "build", "*.egg-info",
                                                                           "__pycache__"))
            env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PIP_INDEX_URL")}
            # No network: an index that cannot be reached, as well as --no-index.
            env.update(PIP_NO_INDEX="1", PIP_DISABLE_PIP_VERSION_CHECK="1", NMBAKE=BINARY)
            # Both ways: with build isolation (the backend requires nothing)
            # and without (what the README gives).
            for isolation in ([], ["--no-build-isolation", "--force-reinstall"]):
                pip = subprocess.run(
                    [os.path.join(venv, "bin", "python"), "-m", "pip", "install", "--no-index"] + isolation
                    + [source], capture_output=True, text=True, env=env, cwd=folder)
                self.assertEqual(pip.returncode, 0, pip.stdout + pip.stderr)
            low, high = write_pair(folder)
            script = ("import nmbake, os\n"
                      "assert os.path.dirname(nmbake.__file__).startswith(%r), nmbake.__file__\n"
                      "r = nmbake.bake(low='low.obj', high='high.obj', output='n.png', size=16)\n"
                      "print(r['outputs'][0])\n" % venv)
            run = subprocess.run([os.path.join(venv, "bin", "python"), "-c", script], capture_output=True,
                                 text=True, env=env, cwd=folder)
            self.assertEqual(run.returncode, 0, run.stdout + run.stderr)
            self.assertEqual(run.stdout.strip(), os.path.join(folder, "n.png"))
            self.assertTrue(os.path.isfile(os.path.join(folder, "n.png")))
        finally:
            shutil.rmtree(folder)


if __name__ == "__main__":
    unittest.main()
