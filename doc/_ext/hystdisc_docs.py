"""Sphinx extension of the hystdisc documentation: pages generated from the code.

- ``builder-inited``: the notebooks (jupytext percent scripts in ``notebooks/``) are
  executed on small data into ``gallery/*.ipynb`` with their outputs and figures (myst-nb
  renders them as they are) and ``gallery/index.rst`` lists them with their titles and
  first paragraphs; the API pages, one per module, go to ``api/generated/``;
- ``.. hystdisc-results-schema::``: the ``results.json`` schema, one table per typed
  record of :mod:`hystdisc.results`, from the dataclass fields and their numpydoc
  ``Attributes``; a field without its ``Attributes`` entry is a build warning;
- ``.. hystdisc-exceptions::``: every error and warning class of the package;
- ``missing-reference``: a reference to a re-exported name (``hystdisc.Discovery``,
  ``hystdisc.models.Param``) resolves to the page of the module that defines it.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil
import sys
import types
import typing
from pathlib import Path

from docutils import nodes
from docutils.statemachine import StringList
from numpydoc.docscrape import NumpyDocString
from sphinx.application import Sphinx
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

logger = logging.getLogger(__name__)

GALLERY = "gallery"


# -- API pages ---------------------------------------------------------------------------
API = "api/generated"


def submodules() -> dict[str, list[str]]:
    """Each package of ``hystdisc`` -> its public submodules, from the files.

    Not from the package's namespace: there a function may hide its module
    (``hystdisc.discovery.varpro``).
    """
    import hystdisc

    out: dict[str, list[str]] = {}

    def walk(path: list[str], name: str) -> None:
        subs = out.setdefault(name, [])
        for info in pkgutil.iter_modules(path):
            if info.name.startswith("_"):
                continue
            subs.append(f"{name}.{info.name}")
            if info.ispkg:
                walk([str(Path(path[0]) / info.name)], f"{name}.{info.name}")

    walk(list(hystdisc.__path__), "hystdisc")
    return out


def _summary_names(mod: types.ModuleType, package: bool) -> list[str]:
    """The functions and classes a module's page lists: its ``__all__`` (a package's are
    its exports, documented where they are defined), else those it defines."""
    names = getattr(mod, "__all__", None)
    if names is None:
        names = [n for n, o in vars(mod).items() if getattr(o, "__module__", None) == mod.__name__]
    out = []
    for name in names:
        obj = getattr(mod, name, None)
        if name.startswith("_") or not (inspect.isclass(obj) or inspect.isfunction(obj)):
            continue
        if package or obj.__module__ == mod.__name__:
            out.append(name)
    return out


def _first_line(obj) -> str:
    """The first paragraph of ``obj``'s docstring, on one line."""
    return " ".join((inspect.getdoc(obj) or "").strip().split("\n\n")[0].split())


def module_page(name: str, subs: list[str] | None) -> str:
    """The reStructuredText of one module's API page."""
    mod = importlib.import_module(name)
    package = subs is not None
    lines = [name, "=" * len(name), "", f".. automodule:: {name}"]
    if package:  # what the package only re-exports is documented where it is defined
        lines += ["   :ignore-module-all:"]
    names = _summary_names(mod, package)
    if names:
        lines += ["", f".. rubric:: {'Exported names' if package else 'Summary'}", ""]
        lines += [".. autosummary::", "   :nosignatures:", ""] + [f"   {n}" for n in names]
    if subs:
        lines += ["", ".. rubric:: Modules", ""]
        for sub in subs:
            summary = _first_line(importlib.import_module(sub))
            lines += [f"* :doc:`{sub}` — {summary}"]
        lines += ["", ".. toctree::", "   :hidden:", ""] + [f"   {sub}" for sub in subs]
    return "\n".join(lines) + "\n"


