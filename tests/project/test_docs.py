"""The documentation: the Sphinx site builds with warnings as errors, and the docstrings.

The site (``doc/``) is built once, from a copy of ``doc/``, ``README.md`` and
``notebooks/`` in a temporary folder (the build writes generated pages beside its
sources), with the package of this tree. The build executes the notebooks on small data
(``HYSTDISC_NOTEBOOK_FAST=1``, concurrently, one kernel each) into the gallery with their
outputs and figures: this is where the test suite executes the notebooks (the measured-
data notebook runs its data cells only when ``HYSTDISC_DATA`` is set). About 75 s of CPU,
of which the API pages are 35 s.

The docstring rules of ``doc/develop.rst`` ("Style"): every public module, function,
class and method has a docstring, and the names :mod:`hystdisc` exports document their
parameters and what they return in numpydoc sections (numpydoc's own validator).
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import os
import pkgutil
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import hystdisc

ROOT = Path(__file__).resolve().parents[2]

#: Every module of the package (``__main__`` runs the command line when imported).
MODULES = sorted(
    ["hystdisc"]
    + [
        m.name
        for m in pkgutil.walk_packages(hystdisc.__path__, "hystdisc.")
        if not m.name.split(".")[-1].startswith("_")
    ]
)


def _copy_sources(dest: Path) -> Path:
    """Copy what the build reads into ``dest``; return the copy of ``doc/``."""
    ignore = shutil.ignore_patterns("_build", "generated", "gallery", "__pycache__")
    shutil.copytree(ROOT / "doc", dest / "doc", ignore=ignore)
    shutil.copytree(ROOT / "notebooks", dest / "notebooks", ignore=ignore)
    shutil.copy2(ROOT / "README.md", dest / "README.md")
    return dest / "doc"


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """Build the HTML site with ``-W --keep-going``; the output folder and the log."""
    for name in ("sphinx", "numpydoc", "myst_nb", "jupytext"):
        pytest.importorskip(name, reason=f"{name} builds the docs: pip install -e '.[docs]'")
    tmp = tmp_path_factory.mktemp("docs")
    src = _copy_sources(tmp / "src")
    out = tmp / "html"
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    )
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html"]
    cmd += ["-d", str(tmp / "doctrees"), str(src), str(out)]
    if env.get("HYSTDISC_DATA"):  # the kernels run in their own folders
        env["HYSTDISC_DATA"] = str(Path(env["HYSTDISC_DATA"]).resolve())
    proc = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True, timeout=1800)
    return out, proc


def test_the_site_builds_without_warnings(site):
    out, proc = site
    assert proc.returncode == 0, f"sphinx-build failed:\n{proc.stderr[-6000:]}"
    assert "WARNING" not in proc.stderr and "ERROR" not in proc.stderr, proc.stderr[-6000:]
    for page in ("index", "quickstart", "schema", "errors", "api", "design", "develop"):
        assert (out / f"{page}.html").is_file(), f"{page}.html missing"


def test_every_module_has_an_api_page(site):
    out, _ = site
    missing = [m for m in MODULES if not (out / "api" / "generated" / f"{m}.html").is_file()]
    assert not missing, f"modules without an API page: {missing}"
    page = (out / "api" / "generated" / "hystdisc.estimator.html").read_text(encoding="utf-8")
    assert 'id="hystdisc.estimator.Discovery.fit"' in page  # methods are documented
    # a name documented where it is defined, and the package's re-export links to it
    root = (out / "api" / "generated" / "hystdisc.html").read_text(encoding="utf-8")
    assert 'href="hystdisc.estimator.html#hystdisc.estimator.Discovery"' in root


def test_every_notebook_is_in_the_gallery(site):
    out, _ = site
    index = (out / "gallery" / "index.html").read_text(encoding="utf-8")
    for script in sorted((ROOT / "notebooks").glob("*.py")):
        page = out / "gallery" / f"{script.stem}.html"
        assert page.is_file(), f"{script.name} is not rendered"
        assert f'href="{script.stem}.html"' in index
        lines = script.read_text(encoding="utf-8").splitlines()
        title = next(line for line in lines if line.startswith("# # "))[4:]
        assert title.split(":")[0] in page.read_text(encoding="utf-8")


def _executed(site, stem: str):
    import nbformat

    out, _ = site
    return nbformat.read(out.parent / "src" / "doc" / "gallery" / f"{stem}.ipynb", as_version=4)


@pytest.mark.parametrize("stem", [p.stem for p in sorted((ROOT / "notebooks").glob("*.py"))])
def test_the_gallery_shows_each_notebook_executed_with_its_figures(site, stem):
    # issue 37: the gallery showed code without outputs or figures
    nb = _executed(site, stem)
    code = [c for c in nb.cells if c.cell_type == "code"]
    errors = [o for c in code for o in c.outputs if o.output_type == "error"]
    assert not errors, f"{stem}: {errors[0]['ename']}: {errors[0]['evalue']}"
    assert all(c.get("execution_count") for c in code), f"{stem}: a cell did not run"
    images = [o for c in code for o in c.outputs if "image/png" in o.get("data", {})]
    page = (site[0] / "gallery" / f"{stem}.html").read_text(encoding="utf-8")
    if "measured" in stem and not os.environ.get("HYSTDISC_DATA"):
        return  # without the data the figures are skipped
    assert images, f"{stem} drew no figure"
    assert page.count("<img") >= len(images), f"{stem}: the page lacks its figures"


def test_code_and_outputs_wrap_instead_of_being_cut(site):
    out, _ = site
    page = (out / "gallery" / "01_term_selection.html").read_text(encoding="utf-8")
    assert "_static/hystdisc.css" in page
    css = (out / "_static" / "hystdisc.css").read_text(encoding="utf-8")
    assert "white-space: pre-wrap" in css


def test_the_api_index_lists_every_module(site):
    # issue 37: the API landing page was nearly empty
    out, _ = site
    page = (out / "api.html").read_text(encoding="utf-8")
    missing = [m for m in MODULES if f'href="api/generated/{m}.html"' not in page]
    assert not missing, f"modules missing from the API index: {missing}"
    summary = " ".join(importlib.import_module("hystdisc.report").__doc__.split("\n\n")[0].split())
    assert summary[:40] in page.replace("\n", " ")


def test_the_schema_page_lists_every_key(site):
    from hystdisc.results import SCHEMA_VERSION, Results
    from hystdisc.results.records import FamilyResult, ParameterResult

    out, _ = site
    page = (out / "schema.html").read_text(encoding="utf-8")
    assert f"This is schema {SCHEMA_VERSION}" in page
    for cls in (Results, FamilyResult, ParameterResult):
        for f in dataclasses.fields(cls):
            if f.name != "extra":
                assert f'<span class="pre">{f.name}</span>' in page, f"{cls.__name__}.{f.name}"


def test_the_errors_page_lists_every_error_and_warning_class(site):
    out, _ = site
    page = (out / "errors.html").read_text(encoding="utf-8")
    for name in ("HystdiscError", "HystdiscWarning", "ImplausibleUnitsWarning", "SchemaError"):
        assert name in page
    assert "re-save the file as UTF-8" in page  # a row of the README's table


# -- docstrings ---------------------------------------------------------------------------
def _public_objects():
    """``(name, object)`` of every public function, class and method of the package."""
    for modname in MODULES:
        mod = importlib.import_module(modname)
        yield modname, mod
        for name, obj in vars(mod).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != modname:
                continue
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            yield f"{modname}.{name}", obj
            if inspect.isclass(obj):
                for attr, member in _methods(obj):
                    # looked up through the class: an override inherits its docstring
                    yield f"{modname}.{name}.{attr}", getattr(obj, attr, member)


def _methods(cls):
    """The public methods and properties a class defines itself."""
    for attr, member in vars(cls).items():
        if attr.startswith("_"):
            continue
        if isinstance(member, (staticmethod, classmethod)):
            member = member.__func__
        if inspect.isfunction(member) or isinstance(member, property):
            yield attr, member


def test_every_public_object_has_a_docstring():
    missing = [name for name, obj in _public_objects() if not (inspect.getdoc(obj) or "").strip()]
    assert not missing, f"{len(missing)} public objects without a docstring: {missing}"


def _exported():
    """The canonical names of what :mod:`hystdisc` exports, and their public methods."""
    for name in hystdisc.__all__:
        if name.startswith("_"):
            continue
        obj = getattr(hystdisc, name)
        canonical = f"{obj.__module__}.{obj.__qualname__}"
        yield canonical, obj
        if inspect.isclass(obj):
            for attr, member in _methods(obj):
                yield f"{canonical}.{attr}", member


#: Exported methods still without their numpydoc sections: ``estimator.py`` is at the
#: 900-line limit of doc/develop.rst (their sections need about 30 lines); document them
#: when the module is split. The test fails when one of them is fixed (remove it here).
KNOWN_GAPS: set[str] = set()


def test_the_exported_names_document_parameters_and_returns():
    validate = pytest.importorskip("numpydoc.validate").validate
    # GL08: no docstring; PR01/PR02: a parameter undocumented / documented but absent;
    # RT01: a function that returns something has no Returns section
    codes = {"GL08", "PR01", "PR02", "RT01"}
    bad = {}
    for name, obj in _exported():
        errors = {code: msg for code, msg in validate(name)["errors"] if code in codes}
        if dataclasses.is_dataclass(obj):
            errors.pop("PR01", None)  # a record's fields are its Attributes (schema page)
        if errors and name not in KNOWN_GAPS:
            bad[name] = errors
        if not errors and name in KNOWN_GAPS:
            bad[name] = "documented now: remove it from KNOWN_GAPS"
    assert not bad, "\n".join(f"{k}: {v}" for k, v in bad.items())
