"""nmbake from Python: bake normal maps with the nmbake binary.

    import nmbake
    report = nmbake.bake(low="low.obj", high="high.ply", output="normal.png", size=1024)

bake() runs one bake (a temporary job file and `nmbake bake`), Job writes
job files and bake_job() runs them, Session keeps an `nmbake serve`
process for many bakes. Errors are the exit codes as exceptions, all
subclasses of nmbake.Error. Standard library only; see docs/guide/python.md.
"""

__version__ = "0.1.0"

from ._errors import BadInput, Cancelled, Error, GateFailed, InternalError, NotFound
from ._run import Job, bake, bake_job, find_binary
from ._session import BakeRequest, Session

__all__ = [
    "BadInput",
    "BakeRequest",
    "Cancelled",
    "Error",
    "GateFailed",
    "InternalError",
    "Job",
    "NotFound",
    "Session",
    "bake",
    "bake_job",
    "find_binary",
]