class ModuleIndex(SphinxDirective):
    """``.. hystdisc-modules::``: every module of the package, nested as the packages are,
    each linked to its API page with the first line of its docstring."""

    def run(self) -> list[nodes.Node]:
        tree = submodules()
        lines: list[str] = []

        def entry(name: str, depth: int) -> None:
            summary = _first_line(importlib.import_module(name))
            lines.extend(["", f"{'  ' * depth}* :doc:`{name} <{API}/{name}>` — {summary}"])
            for sub in tree.get(name, []):
                entry(sub, depth + 1)

        entry("hystdisc", 0)
        container = nodes.container(classes=["hystdisc-modules"])
        self.state.nested_parse(StringList(lines, "<modules>"), self.content_offset, container)
        return container.children


def build_api(app: Sphinx) -> None:
    """Write one page per module of ``hystdisc`` into ``api/generated/``."""
    out = Path(app.srcdir) / API
    out.mkdir(parents=True, exist_ok=True)
    tree = submodules()
    modules = ["hystdisc"] + [m for subs in tree.values() for m in subs]
    for name in modules:
        _write_if_changed(out / f"{name}.rst", module_page(name, tree.get(name)))
    for old in out.glob("*.rst"):
        if old.stem not in modules:  # a module removed since the last build
            old.unlink()


# -- gallery ------------------------------------------------------------------------------
def _title_and_summary(nb) -> tuple[str, str]:
    """The notebook's title (its first ``#`` line) and its first paragraph after it."""
    for cell in nb.cells:
        if cell.cell_type != "markdown":
            continue
        lines = cell.source.splitlines()
        title = lines[0].lstrip("#").strip() if lines and lines[0].startswith("# ") else ""
        para: list[str] = []
        for line in lines[1:]:
            if line.strip():
                para.append(line.strip())
            elif para:
                break
        return title, " ".join(para)
    return "", ""


def _write_if_changed(path: Path, text: str) -> None:
    """Write ``text`` unless the file holds it already (keeps incremental builds cheap)."""
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


#: What the docs build sets in the notebooks' kernels: the small data of the test suite.
NOTEBOOK_ENV = {"HYSTDISC_NOTEBOOK_FAST": "1"}
#: Longest a cell may run, s.
CELL_TIMEOUT = 600


def _digest(script: Path) -> str:
    """What an executed notebook depends on: its script and the package's sources."""
    import hashlib

    import hystdisc

    h = hashlib.sha256(script.read_bytes())
    for path in sorted(Path(hystdisc.__file__).parent.rglob("*.py")):
        h.update(path.read_bytes())
    h.update(repr(sorted(NOTEBOOK_ENV.items())).encode())
    return h.hexdigest()[:16]


def execute_notebook(nb, workdir: Path, env: dict[str, str]) -> str | None:
    """Execute ``nb`` in place in a fresh ``python3`` kernel; the failure, if any.

    The kernel talks over IPC sockets in ``workdir``, not TCP ports (a TCP kernel picks
    free ports, releases them and binds them again, and another process can take one in
    between: a CI failure at 7e4a116).
    """
    import nbclient
    from traitlets.config import Config

    workdir.mkdir(parents=True, exist_ok=True)
    client = nbclient.NotebookClient(
        nb,
        timeout=CELL_TIMEOUT,
        kernel_name="python3",
        resources={"metadata": {"path": str(workdir)}},
        config=Config({"KernelManager": {"transport": "ipc", "ip": str(workdir / "kernel")}}),
    )
    try:
        client.execute(env=env)
    except nbclient.exceptions.CellExecutionError as exc:
        return str(exc).strip().splitlines()[-1] if str(exc).strip() else repr(exc)
    return None


