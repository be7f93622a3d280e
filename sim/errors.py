"""The one root of the errors a user is told about (issue 26).

Every error that means "this input, option or file is wrong" or "the work could not be done"
derives from ``TouchdownError``: ``str()`` is one line naming the file, the key or the field at
fault, and ``exit_code`` is what the command line exits with (SPEC.md section 2: 2 bad usage or
bad input, 1 a failure of the work). The roots of each part derive from it (sim.scenario's
ScenarioError, sim.timeline's CommandError, logs' LogError, service.serve's ServeError,
view.rerun_view's ViewError, replay.incident's Diverged, sweep.cases' SweepError), and cli.py has
one handler for them all. Nothing here is used by the step: it is I/O-free like the rest of sim/.
"""
from __future__ import annotations


class TouchdownError(Exception):
    """An error told to a user in one line; the command line exits with ``exit_code`` (2 by
    default: bad usage or bad input; a subclass or one instance may say 1: the work failed)."""

    exit_code: int = 2

    def __init__(self, *args, exit_code: int | None = None):
        super().__init__(*args)
        if exit_code is not None:
            self.exit_code = exit_code


class UserError(TouchdownError):
    """Bad usage or bad input (an option, a file that cannot be read): exit 2."""

    exit_code = 2


class WorkFailed(TouchdownError):
    """The work could not be done (a full disk, a viewer that would not start): exit 1."""

    exit_code = 1
