"""The tutorial notebooks (jupytext percent scripts in ``notebooks/``) execute without errors.

Each script is converted to a notebook with jupytext and executed by nbclient in a
``python3`` kernel with ``HYSTDISC_NOTEBOOK_FAST=1`` (smaller data); the notebooks run
concurrently, one kernel each, talking over IPC sockets. The measured-data notebook runs
its data cells only when ``HYSTDISC_DATA`` is set.
"""

from __future__ import annotations

import os
import re
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from traitlets.config import Config

jupytext = pytest.importorskip("jupytext")
nbclient = pytest.importorskip("nbclient")

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.py"))
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


def _execute(path: Path, workdir: Path):
    """Execute one notebook in a fresh python3 kernel; return it and the failure, if any."""
    nb = jupytext.read(path)
    client = nbclient.NotebookClient(
        nb,
        timeout=CELL_TIMEOUT,
        kernel_name="python3",
        resources={"metadata": {"path": str(workdir)}},
        # IPC sockets in the notebook's own folder, not TCP ports: a TCP kernel picks free
        # ports, releases them and binds them again, and a Dask cluster in another test
        # worker can take one in between; the kernel then dies before replying (a CI
        # failure at 7e4a116).
        config=Config({"KernelManager": {"transport": "ipc", "ip": str(workdir / "kernel")}}),
    )
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}  # the inline backend
    env["HYSTDISC_NOTEBOOK_FAST"] = "1"
    try:
        client.execute(env=env)
    except nbclient.exceptions.CellExecutionError as exc:
        return nb, f"{path.name}: a cell failed:\n{exc}"
    return nb, None


@pytest.fixture(scope="module")
def executed(tmp_path_factory):
    """All notebooks, executed concurrently (one kernel each) on first use."""
    if os.environ.get("HYSTDISC_DATA"):
        # the kernels run in their own folders: a relative data path must not break them
        os.environ["HYSTDISC_DATA"] = str(Path(os.environ["HYSTDISC_DATA"]).resolve())
    pool = ThreadPoolExecutor(max_workers=min(4, max(len(NOTEBOOKS), 1)))
    futures = {p: pool.submit(_execute, p, tmp_path_factory.mktemp(p.stem)) for p in NOTEBOOKS}
    yield futures
    pool.shutdown(wait=True, cancel_futures=True)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_executes(path, executed):
    nb, failure = executed[path].result()
    if failure:
        pytest.fail(failure)
    errors = [
        o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"
    ]
    assert not errors, f"{path.name}: {errors[0]['ename']}: {errors[0]['evalue']}"
    images = [
        o
        for c in nb.cells
        if c.cell_type == "code"
        for o in c.outputs
        if "image/png" in o.get("data", {})
    ]
    if "measured" in path.stem and not os.environ.get("HYSTDISC_DATA"):
        return  # without the data the figures are skipped
    assert images, f"{path.name} drew no figure"
