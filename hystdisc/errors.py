"""The one error type users see.

Every problem with the user's input or settings is raised as :class:`HystdiscError`
with a single-line message that names the file (and run) concerned, what is wrong and
how to fix it. The command-line interface prints it as ``hystdisc: error: <message>``
and exits with status 2; it never shows a traceback for these.

Examples
--------
>>> from hystdisc.errors import HystdiscError, input_error
>>> err = input_error("run.csv", "column 'theta' is missing", "add it or map it with --column theta=NAME", run="3")
>>> str(err)
"run.csv, run 3: column 'theta' is missing; fix: add it or map it with --column theta=NAME"
"""

from __future__ import annotations


class HystdiscError(Exception):
    """A user-facing error with a one-line message (file, problem, fix).

    Parameters
    ----------
    message : str
        ``FILE, run R: problem; fix: what to do`` (:func:`input_error` builds it); line
        breaks and runs of spaces are joined into one line.
    """

    def __init__(self, message: str) -> None:
        message = " ".join(str(message).split())  # always one line
        super().__init__(message)


class HystdiscWarning(UserWarning):
    """Something was handled automatically; the message says what was done."""


def input_error(
    source: str | None, problem: str, fix: str, run: str | None = None
) -> HystdiscError:
    """Build a :class:`HystdiscError` of the form ``FILE, run R: PROBLEM; fix: FIX``."""
    where = str(source) if source else "input"
    if run is not None:
        where += f", run {run}"
    return HystdiscError(f"{where}: {problem}; fix: {fix}")
