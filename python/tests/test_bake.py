"""nmbake.bake(), Job and bake_job() against the real binary ($NMBAKE):
the same bytes as the command line, the report, errors, hostile names."""

import json
import os
import shutil
import subprocess
import tempfile
import unittest

import nmbake

from meshes import nmbake_binary, write_pair

BINARY = nmbake_binary()


def read(path):
    with open(path, "rb") as f:
        return f.read()


class BakeTest(unittest.TestCase):
    def setUp(self):
        if not os.path.isfile(BINARY):
            self.fail("no nmbake binary at %s (build it, or set NMBAKE)" % BINARY)
        self.dir = tempfile.mkdtemp(prefix="nmbake-py-")
        self.low, self.high = write_pair(self.dir)
        self.old_cwd = os.getcwd()

    def tearDown(self):
        os.chdir(self.old_cwd)
        shutil.rmtree(self.dir)

    def path(self, name):
        return os.path.join(self.dir, name)

    def cli(self, *args):
        return subprocess.run([BINARY, "bake"] + list(args) + ["-q"], capture_output=True, text=True)

    def test_same_bytes_as_the_command_line(self):
        done = self.cli("--low", self.low, "--high", self.high, "-o", self.path("cli_<MAP>.png"),
                        "--size", "64", "--samples", "16", "--map", "normal,height", "--preset", "unreal",
                        "--front", "0.1", "--back", "0.1", "--padding", "4")
        self.assertEqual(done.returncode, 0, done.stderr)
        report = nmbake.bake(low=self.low, high=self.high, output=self.path("py_<MAP>.png"), size=64,
                             samples=16, maps=["normal", "height"], preset="unreal", front=0.1, back=0.1,
                             padding=4, nmbake=BINARY)
        for kind in ("normal", "height"):
            self.assertEqual(read(self.path("cli_%s.png" % kind)), read(self.path("py_%s.png" % kind)), kind)
        self.assertEqual(report["outputs"], [self.path("py_normal.png"), self.path("py_height.png")])

    def test_report_and_relative_paths(self):
        os.chdir(self.dir)
        report = nmbake.bake(low="low.obj", high=["high.obj"], output=["n.png", {"path": "n.exr", "format": "exr-half"}],
                             size=32, maps="normal", nmbake=BINARY)
        self.assertIsInstance(report, dict)
        self.assertEqual((report["width"], report["height"]), (32, 32))
        self.assertEqual(report["low"], self.low)
        self.assertEqual(report["outputs"], [self.path("n.png"), self.path("n.exr")])
        self.assertGreater(report["high_triangles"], 1000)
        self.assertTrue(os.path.isfile(self.path("n.png")) and os.path.isfile(self.path("n.exr")))
        # pathlib paths, and a report path of the caller's: a copy of the report.
        import pathlib

        again = nmbake.bake(low=pathlib.Path("low.obj"), high=pathlib.Path("high.obj"),
                            output=pathlib.Path("m.png"), size=32, report="mine.json", nmbake=BINARY)
        with open(self.path("mine.json"), encoding="utf-8") as f:
            self.assertEqual(json.load(f), again)

    def test_binary_from_the_environment(self):
        old = os.environ.get("NMBAKE")
        os.environ["NMBAKE"] = BINARY
        try:
            nmbake.bake(low=self.low, high=self.high, output=self.path("env.png"), size=16)
        finally:
            if old is None:
                del os.environ["NMBAKE"]
            else:
                os.environ["NMBAKE"] = old
        self.assertTrue(os.path.isfile(self.path("env.png")))

    def test_missing_file_is_bad_input_and_writes_nothing(self):
        missing = self.path("no such low.obj")
        with self.assertRaises(nmbake.BadInput) as caught:
            nmbake.bake(low=missing, high=self.high, output=self.path("never.png"), size=16, nmbake=BINARY)
        self.assertIn(missing, caught.exception.message)
        self.assertEqual(caught.exception.code, 2)
        self.assertIsInstance(caught.exception, nmbake.Error)
        self.assertFalse(os.path.exists(self.path("never.png")))
        self.assertEqual(sorted(os.listdir(self.dir)), ["high.obj", "low.obj"])

    def test_unknown_option_is_bad_input(self):
        with self.assertRaises(nmbake.BadInput) as caught:
            nmbake.bake(low=self.low, high=self.high, output=self.path("x.png"), sise=16, nmbake=BINARY)
        self.assertIn("sise", caught.exception.message)

    def test_gate_failed_carries_the_report(self):
        # A high half the size of the low: rays over the other half miss.
        with open(self.path("half.obj"), "w") as f:
            f.write("v -1 -1 0.01\nv 0 -1 0.01\nv 0 1 0.01\nv -1 1 0.01\nf 1 2 3\nf 1 3 4\n")
        with self.assertRaises(nmbake.GateFailed) as caught:
            nmbake.bake(low=self.low, high=self.path("half.obj"), output=self.path("gate.png"), size=16,
                        front=0.1, back=0.1, max_miss_rate=0.01, nmbake=BINARY)
        self.assertEqual(caught.exception.code, 1)
        self.assertGreater(caught.exception.report["rays"]["misses"], 0)
        self.assertTrue(os.path.isfile(self.path("gate.png")))

    def test_missing_binary_is_not_found(self):
        with self.assertRaises(nmbake.NotFound):
            nmbake.bake(low=self.low, high=self.high, output=self.path("x.png"), nmbake=self.path("nope/nmbake"))
        with self.assertRaises(nmbake.NotFound):
            nmbake.find_binary("no-such-nmbake-binary-anywhere")

    def test_hostile_names(self):
        # Quotes, backslashes, a newline, a tab and unicode in the folder and
        # file names: the job file must carry them exactly.
        folder = self.path('we"ird \\ fold\ner\t ü 漢字')
        os.mkdir(folder)
        low, high = write_pair(folder, 'lo"w\\.obj', "hi\ngh é.obj")
        out = os.path.join(folder, "out \"'\\ 🙂.png")
        report = nmbake.bake(low=low, high=[high], output=out, size=16, nmbake=BINARY)
        self.assertEqual(report["outputs"], [out])
        self.assertEqual(report["low"], low)
        self.assertTrue(os.path.isfile(out))

    def test_job_round_trip_through_print_options(self):
        job = nmbake.Job(defaults={"size": 64, "samples": 16, "preset": "unity"})
        job.add(name='first "one"\n\\', low="low.obj", high=["high.obj", "high.obj"],
                outputs=["a_<MAP>.png", {"path": "a_<MAP>.exr", "format": "exr-half"}],
                maps="normal,ao", front="2%", back=0.05, ignore_backfaces=True, ao_rays=8,
                pack=["orm.png=r:ao,g:1,b:0"])
        job.add(name="second ü", low="low.obj", high="high.obj", outputs=["b.png"], size="32x16", green="down")
        job_path = self.path("job.toml")
        job.write(job_path)
        with open(job_path, encoding="utf-8") as f:
            self.assertEqual(f.read(), job.text())
        done = subprocess.run([BINARY, "bake", job_path, "--print-options"], capture_output=True, text=True)
        self.assertEqual(done.returncode, 0, done.stderr)
        first, second = [json.loads(line) for line in done.stdout.splitlines()]
        self.assertEqual(first["low"], self.low)
        self.assertEqual(first["high"], self.high + " + " + self.high)
        self.assertEqual((first["size"], first["samples"], first["maps"]), ("64", "16", "normal, ao"))
        self.assertEqual(first["preset"], "unity")
        self.assertEqual((float(first["front"].rstrip("%")), float(first["back"])), (2.0, 0.05))
        self.assertTrue(first["front"].endswith("%"))
        self.assertEqual((first["ignore_backfaces"], first["ao_rays"]), ("true", "8"))
        self.assertIn(self.path("orm.png"), first["pack"])
        self.assertEqual([o["path"] for o in first["outputs"]], [self.path("a_<MAP>.png"), self.path("a_<MAP>.exr")])
        self.assertEqual(first["outputs"][1]["format"], "exr-half")
        self.assertEqual((second["width"], second["height"], second["green"]), ("32", "16", "down"))
        # And baked: the job report names the bakes, hostile names intact.
        result = nmbake.bake_job(job_path, nmbake=BINARY)
        self.assertEqual([b["name"] for b in result["bakes"]], ['first "one"\n\\', "second ü"])
        self.assertEqual([b["status"] for b in result["bakes"]], ["done", "done"])
        self.assertTrue(os.path.isfile(self.path("orm.png")))

    def test_bake_job_errors(self):
        job = nmbake.Job()
        job.add(low="missing.obj", high="high.obj", outputs=["x.png"])
        job.write(self.path("bad.toml"))
        with self.assertRaises(nmbake.BadInput) as caught:
            nmbake.bake_job(self.path("bad.toml"), nmbake=BINARY)
        self.assertIn(self.path("missing.obj"), caught.exception.message)

    def test_exit_codes_map_to_exceptions(self):
        from nmbake._errors import error_for_code

        self.assertIsInstance(error_for_code(1, "m"), nmbake.GateFailed)
        self.assertIsInstance(error_for_code(2, "m"), nmbake.BadInput)
        self.assertIsInstance(error_for_code(3, "m"), nmbake.InternalError)
        self.assertIsInstance(error_for_code(130, "m"), nmbake.Cancelled)
        self.assertIsInstance(error_for_code(-15, "m"), nmbake.Cancelled)
        self.assertEqual(error_for_code(-15, "m").code, 143)


if __name__ == "__main__":
    unittest.main()
