"""nmbake.Session: the client against a fake server (a Python script that
speaks protocol 1, written by the test) for dispatching, progress, errors
and cancel; and once against the real `nmbake serve`, when the binary has
that command."""

import os
import shutil
import stat
import subprocess
import sys
import tempfile
import threading
import unittest

import nmbake

from meshes import nmbake_binary, write_pair

# The fake server. MODE: "serve" speaks the protocol; "unknown" is a binary
# without the command; "protocol2" announces another version. A bake's
# behaviour is chosen by its low path: "ok" (progress, then a result
# echoing the request), "bad" (error 2), "internal" (error 3), "slow"
# (progress, then waits for a cancel: error 130), "die" (exits).
FAKE = r'''#!PYTHON
import json, sys
MODE = "MODE_HERE"
def send(message):
    sys.stdout.write(json.dumps(message) + "\n")
    sys.stdout.flush()
if MODE == "unknown":
    sys.stderr.write("nmbake: error: The following argument was not expected: serve\n")
    sys.exit(2)
send({"type": "ready", "protocol": 2 if MODE == "protocol2" else 1, "nmbake": "0.0-fake"})
slow = []
for line in sys.stdin:
    request = json.loads(line)
    kind = request.get("type")
    if kind == "quit":
        send({"type": "bye"})
        break
    if kind == "status":
        send({"id": request["id"], "type": "status", "running": list(slow)})
    elif kind == "cancel":
        if request["target"] in slow:
            slow.remove(request["target"])
            send({"id": request["target"], "type": "error", "code": 130, "message": "cancelled"})
    elif kind == "bake":
        rid, low = request["id"], request["bake"]["low"]
        if low == "die":
            sys.exit(3)
        send({"id": rid, "type": "progress", "stage": "load", "fraction": 0.0})
        if low == "ok":
            send({"id": rid, "type": "progress", "stage": "trace", "fraction": 0.5})
            send({"id": rid, "type": "result", "report": {"request": request},
                  "reused": {"high_mesh": True, "high_scene": False}})
        elif low == "bad":
            send({"id": rid, "type": "error", "code": 2, "message": "bad.obj: the low mesh does not exist"})
        elif low == "internal":
            send({"id": rid, "type": "error", "code": 3, "message": "it broke"})
        elif low == "slow":
            slow.append(rid)
'''


