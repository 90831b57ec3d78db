"""A client of `nmbake serve`, protocol version 1: one process that keeps
its loaded high meshes between bakes.

The protocol is JSON lines on the server's stdin and stdout:

  server, first:  {"type":"ready","protocol":1,"nmbake":"<version>"}
  requests:       {"id":..,"type":"bake","bake":{<[[bake]] keys>},"folder":"<cwd>"}
                  {"id":..,"type":"status"}
                  {"id":..,"type":"cancel","target":<bake id>}
                  {"type":"quit"}
  answers:        {"id":..,"type":"progress","stage":..,"fraction":..}
                  {"id":..,"type":"result","report":{..},"reused":{"high_mesh":b,"high_scene":b}}
                  {"id":..,"type":"error","code":2|3|130,"message":".."}
                  {"id":..,"type":"status",..}
                  {"type":"bye"}

A reader thread reads the answers and puts each in the queue of the
request with its id; the thread that asked waits on that queue, so a
progress callback runs in the caller's thread while the bake runs, and
several threads can have requests in flight at once.
"""

import collections
import itertools
import json
import os
import queue
import subprocess
import threading

from ._errors import Cancelled, Error, InternalError, NotFound, error_for_code
from ._run import _outputs, find_binary

PROTOCOL = 1

# Seconds to wait for "ready", and for "bye" on close.
_READY_TIMEOUT = 30.0
_QUIT_TIMEOUT = 10.0

# The server's exit: what a pending request gets when the process ends.
_EOF = object()


class BakeRequest:
    """A bake sent to the server: `id`, `result()`, `cancel()`."""

    def __init__(self, session, request_id, answers, progress):
        self.id = request_id
        self._session = session
        self._answers = answers
        self._progress = progress

    def cancel(self):
        """Asks the server to cancel this bake (result() then raises
        Cancelled, unless the bake had already finished)."""
        self._session.cancel(self.id)

    def result(self, timeout=None):
        """Waits for the bake; returns its report with a `reused` entry.

        Progress answers call the progress callback (stage, fraction) here,
        in this thread. A callback that raises cancels the bake, and its
        exception is raised once the server has answered.
        """
        failure = None
        while True:
            try:
                answer = self._answers.get(timeout=timeout)
            except queue.Empty:
                raise TimeoutError("no answer to bake %r within %s s" % (self.id, timeout)) from None
            except KeyboardInterrupt:
                # Ctrl-C while waiting: the server's bake is not left running.
                self.cancel()
                raise
            if answer is _EOF:
                self._session._forget(self.id)
                raise self._session._broken("bake %r" % (self.id,))
            kind = answer.get("type")
            if kind == "progress":
                if self._progress is not None and failure is None:
                    try:
                        self._progress(answer.get("stage"), answer.get("fraction"))
                    except BaseException as e:  # the caller's own exception, raised below
                        failure = e
                        self.cancel()
                continue
            self._session._forget(self.id)
            if failure is not None:
                raise failure
            if kind == "result":
                report = dict(answer.get("report") or {})
                report["reused"] = answer.get("reused", {})
                return report
            if kind == "error":
                raise _error_answer(answer)
            raise InternalError("unexpected answer to bake %r: %s" % (self.id, json.dumps(answer)))


def _error_answer(answer):
    code = answer.get("code")
    message = answer.get("message", "")
    if code == 130:
        return Cancelled(message, 130)
    if isinstance(code, int):
        return error_for_code(code, message)
    return Error(message, code)


