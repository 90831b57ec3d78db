"""The exceptions of the nmbake package, one per exit code of the CLI.

docs/reference/exit-codes.md: 0 success, 1 a gate failed, 2 bad input or usage,
3 internal error, 128 + N ended by signal N (130 Ctrl-C, 143 SIGTERM).
"""


class Error(Exception):
    """Base of every error this package raises.

    `message` is what nmbake said (without its "nmbake: error: " prefix),
    `code` the exit code (or the serve protocol's error code), `stderr`
    everything the process wrote on stderr when there was a process.
    """

    def __init__(self, message, code=None, stderr=""):
        super().__init__(message)
        self.message = message
        self.code = code
        self.stderr = stderr


class NotFound(Error):
    """The nmbake binary (or its `serve` command) is not there."""


class BadInput(Error):
    """Exit 2: bad input or usage. Nothing was written."""


class GateFailed(Error):
    """Exit 1: the bake finished but a gate (max_miss_rate) failed.

    The maps are written; `report` is the bake report (a dict) when there
    was one.
    """

    def __init__(self, message, code=1, stderr="", report=None):
        super().__init__(message, code, stderr)
        self.report = report


class InternalError(Error):
    """Exit 3: an internal error of nmbake (or a server that broke off)."""


class Cancelled(Error):
    """Ended by a signal (exit 128 + N) or cancelled through a Session."""


def error_for_code(code, message, stderr="", report=None):
    """The exception for exit code `code` (a negative code is Python's
    "killed by signal -code", the same as 128 - code)."""
    if code < 0:
        code = 128 - code
    if code == 1:
        return GateFailed(message, code, stderr, report)
    if code == 2:
        return BadInput(message, code, stderr)
    if code == 3:
        return InternalError(message, code, stderr)
    if code > 128:
        return Cancelled(message, code, stderr)
    return Error(message, code, stderr)