class FakeServerTest(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="nmbake-py-")

    def tearDown(self):
        shutil.rmtree(self.dir)

    def fake(self, mode="serve"):
        path = os.path.join(self.dir, "fake-nmbake-" + mode)
        with open(path, "w") as f:
            f.write(FAKE.replace("PYTHON", sys.executable).replace("MODE_HERE", mode))
        os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR)
        return path

    def test_bake_progress_and_result(self):
        calls = []
        with nmbake.Session(nmbake=self.fake()) as session:
            self.assertEqual(session.version, "0.0-fake")
            report = session.bake(low="ok", high=["h1.obj", "h2.obj"], output="n.png", size=64,
                                  maps=["normal", "ao"],
                                  progress=lambda stage, f: calls.append((stage, f, threading.get_ident())))
        me = threading.get_ident()
        self.assertEqual(calls, [("load", 0.0, me), ("trace", 0.5, me)])
        self.assertEqual(report["reused"], {"high_mesh": True, "high_scene": False})
        request = report["request"]
        self.assertEqual(request["type"], "bake")
        self.assertEqual(request["folder"], os.getcwd())
        self.assertEqual(request["bake"], {"low": "ok", "high": ["h1.obj", "h2.obj"], "outputs": ["n.png"],
                                           "size": 64, "maps": ["normal", "ao"]})

    def test_errors_are_typed(self):
        with nmbake.Session(nmbake=self.fake()) as session:
            with self.assertRaises(nmbake.BadInput) as caught:
                session.bake(low="bad", high="h", output="n.png")
            self.assertEqual(caught.exception.message, "bad.obj: the low mesh does not exist")
            with self.assertRaises(nmbake.InternalError):
                session.bake(low="internal", high="h", output="n.png")
            # The session still works after errors.
            self.assertIn("reused", session.bake(low="ok", high="h", output="n.png"))

    def test_cancel_while_another_thread_bakes(self):
        with nmbake.Session(nmbake=self.fake()) as session:
            started = threading.Event()
            outcome = {}

            def run():
                try:
                    session.bake(low="slow", high="h", output="n.png", request_id="slow-1",
                                 progress=lambda stage, f: started.set())
                except nmbake.Error as e:
                    outcome["error"] = e

            thread = threading.Thread(target=run)
            thread.start()
            self.assertTrue(started.wait(120))
            # A status answer reaches this thread while the bake waits in the other.
            self.assertEqual(session.status(timeout=120)["running"], ["slow-1"])
            session.cancel("slow-1")
            thread.join(120)
            self.assertFalse(thread.is_alive())
            self.assertIsInstance(outcome.get("error"), nmbake.Cancelled)
            self.assertEqual(outcome["error"].code, 130)

    def test_submit_and_cancel_through_the_request(self):
        with nmbake.Session(nmbake=self.fake()) as session:
            request = session.submit(low="slow", high="h", output="n.png")
            self.assertIsInstance(request.id, int)
            request.cancel()
            with self.assertRaises(nmbake.Cancelled):
                request.result(timeout=120)

    def test_a_raising_progress_callback_cancels(self):
        class Stop(Exception):
            pass

        def progress(stage, fraction):
            raise Stop()

        with nmbake.Session(nmbake=self.fake()) as session:
            with self.assertRaises(Stop):
                session.bake(low="slow", high="h", output="n.png", progress=progress)
            self.assertEqual(session.status(timeout=120)["running"], [])

    def test_server_that_dies_is_an_internal_error(self):
        session = nmbake.Session(nmbake=self.fake())
        with self.assertRaises(nmbake.InternalError) as caught:
            session.bake(low="die", high="h", output="n.png")
        # How it ended: its exit code when the process is gone by then (it
        # usually is), else that its output closed; either way an error,
        # whatever the machine's load.
        message = caught.exception.message
        self.assertIn("nmbake serve ended", message)
        self.assertTrue("exit code 3" in message or "its output closed" in message, message)
        session.close()

    def test_no_serve_command_is_not_found(self):
        with self.assertRaises(nmbake.NotFound) as caught:
            nmbake.Session(nmbake=self.fake("unknown"))
        self.assertIn("serve", caught.exception.message)
        self.assertIn("not expected", caught.exception.message)

    def test_other_protocol_is_refused(self):
        with self.assertRaises(nmbake.Error) as caught:
            nmbake.Session(nmbake=self.fake("protocol2"))
        self.assertIn("protocol", caught.exception.message)

    def test_missing_binary(self):
        with self.assertRaises(nmbake.NotFound):
            nmbake.Session(nmbake=os.path.join(self.dir, "nope"))


def has_serve(binary):
    """Whether `binary serve` exists (the serve branch adds it)."""
    done = subprocess.run([binary, "--help"], capture_output=True, text=True)
    return any(line.strip().startswith("serve") for line in done.stdout.splitlines())


BINARY = nmbake_binary()


@unittest.skipUnless(os.path.isfile(BINARY) and has_serve(BINARY),
                     "this nmbake binary has no `serve` command yet (it comes with the serve branch)")
class RealServerTest(unittest.TestCase):
    def test_two_bakes_reuse_the_high_mesh_and_match_the_command_line(self):
        folder = tempfile.mkdtemp(prefix="nmbake-py-")
        try:
            low, high = write_pair(folder)
            out = [os.path.join(folder, "s%d.png" % i) for i in range(2)]
            stages = []
            with nmbake.Session(nmbake=BINARY) as session:
                first = session.bake(low=low, high=high, output=out[0], size=32,
                                     progress=lambda stage, f: stages.append(stage))
                second = session.bake(low=low, high=high, output=out[1], size=32)
                session.status()
            self.assertTrue(second["reused"]["high_mesh"])
            self.assertIn("reused", first)
            cli = os.path.join(folder, "cli.png")
            subprocess.run([BINARY, "bake", "--low", low, "--high", high, "-o", cli, "--size", "32", "-q"],
                           check=True)
            with open(cli, "rb") as a, open(out[0], "rb") as b, open(out[1], "rb") as c:
                expected = a.read()
                self.assertEqual(b.read(), expected)
                self.assertEqual(c.read(), expected)
        finally:
            shutil.rmtree(folder)


if __name__ == "__main__":
    unittest.main()