class Session:
    """`nmbake serve` as a Python object; use it as a context manager, or
    call close(). Raises NotFound when the binary is missing or has no
    `serve` command."""

    def __init__(self, nmbake=None, args=()):
        binary = find_binary(nmbake)
        self._lock = threading.Lock()  # guards _pending, _ids, writes to stdin
        self._pending = {}
        self._ids = itertools.count(1)
        self._stderr_tail = collections.deque(maxlen=50)
        self._ready = queue.Queue()
        self._closed = False
        try:
            self._process = subprocess.Popen(
                [binary, "serve"] + list(args),
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
                encoding="utf-8",
                errors="replace",
                bufsize=1,
            )
        except (FileNotFoundError, PermissionError) as e:
            raise NotFound("cannot run %s: %s" % (binary, e)) from e
        self._reader = threading.Thread(target=self._read, name="nmbake-serve-reader", daemon=True)
        self._stderr_reader = threading.Thread(target=self._read_stderr, name="nmbake-serve-stderr", daemon=True)
        self._reader.start()
        self._stderr_reader.start()
        try:
            ready = self._ready.get(timeout=_READY_TIMEOUT)
        except queue.Empty:
            self._kill()
            raise NotFound("%s serve printed no \"ready\" within %g s" % (binary, _READY_TIMEOUT)) from None
        if ready is _EOF or not isinstance(ready, dict) or ready.get("type") != "ready":
            self._kill()
            said = "\n".join(self._stderr_tail).strip()
            raise NotFound(
                "%s has no working `serve` command (it %s before \"ready\")%s"
                % (binary, "exited" if ready is _EOF else "printed something else",
                   ": " + said if said else ""),
                stderr=said,
            )
        if ready.get("protocol") != PROTOCOL:
            self._kill()
            raise Error("%s serve speaks protocol %r; this package speaks %d"
                        % (binary, ready.get("protocol"), PROTOCOL))
        self.version = ready.get("nmbake")
        self.binary = binary

    # -- the threads ------------------------------------------------------

    def _read(self):
        """Reads answers until the server's stdout closes."""
        ready_seen = False
        for line in self._process.stdout:
            line = line.strip()
            if not line:
                continue
            try:
                answer = json.loads(line)
            except ValueError:
                self._stderr_tail.append("(not JSON on stdout) " + line)
                continue
            if not ready_seen:
                ready_seen = True
                self._ready.put(answer)
                continue
            if not isinstance(answer, dict):
                continue
            with self._lock:
                answers = self._pending.get(answer.get("id")) if "id" in answer else None
            if answers is not None:
                answers.put(answer)
            # "bye" and answers to no pending request (a cancel's, say)
            # need nobody.
        # The server is gone: wake everyone who waits.
        self._ready.put(_EOF)
        with self._lock:
            waiting = list(self._pending.values())
        for answers in waiting:
            answers.put(_EOF)

    def _read_stderr(self):
        for line in self._process.stderr:
            self._stderr_tail.append(line.rstrip("\n"))

    # -- requests ---------------------------------------------------------

    def _send(self, message):
        data = json.dumps(message, ensure_ascii=False) + "\n"
        try:
            with self._lock:
                if self._closed:
                    raise Error("the session is closed")
                self._process.stdin.write(data)
                self._process.stdin.flush()
        except (BrokenPipeError, OSError, ValueError):
            raise self._broken("the request") from None

    def _register(self, request_id):
        answers = queue.Queue()
        with self._lock:
            if request_id is None:
                request_id = next(self._ids)
                while request_id in self._pending:
                    request_id = next(self._ids)
            elif request_id in self._pending:
                raise ValueError("request id %r is in use" % (request_id,))
            self._pending[request_id] = answers
        return request_id, answers

    def _forget(self, request_id):
        with self._lock:
            self._pending.pop(request_id, None)

    def _broken(self, what):
        # Its output closes just before it ends: a moment for the exit code.
        try:
            code = self._process.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            code = None
        said = "\n".join(self._stderr_tail).strip()
        return InternalError(
            "nmbake serve ended (%s) before answering %s%s"
            % ("exit code %s" % code if code is not None else "its output closed", what,
               ": " + said if said else ""),
            code, said)

    def submit(self, low, high, output, *, progress=None, request_id=None, **options):
        """Sends a bake and returns its BakeRequest at once. Arguments as
        bake(); `request_id` (a str or int) is chosen for you if None."""
        entries = dict(options, low=low, high=high, outputs=_outputs(output, absolute=False))
        entries = {k: _fspath(v) for k, v in entries.items()}
        request_id, answers = self._register(request_id)
        try:
            self._send({"id": request_id, "type": "bake", "bake": entries, "folder": os.getcwd()})
        except BaseException:
            self._forget(request_id)
            raise
        return BakeRequest(self, request_id, answers, progress)

    def bake(self, low, high, output, *, progress=None, request_id=None, **options):
        """Bakes and returns the report (a dict) with `reused`: which of the
        high mesh and its BVH the server had loaded already. Options are the
        job file's keys; relative paths are the working directory's.
        progress(stage, fraction) is called while it runs. Errors raise
        BadInput (2), InternalError (3), Cancelled (130)."""
        return self.submit(low, high, output, progress=progress, request_id=request_id, **options).result()

    def status(self, timeout=None):
        """The server's status answer (a dict)."""
        request_id, answers = self._register(None)
        try:
            self._send({"id": request_id, "type": "status"})
            answer = answers.get(timeout=timeout)
        except queue.Empty:
            raise TimeoutError("no status answer within %s s" % timeout) from None
        finally:
            self._forget(request_id)
        if answer is _EOF:
            raise self._broken("status")
        if answer.get("type") == "error":
            raise _error_answer(answer)
        return answer

    def cancel(self, target):
        """Asks the server to cancel the bake with id `target`; the bake's
        own result() then raises Cancelled. Does not wait."""
        request_id = next(self._ids)
        self._send({"id": "cancel-%d" % request_id, "type": "cancel", "target": target})

    def close(self):
        """Sends quit, waits for the server to end (kills it after a
        while). Bakes still running end with an InternalError."""
        with self._lock:
            if self._closed:
                return
        try:
            self._send({"type": "quit"})
        except Error:
            pass
        with self._lock:
            self._closed = True
        try:
            self._process.stdin.close()
        except OSError:
            pass
        try:
            self._process.wait(timeout=_QUIT_TIMEOUT)
        except subprocess.TimeoutExpired:
            self._kill()
            return
        self._close_pipes()

    def _kill(self):
        """Ends the server at once (a failed start, or no "bye")."""
        with self._lock:
            self._closed = True
        if self._process.poll() is None:
            self._process.kill()
        self._process.wait()
        self._close_pipes()

    def _close_pipes(self):
        # The readers end at the pipes' end of file; then the pipes close.
        self._reader.join(timeout=_QUIT_TIMEOUT)
        self._stderr_reader.join(timeout=_QUIT_TIMEOUT)
        for stream in (self._process.stdin, self._process.stdout, self._process.stderr):
            try:
                stream.close()
            except OSError:
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def _fspath(v):
    """`v` with every path object (pathlib) made a str, for json."""
    if isinstance(v, (list, tuple)):
        return [_fspath(item) for item in v]
    if isinstance(v, dict):
        return {k: _fspath(item) for k, item in v.items()}
    if hasattr(v, "__fspath__"):
        return os.fspath(v)
    return v
