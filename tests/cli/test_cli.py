"""The command-line layer: cheap parsers, names from the registry, one way to the estimator.

``hystdisc --help`` must not import the numerical stack (numpy, numba, scipy, scikit-learn,
pysindy, matplotlib): the parsers are built from :mod:`hystdisc.registry` alone and each
command imports the heavy layers inside its ``run``. What is checked here is the set of
imported modules, not a time (no timed tests).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import hystdisc
from hystdisc import registry
from hystdisc.cli import COMMANDS, build_parser
from hystdisc.cli.common import discovery_options, make_discovery

#: Top-level packages the help path must not import.
HEAVY = ("numpy", "numba", "scipy", "sklearn", "pysindy", "matplotlib")

ROOT = Path(hystdisc.__file__).resolve().parent.parent


def _env() -> dict[str, str]:
    """The environment of a child interpreter that imports this checkout's hystdisc."""
    return {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    }


def _heavy_modules(code: str) -> list[str]:
    """Run ``code`` in a fresh interpreter; the heavy modules it left imported."""
    script = (
        "import sys\n"
        f"{code}\n"
        f"heavy = {set(HEAVY)!r}\n"
        "import json\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in heavy)))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        env=_env(),
        cwd=ROOT,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("command", [None, *COMMANDS])
def test_help_imports_nothing_heavy(command):
    argv = ["--help"] if command is None else [command, "--help"]
    code = (
        "import contextlib, io\n"
        "from hystdisc.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    try:\n"
        f"        main({argv!r})\n"
        "    except SystemExit:\n"
        "        pass"
    )
    assert _heavy_modules(code) == []


def test_import_hystdisc_is_cheap_and_names_resolve_lazily():
    assert _heavy_modules("import hystdisc, hystdisc.registry, hystdisc.errors") == []
    # the lazy names resolve to the objects of their modules
    from hystdisc.models import Model, TermModel

    assert hystdisc.Model is Model
    assert hystdisc.TermModel is TermModel
    assert {"Discovery", "Model", "Results", "TermModel", "load", "generate"} <= set(dir(hystdisc))
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        _ = hystdisc.nope


def _subparser(name: str):
    return build_parser()._subparsers._group_actions[0].choices[name]


def test_every_command_is_registered():
    assert tuple(build_parser()._subparsers._group_actions[0].choices) == COMMANDS


@pytest.mark.parametrize("command", ["discover", "predict", "report"])
def test_experiment_choices_come_from_the_registry(command):
    (action,) = [a for a in _subparser(command)._actions if a.dest == "experiment"]
    assert tuple(action.choices) == registry.experiment_names()


@pytest.mark.parametrize("command", ["discover", "report", "simulate", "study"])
def test_model_help_lists_every_registered_family(command):
    (action,) = [a for a in _subparser(command)._actions if a.dest == "model"]
    assert ", ".join(registry.family_names()) in action.help


def test_families_default_lists_every_registered_family():
    (action,) = [a for a in _subparser("discover")._actions if a.dest == "families"]
    assert f"default: {','.join(registry.family_names())}" in action.help


def test_make_discovery_passes_the_command_line_options():
    args = build_parser().parse_args(
        ["discover", "x.csv", "--families", "dahl, bingham", "--seed", "3", "--no-heldout"]
    )
    disc = make_discovery(discovery_options(args))
    assert isinstance(disc, hystdisc.Discovery)
    assert disc.families == ["dahl", "bingham"]
    assert disc.seed == 3
    assert disc.heldout is False
    assert disc.close_loop is True


def test_a_bug_is_one_line_with_its_own_exit_code(monkeypatch, capsys):
    from hystdisc.cli import main
    from hystdisc.cli import simulate as simulate_cmd

    def broken(args):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(simulate_cmd, "run", broken)
    monkeypatch.delenv("HYSTDISC_TRACEBACK", raising=False)
    assert main(["simulate", "--model", "dahl", "-o", "x.csv"]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("hystdisc: internal error: ZeroDivisionError: float division by zero;")
    assert "HYSTDISC_TRACEBACK=1" in err
    monkeypatch.setenv("HYSTDISC_TRACEBACK", "1")
    with pytest.raises(ZeroDivisionError):
        main(["simulate", "--model", "dahl", "-o", "x.csv"])


@pytest.mark.parametrize("ends", ["returns", "fails", "raises"])
def test_warnings_are_one_line_each_during_a_command_and_shown_as_before_after(
    monkeypatch, capsys, ends
):
    """``main`` prints each warning once, as one line, while the command runs, and puts the
    process's warning display and filters back however the command ends."""
    import warnings

    from hystdisc.cli import main
    from hystdisc.cli import simulate as simulate_cmd
    from hystdisc.errors import HystdiscError, HystdiscWarning

    def warns(args):
        warnings.simplefilter("ignore", DeprecationWarning)  # a command's own filter
        for _ in range(2):
            warnings.warn("the runs share one current", HystdiscWarning, stacklevel=1)
        warnings.warn("a library's", RuntimeWarning, stacklevel=1)
        if ends == "fails":
            raise HystdiscError("a user error")
        if ends == "raises":
            raise ZeroDivisionError("a bug")
        return 0

    monkeypatch.setattr(simulate_cmd, "run", warns)
    monkeypatch.setenv("HYSTDISC_TRACEBACK", "1")  # a bug propagates out of main
    display, filters = warnings.showwarning, list(warnings.filters)
    argv = ["simulate", "--model", "dahl", "-o", "x.csv"]
    if ends == "raises":
        with pytest.raises(ZeroDivisionError):
            main(argv)
    else:
        assert main(argv) == (0 if ends == "returns" else 2)
    assert warnings.showwarning is display
    assert warnings.filters == filters
    err = capsys.readouterr().err.splitlines()
    assert err[:2] == [
        "hystdisc: warning: the runs share one current",
        "hystdisc: warning: RuntimeWarning: a library's",
    ]


def _console(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """``python -m hystdisc ARGS`` (the console entry, :func:`hystdisc.cli.console`)."""
    return subprocess.run(
        [sys.executable, "-m", "hystdisc", *args],
        capture_output=True,
        text=True,
        env=_env(),
        cwd=cwd,
        check=False,
    )


def test_the_console_entry_keeps_exit_codes_and_flushes_what_it_wrote(tmp_path):
    # it ends the process with os._exit: the status, the piped output and the files
    # written must all survive that
    version = _console(["--version"], tmp_path)
    assert (version.returncode, version.stdout) == (0, f"hystdisc {hystdisc.__version__}\n")
    usage = _console(["simulate", "--no-such-option"], tmp_path)
    assert usage.returncode == 2
    assert usage.stderr.startswith(
        "hystdisc: error: hystdisc simulate: unrecognized arguments: --no-such-option"
    )
    missing = _console(["discover", "missing.csv"], tmp_path)
    assert missing.returncode == 2 and "missing.csv" in missing.stderr
    made = _console(["simulate", "--model", "dahl", "--duration", "1", "-o", "d.csv"], tmp_path)
    assert made.returncode == 0, made.stderr
    assert made.stdout.endswith("\n") and "d.csv" in made.stdout
    rows = (tmp_path / "d.csv").read_text().splitlines()
    assert rows[0].split(",")[0] == "run" and len(rows) > 1000


#: A complete command line of each command (nothing runs: the option error comes first).
_VALID = {
    "discover": ["x.csv"],
    "predict": ["r.json", "d.csv", "-o", "p.csv"],
    "simulate": ["--model", "dahl", "-o", "x.csv"],
    "report": ["x.csv"],
    "study": ["--model", "dahl", "--vary", "rho=2,3", "-o", "x.png"],
    "design": ["r.json"],
}


@pytest.mark.parametrize("command", COMMANDS)
def test_an_unknown_option_points_to_the_subcommands_help(command, capsys):
    from hystdisc.cli import main

    with pytest.raises(SystemExit) as exit_:
        main([command, *_VALID[command], "--modle"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith(f"hystdisc: error: hystdisc {command}: unrecognized arguments: --modle")
    assert err.rstrip().endswith(f"fix: see hystdisc {command} --help")
    if command in ("discover", "report", "simulate", "study"):  # they have --model
        assert "(did you mean --model?)" in err


def test_an_unknown_option_without_a_command_points_to_the_main_help(capsys):
    from hystdisc.cli import main

    with pytest.raises(SystemExit):
        main(["--modle"])
    err = capsys.readouterr().err
    assert (
        err
        == "hystdisc: error: hystdisc: unrecognized arguments: --modle; fix: see hystdisc --help\n"
    )


@pytest.mark.parametrize("quiet", [False, True])
def test_a_line_is_printed_before_the_first_compile(monkeypatch, capsys, quiet):
    # issue 37: a fresh install compiled for about 40 s without a word
    import numba

    from hystdisc.cli import main
    from hystdisc.cli import simulate as simulate_cmd
    from hystdisc.cli.common import COMPILE_NOTE

    def compiles(args):
        @numba.njit  # not cached: compiled in this process, as a fresh install does
        def twice(x):
            return 2 * x

        twice(1)
        twice(1.5)  # a second compile says nothing more
        return 0

    monkeypatch.setattr(simulate_cmd, "run", compiles)
    argv = ["simulate", "--model", "dahl", "-o", "x.csv", *(["--quiet"] if quiet else [])]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert err == ("" if quiet else COMPILE_NOTE + "\n")
    # after the command the note is gone: a compile outside it prints nothing
    numba.njit(lambda x: x + 1)(1)
    assert capsys.readouterr().err == ""
