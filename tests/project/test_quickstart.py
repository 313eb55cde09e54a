"""The README's first hour (issue 37): the two set-up commands and a Quickstart that runs
as printed.

The Quickstart's commands and Python are run in order by ``doc/quickstart.py`` in a folder
holding what a fresh clone holds (``data_synth/``), and what they print must fit what the
README shows (``...`` stands for lines left out). After a change of output,
``python doc/quickstart.py --update`` rewrites the README. About 30 s of CPU: one discover
of the bundled Bouc-Wen set, one of the Dahl set, a report, a design.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _quickstart():
    spec = importlib.util.spec_from_file_location("quickstart", ROOT / "doc" / "quickstart.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("quickstart", mod)  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


def _setup_commands(text: str) -> list[str]:
    block = text.split("## Set-up: two commands", 1)[1].split("```bash", 1)[1].split("```")[0]
    return [line.strip() for line in block.splitlines() if line.strip() and line[0] != "#"]


def test_two_setup_commands_a_light_install_to_run_and_the_dev_install_to_test():
    run, test = _setup_commands(README)  # exactly two
    # running needs no test or docs tools (the dev extra was about 100 packages)
    assert run.startswith("pip install -e . && hystdisc discover ")
    assert test.startswith('pip install -e ".[dev]" && python -m pytest')
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert test.replace("pip install -e", "pip install -q -e", 1) in ci  # quiet, else verbatim
    develop = (ROOT / "doc" / "develop.rst").read_text(encoding="utf-8")
    assert run in develop and test in develop


def test_the_quickstart_writes_into_a_scratch_folder():
    qs = _quickstart()
    outputs = []
    for step in qs.steps(README):
        if step.kind != "python":
            outputs += re.findall(r"(?:-o|--out|--output)\s+(\S+)", step.text)
    assert outputs and all(o == "out" or o.startswith("out/") for o in outputs), outputs
    assert "/out/" in (ROOT / ".gitignore").read_text().splitlines()


def test_every_quickstart_command_runs_as_printed(tmp_path):
    qs = _quickstart()
    steps = qs.steps(README)
    kinds = {s.kind for s in steps}
    assert kinds == {"console", "bash", "python"}, kinds
    assert any(s.text.startswith("hystdisc predict ") for s in steps)
    assert any(s.text.startswith("hystdisc report out/results.json") for s in steps)
    qs.run(steps, tmp_path)  # raises, with the command and its stderr, on a failure
    diffs = qs.differences(steps)
    assert not diffs, "the Quickstart prints something else now (python doc/quickstart.py " + (
        "--update rewrites it):\n" + "\n".join(diffs)
    )
    # what the commands were meant to write
    for name in ("results.json", "results.report.npz", "predicted.csv", "report.html", "rho.png"):
        assert (tmp_path / "out" / name).is_file(), name