def build_gallery(app: Sphinx) -> None:
    """Execute the notebooks (small data) into ``gallery/`` and write its index page.

    Each notebook is executed once per change of its script or of the package (the
    digest is kept in the notebook's metadata), concurrently in kernels of their own,
    with :data:`NOTEBOOK_ENV`. A cell that fails is a build warning (an error with
    ``-W``); the measured-data notebook runs its data cells only when ``HYSTDISC_DATA``
    is set. ``hystdisc_execute_notebooks = False`` renders them without outputs.
    """
    import os
    import tempfile
    from concurrent.futures import ThreadPoolExecutor

    import jupytext
    import nbformat

    src = Path(app.config.hystdisc_notebooks)
    scripts = sorted(src.glob("*.py"))
    if not scripts:
        logger.warning("no notebooks found in %s", src)
    out = Path(app.srcdir) / GALLERY
    out.mkdir(exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}  # the inline backend
    env.update(NOTEBOOK_ENV)
    if env.get("HYSTDISC_DATA"):  # the kernels run in their own folders
        env["HYSTDISC_DATA"] = str(Path(env["HYSTDISC_DATA"]).resolve())
    env["PYTHONPATH"] = os.pathsep.join([str(_package_root()), env.get("PYTHONPATH", "")])
    todo = []
    rows = []
    for script in scripts:
        target = out / f"{script.stem}.ipynb"
        digest = _digest(script)
        nb = jupytext.read(script)
        nb.metadata.pop("jupytext", None)
        title, summary = _title_and_summary(nb)
        rows.append((script, title, summary))
        if not app.config.hystdisc_execute_notebooks:
            _write_if_changed(target, nbformat.writes(nb) + "\n")
            continue
        if target.exists():
            old = nbformat.read(target, as_version=4)
            if old.metadata.get("hystdisc", {}).get("digest") == digest:
                continue  # executed already, from the same script and package
        nb.metadata["hystdisc"] = {"digest": digest}
        todo.append((script, target, nb))
    if todo:
        logger.info("executing %d notebooks for the gallery ...", len(todo))
        with (
            tempfile.TemporaryDirectory() as tmp,
            ThreadPoolExecutor(max_workers=min(4, len(todo))) as pool,
        ):
            futures = [
                (
                    script,
                    target,
                    nb,
                    pool.submit(execute_notebook, nb, Path(tmp) / script.stem, env),
                )
                for script, target, nb in todo
            ]
            for script, target, nb, future in futures:
                failure = future.result()
                if failure:
                    logger.warning("notebook %s: a cell failed: %s", script.name, failure)
                    nb.metadata["hystdisc"] = {"failed": failure}  # run it again next time
                target.write_text(nbformat.writes(nb) + "\n", encoding="utf-8")
    lines = [
        "Notebook gallery",
        "================",
        "",
        "Tutorials as notebooks, shown here executed, with their outputs and figures (on",
        "the small data the test suite uses: ``HYSTDISC_NOTEBOOK_FAST=1``). Each is a",
        'jupytext percent script in ``notebooks/``: with ``pip install -e ".[notebooks]"``',
        "Jupyter opens it as a notebook, and ``jupytext --to ipynb --execute notebooks/*.py``",
        "executes them all into notebooks with their outputs beside the scripts.",
        "",
    ]
    for script, _title, summary in rows:
        lines += [f"* :doc:`{script.stem}` (``notebooks/{script.name}``): {summary}", ""]
    lines += [".. toctree::", "   :hidden:", ""]
    lines += [f"   {script.stem}" for script, _, _ in rows]
    _write_if_changed(out / "index.rst", "\n".join(lines) + "\n")


def _package_root() -> Path:
    """The folder that holds the ``hystdisc`` package the docs are built from."""
    import hystdisc

    return Path(hystdisc.__file__).resolve().parent.parent


# -- results.json schema ------------------------------------------------------------------
def _record_types(hint) -> list[type]:
    """The record classes named in a field's type (``dict[str, X] | None`` gives ``[X]``)."""
    from hystdisc.results.record import Record

    if isinstance(hint, type) and issubclass(hint, Record):
        return [hint]
    out: list[type] = []
    for arg in typing.get_args(hint):
        out += _record_types(arg)
    return out


