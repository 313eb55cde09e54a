"""The tutorial notebooks (jupytext percent scripts in ``notebooks/``): tutorials, and how
a user runs them.

The notebooks are executed, with ``HYSTDISC_NOTEBOOK_FAST=1`` (smaller data), by the docs
build into the gallery with their outputs and figures, and ``tests/project/test_docs.py`` checks
them there (no errors, every cell run, figures drawn): executing them here as well would
cost CI a minute more. Here: each is a tutorial without drawing code of its own, the
``notebooks`` extra installs Jupyter and what executes them, and the README's command
executes a notebook into an ``.ipynb`` that keeps its figures.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

jupytext = pytest.importorskip("jupytext")

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.py"))
CELL_TIMEOUT = 300  # s

#: Drawing calls that belong in hystdisc.plotting, not in a notebook.
_DRAWING = re.compile(
    r"\.(plot|scatter|bar|barh|loglog|semilogx|semilogy|fill_between|hist|errorbar|imshow|"
    r"axhline|axvline|contour|contourf|step|stem)\("
)


def test_notebooks_exist():
    names = [p.name for p in NOTEBOOKS]
    for prefix in ("01_term_selection", "02_family_comparison", "03_closing_loop", "04_measured"):
        assert any(n.startswith(prefix) for n in names), f"{prefix}*.py missing from notebooks/"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_is_a_tutorial(path):
    nb = jupytext.read(path)
    assert nb.metadata["kernelspec"]["name"] == "python3"
    assert nb.metadata["jupytext"]["text_representation"]["format_name"] == "percent"
    markdown = [c for c in nb.cells if c.cell_type == "markdown"]
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert markdown[0].source.startswith("# "), "the notebook opens with a title"
    assert len(markdown) >= 5 and len(code) >= 4
    for cell in code:
        found = _DRAWING.search(cell.source)
        assert found is None, (
            f"drawing code in a notebook ({found.group(0)}): use hystdisc.plotting"
        )


def _readme_command() -> str:
    """The README's command that executes the notebooks with their outputs."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    (line,) = [x for x in readme.splitlines() if x.startswith("jupytext ") and "--execute" in x]
    return line.split("  #", 1)[0].strip()


def test_the_notebooks_extra_installs_jupyter_and_what_executes_them():
    # issue 37: the README said to open them in Jupyter, but no extra installed Jupyter,
    # and jupytext --execute failed for want of nbconvert
    with open(ROOT / "pyproject.toml", "rb") as f:
        extras = tomllib.load(f)["project"]["optional-dependencies"]
    names = {re.split(r"[<>=\[ ;]", d, maxsplit=1)[0].lower() for d in extras["notebooks"]}
    assert {"jupyterlab", "jupytext", "nbconvert", "ipykernel"} <= names
    assert 'pip install -e ".[notebooks]"' in (ROOT / "README.md").read_text(encoding="utf-8")
    assert _readme_command().endswith("notebooks/*.py")


def test_the_documented_command_executes_a_notebook_with_its_figures(tmp_path):
    # run as scripts the notebooks lost every figure; the README's command keeps them
    pytest.importorskip("nbconvert", reason="jupytext --execute needs nbconvert (dev extra)")
    import shutil
    import subprocess
    import sys

    script = tmp_path / "notebooks" / "tiny.py"
    script.parent.mkdir()
    header = NOTEBOOKS[0].read_text(encoding="utf-8").split("# %%", 1)[0]  # its kernel
    script.write_text(
        header + "# %% [markdown]\n# # A tiny notebook\n\n"
        "# %%\nfrom hystdisc.plotting import plot_loops\n"
        "import numpy as np\nt = np.linspace(0, 6.3, 200)\n"
        "plot_loops(t, np.sin(t), np.cos(t), np.tanh(5 * np.cos(t)))\n"
    )
    jupytext_cli = shutil.which("jupytext", path=str(Path(sys.executable).parent))
    assert jupytext_cli, "the jupytext command is missing"
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    proc = subprocess.run(
        ["bash", "-c", _readme_command()],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=CELL_TIMEOUT,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    nb = jupytext.read(tmp_path / "notebooks" / "tiny.ipynb")
    images = [
        o
        for c in nb.cells
        if c.cell_type == "code"
        for o in c.outputs
        if "image/png" in o.get("data", {})
    ]
    assert images, "the executed notebook holds no figure"
