"""Command-line interface: ``hystdisc <command> ...``.

Each command lives in its own module of this package and provides ``HELP`` (its line in
``hystdisc --help``), ``DESCRIPTION`` (and optionally ``EPILOG``) of its own ``--help``,
``add_arguments(p)`` (its options) and ``run(args) -> int``. User errors
(:class:`~hystdisc.errors.HystdiscError`) are printed as one line on stderr with exit
status 2; Ctrl-C exits with 130 and leaves no partial files (outputs are written
atomically).

Building the parsers is cheap: this package and the command modules import only
:mod:`hystdisc.registry` (for the names of families and experiment types) and the
standard library at module level; each command imports the numerical layers inside its
``run(args)``, so ``hystdisc --help`` imports no numpy, numba, scipy, scikit-learn,
pysindy or matplotlib (``tests/cli/test_cli.py`` checks it).

The console script (:func:`console`) leaves without tearing the interpreter down: by then
every output is written and closed, and finalizing the modules of numba, SciPy and
scikit-learn cost 0.4 s of a 6.4 s ``hystdisc discover`` (see :func:`console`).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import NoReturn

from hystdisc import __version__
from hystdisc.cli.common import first_compile_note
from hystdisc.errors import HystdiscError, HystdiscWarning

COMMANDS = ("discover", "predict", "simulate", "report", "study", "design")


class OneLineParser(argparse.ArgumentParser):
    """argparse parser whose errors are one line (no usage block) with exit status 2."""

    def error(self, message: str):  # noqa: D401
        msg = " ".join(str(message).split())
        print(f"hystdisc: error: {self.prog}: {msg}; fix: see {self.prog} --help", file=sys.stderr)
        sys.exit(2)

    def long_options(self) -> list[str]:
        """Every ``--option`` this parser knows."""
        return [o for a in self._actions for o in a.option_strings if o.startswith("--")]


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every available sub-command."""
    parser = OneLineParser(
        prog="hystdisc",
        description="Discover the hysteresis model of an MR damper from measured data.",
    )
    parser.add_argument("--version", action="version", version=f"hystdisc {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            mod = importlib.import_module(f"hystdisc.cli.{name}")
        except ModuleNotFoundError as exc:  # a command not built yet
            if exc.name != f"hystdisc.cli.{name}":
                raise
            continue
        p = sub.add_parser(
            name, help=mod.HELP, description=mod.DESCRIPTION, epilog=getattr(mod, "EPILOG", None)
        )
        mod.add_arguments(p)
        p.set_defaults(run_command=mod.run, command_parser=p)
    return parser


def _unknown_options(parser: OneLineParser, extras: list[str]) -> str:
    """The message for options no parser knows, with the closest known option if any.

    Examples
    --------
    >>> p = OneLineParser(prog="hystdisc discover")
    >>> _ = p.add_argument("--model")
    >>> _unknown_options(p, ["--modle"])
    'unrecognized arguments: --modle (did you mean --model?)'
    """
    import difflib

    known = parser.long_options()
    hints = {}
    for extra in extras:
        name = extra.split("=", 1)[0]
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.75)
        if name.startswith("--") and close:
            hints[name] = close[0]
    text = f"unrecognized arguments: {' '.join(extras)}"
    if len(hints) == 1:
        return f"{text} (did you mean {next(iter(hints.values()))}?)"
    if hints:
        return f"{text} ({'; '.join(f'{k}: did you mean {v}?' for k, v in hints.items())})"
    return text


@contextmanager
def reported_warnings(quiet: bool = False) -> Iterator[None]:
    """Inside the block, every warning is one line on stderr, each text once (the data are
    checked by the reader and again by the fit): ``hystdisc: warning: ...`` for
    hystdisc's own, with its category for another library's (those only without
    ``quiet``). The warning display (``warnings.showwarning``) and filters are restored
    when the block ends, however it ends.

    Examples
    --------
    >>> before = warnings.showwarning
    >>> with reported_warnings():
    ...     warnings.showwarning is before
    False
    >>> warnings.showwarning is before
    True
    """
    said: set[str] = set()

    def _warn(message, category, filename, lineno, file=None, line=None):
        text = str(message)
        if text in said:
            return
        said.add(text)
        if issubclass(category, HystdiscWarning):
            print(f"hystdisc: warning: {message}", file=sys.stderr)
        elif not quiet:
            print(f"hystdisc: warning: {category.__name__}: {message}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.showwarning = _warn
        yield


def main(argv: list[str] | None = None) -> int:
    """Run the command line ``argv`` (default ``sys.argv[1:]``) and return its exit status
    (the console script is :func:`console`). Warnings are printed as
    :func:`reported_warnings` says while the command runs, and shown as before after it."""
    parser = build_parser()
    args, extras = parser.parse_known_args(argv)
    if extras:  # the subcommand's own parser names itself and its --help in the message
        owner = getattr(args, "command_parser", None) or parser
        owner.error(_unknown_options(owner, extras))
    if not getattr(args, "command", None):
        parser.print_help(sys.stderr)
        return 2
    with reported_warnings(getattr(args, "quiet", False)):
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """The command of ``args``, its errors as one line and an exit status."""
    try:
        with first_compile_note(getattr(args, "quiet", False)):
            return int(args.run_command(args) or 0)
    except HystdiscError as exc:
        print(f"hystdisc: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            "hystdisc: interrupted; no partial file was left (outputs completed before the "
            "interrupt are kept)",
            file=sys.stderr,
        )
        return 130
    except Exception as exc:  # a bug, not the user's input: one line, the traceback on request
        if os.environ.get("HYSTDISC_TRACEBACK"):
            raise
        print(
            f"hystdisc: internal error: {type(exc).__name__}: {exc}; this is a bug in hystdisc, "
            "not a problem with your data (fix: report it with the command and the data; "
            "HYSTDISC_TRACEBACK=1 prints the traceback)",
            file=sys.stderr,
        )
        return 3


def console(argv: list[str] | None = None) -> NoReturn:
    """Entry point of the ``hystdisc`` console script and of ``python -m hystdisc``.

    Runs :func:`main`, flushes stdout and stderr, and ends the process at once with its
    exit status (``os._exit``): the interpreter's finalization is skipped. Every file a
    command writes is complete and closed before :func:`main` returns (outputs are
    written atomically), the worker threads are idle, and no command registers an exit
    handler, so nothing is lost; what is saved is the teardown of the numerical
    libraries' modules: ``hystdisc discover data_synth/bouc-wen.csv`` took 6.01 s instead
    of 6.43 s (medians of 3 on 2 cores; about 1 s under load;
    ``benchmarks/results/bench_speed.md``). Call :func:`main` to stay in the process.
    """
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's --help, --version and usage errors
        if isinstance(exc.code, str):
            print(exc.code, file=sys.stderr)
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe (``hystdisc ... | head``)
            pass
    os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    console()