def _schema_rst(root: type) -> tuple[list[str], list[str]]:
    """The schema's reStructuredText (one section per record) and the problems found."""
    order: list[type] = [root]
    lines: list[str] = []
    problems: list[str] = []
    k = 0
    while k < len(order):
        cls = order[k]
        k += 1
        doc = NumpyDocString(inspect.getdoc(cls) or "")
        # numpydoc may document several keys in one entry (``rms_before, rms_after : float``)
        described = {n.strip(): p for p in doc["Attributes"] for n in p.name.split(",")}
        names = {**vars(typing), **vars(sys.modules[cls.__module__])}
        title = "Top level" if cls is root else f"``{cls.__name__}``"
        summary = " ".join(doc["Summary"])
        lines += [f".. _schema-{cls.__name__.lower()}:", "", title, "-" * len(title), ""]
        lines += [f"{summary} (:class:`{cls.__module__}.{cls.__qualname__}`)", ""]
        lines += [".. list-table::", "   :header-rows: 1", "   :widths: 20 25 55", ""]
        lines += ["   * - key", "     - type", "     - meaning"]
        for f in dataclasses.fields(cls):
            if f.name == "extra":
                continue
            hint = eval(f.type, names) if isinstance(f.type, str) else f.type  # noqa: S307
            nested = _record_types(hint)
            for rec in nested:
                if rec not in order:
                    order.append(rec)
            entry = described.get(f.name)
            if entry is None:
                problems.append(f"{cls.__qualname__}.{f.name} has no Attributes entry")
                kind, desc = "", []
            else:
                kind, desc = entry.type, entry.desc
            for rec in nested:
                kind = kind.replace(
                    rec.__name__, f":ref:`{rec.__name__} <schema-{rec.__name__.lower()}>`"
                )
            lines += [f"   * - ``{f.name}``", f"     - {kind}"]
            lines += [f"     - {desc[0] if desc else ''}"] + [f"       {d}" for d in desc[1:]]
        lines += [""]
    return lines, problems


class ResultsSchema(SphinxDirective):
    """``.. hystdisc-results-schema::``: the tables of ``results.json``."""

    def run(self) -> list[nodes.Node]:
        from hystdisc.results import SCHEMA_VERSION, Results

        lines, problems = _schema_rst(Results)
        for p in problems:
            logger.warning("results.json schema: %s", p, location=self.get_location())
        head = [f"This is schema {SCHEMA_VERSION} (``schema_version``).", ""]
        container = nodes.section()
        nested_parse_with_titles(
            self.state, StringList(head + lines, "<results schema>"), container
        )
        return container.children


# -- error and warning classes ------------------------------------------------------------
def _package_modules() -> list[types.ModuleType]:
    """Every module of ``hystdisc`` (imported; ``__main__`` would run the command line)."""
    import hystdisc

    names = [m.name for m in pkgutil.walk_packages(hystdisc.__path__, "hystdisc.")]
    return [hystdisc] + [importlib.import_module(n) for n in names if not n.endswith("__main__")]


class Exceptions(SphinxDirective):
    """``.. hystdisc-exceptions::``: a table of the package's error and warning classes."""

    def run(self) -> list[nodes.Node]:
        found: dict[str, type] = {}
        for mod in _package_modules():
            for name, obj in vars(mod).items():
                if (
                    isinstance(obj, type)
                    and issubclass(obj, (Exception, Warning))
                    and obj.__module__ == mod.__name__
                    and not name.startswith("_")
                ):
                    found[f"{obj.__module__}.{obj.__qualname__}"] = obj
        lines = [".. list-table::", "   :header-rows: 1", "   :widths: 35 25 40", ""]
        lines += ["   * - class", "     - kind", "     - what it means"]
        for full, cls in sorted(
            found.items(),
            key=lambda kv: (not issubclass(kv[1], Exception) or issubclass(kv[1], Warning), kv[0]),
        ):
            kind = "warning" if issubclass(cls, Warning) else "error"
            bases = ", ".join(f":class:`~{b.__module__}.{b.__qualname__}`" for b in cls.__bases__)
            summary = (inspect.getdoc(cls) or "").split("\n\n")[0].replace("\n", " ")
            lines += [f"   * - :class:`~{full}`", f"     - {kind} ({bases})", f"     - {summary}"]
        container = nodes.container()
        self.state.nested_parse(StringList(lines, "<exceptions>"), self.content_offset, container)
        return container.children


# -- references to re-exported names ------------------------------------------------------
def _lookup(target: str):
    """The object ``target`` names (``hystdisc.models.Param``), or None."""
    parts = target.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        try:
            for attr in parts[k:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return None
        return obj
    return None


def resolve_reexport(app: Sphinx, env, node, contnode):
    """Resolve ``hystdisc.X`` to where ``X`` is documented (the module defining it)."""
    target = node.get("reftarget", "")
    if node.get("refdomain") != "py" or not target.startswith("hystdisc."):
        return None
    obj = _lookup(target)
    if obj is None:
        return None
    head, _, last = target.rpartition(".")
    candidates = []
    module = getattr(obj, "__module__", None)
    qualname = getattr(obj, "__qualname__", None)
    if isinstance(module, str) and isinstance(qualname, str):
        candidates.append(f"{module}.{qualname}")
    # data (and anything else) defined in a submodule of the named package
    candidates += [
        f"{name}.{last}"
        for name, mod in sorted(sys.modules.items())
        if name.startswith(head + ".") and getattr(mod, last, None) is obj
    ]
    domain = env.domains["py"]
    for cand in candidates:
        if cand == target:
            continue
        ref = domain.resolve_xref(
            env, node["refdoc"], app.builder, node["reftype"], cand, node, contnode
        )
        if ref is not None:
            return ref
    return None


def skip_foreign_member(app: Sphinx, what: str, name: str, obj, skip: bool, options):
    """Skip a class's members made by another package (scikit-learn's ``set_*_request``)."""
    module = getattr(obj, "__module__", None)
    if what == "class" and isinstance(module, str) and not module.startswith("hystdisc"):
        return True
    return None


def template_once(app: Sphinx) -> None:
    """Make numpydoc compile its docstring template once, not once per docstring.

    numpydoc builds a new Jinja environment, and so compiles its template again, for every
    docstring: half of this build's time. The template and the rest of the call are
    numpydoc's own; with another numpydoc than expected this does nothing.
    """
    try:
        import numpydoc.docscrape_sphinx as ds
        import numpydoc.numpydoc as nd

        slow = nd.get_doc_object
        orig = ds.get_doc_object_orig
        kinds = {
            "class_doc": ds.SphinxClassDoc,
            "func_doc": ds.SphinxFunctionDoc,
            "obj_doc": ds.SphinxObjDoc,
        }
    except (ImportError, AttributeError):
        return
    cache = {}

    def get_doc_object(obj, what=None, doc=None, config=None, builder=None):
        config = {} if config is None else config
        key = builder is None  # numpydoc loads the template through the builder, if any
        if key not in cache:
            slow(None, "object", "", config, builder)  # compiles it into config
            cache[key] = config["template"]
        config["template"] = cache[key]
        return orig(obj, what=what, doc=doc, config=config, **kinds)

    nd.get_doc_object = get_doc_object


def setup(app: Sphinx) -> dict:
    app.add_config_value("hystdisc_notebooks", "", "env")
    app.add_config_value("hystdisc_execute_notebooks", True, "env")
    app.connect("builder-inited", build_api)
    app.connect("builder-inited", build_gallery)
    app.connect("builder-inited", template_once)
    app.connect("missing-reference", resolve_reexport)
    app.connect("autodoc-skip-member", skip_foreign_member)
    app.add_directive("hystdisc-results-schema", ResultsSchema)
    app.add_directive("hystdisc-exceptions", Exceptions)
    app.add_directive("hystdisc-modules", ModuleIndex)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
