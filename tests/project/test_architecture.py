"""The house rules of doc/develop.rst that a machine can check.

- no import cycle in ``hystdisc``, function-level imports included (importing
  ``hystdisc.a.b`` also runs the package ``hystdisc.a``);
- data flows down the layers: no module imports one of a higher layer;
- no module reads another object's private attributes;
- no module over 900 lines.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "hystdisc"

#: Layers, lowest first (doc/develop.rst, "Package structure"); a module may import its
#: own layer or lower ones.
LAYERS = [
    ("hystdisc", "hystdisc.errors", "hystdisc.stats", "hystdisc.registry"),
    ("hystdisc.experiments",),
    ("hystdisc.data",),
    ("hystdisc.models",),
    ("hystdisc.simulation",),
    ("hystdisc.discovery",),
    ("hystdisc.measurement",),
    ("hystdisc.fitting",),
    ("hystdisc.apply",),
    ("hystdisc.selection",),
    ("hystdisc.closing",),
    ("hystdisc.results",),
    ("hystdisc.design",),
    ("hystdisc.pipeline",),
    ("hystdisc.estimator",),
    ("hystdisc.plotting",),
    ("hystdisc.report",),
    ("hystdisc.cli", "hystdisc.__main__"),
]


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _layer(module: str) -> int:
    best, rank = -1, -1
    for k, names in enumerate(LAYERS):
        for n in names:
            if (module == n or module.startswith(n + ".")) and len(n) > best:
                best, rank = len(n), k
    assert rank >= 0, f"{module} is in no layer: add it to LAYERS and doc/develop.rst"
    return rank


def _runtime_nodes(tree: ast.AST):
    """Every node, except those under ``if TYPE_CHECKING:`` (annotations only, never run)."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                todo.extend(child.orelse)
                continue
            todo.append(child)


def _imports(module: str, path: Path) -> set[str]:
    """Every hystdisc module that ``module`` imports, anywhere in its body."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()
    for node in _runtime_nodes(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([base] if base else []))
            names = [base] + [f"{base}.{a.name}" for a in node.names]
        for name in names:
            if name.split(".")[0] != "hystdisc":
                continue
            parts = name.split(".")
            # the module itself and every package above it run on import (the packages
            # that contain the importer are running already)
            for k in range(1, len(parts) + 1):
                cand = ".".join(parts[:k])
                named = cand in (name, names[0])
                if cand in MODULES and cand != module:
                    if named or not module.startswith(cand + "."):
                        found.add(cand)
    return found


GRAPH = {m: _imports(m, p) for m, p in MODULES.items()}


def test_no_import_cycle():
    # Tarjan-free check: depth-first search with colours, reporting the first cycle found
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        stack.append(m)
        for n in sorted(GRAPH[m]):
            if n == "hystdisc" or m == "hystdisc":
                continue  # the root package only names lazy entry points
            if state.get(n) == 1:
                return stack[stack.index(n) :] + [n]
            if n not in state:
                cyc = visit(n)
                if cyc:
                    return cyc
        stack.pop()
        state[m] = 2
        return None

    for m in sorted(GRAPH):
        if m not in state:
            cyc = visit(m)
            assert cyc is None, "import cycle: " + " -> ".join(cyc)


def test_imports_never_go_up_the_layers():
    bad = [
        f"{m} (layer {_layer(m)}) imports {n} (layer {_layer(n)})"
        for m, deps in GRAPH.items()
        for n in deps
        if n != "hystdisc" and _layer(n) > _layer(m)
    ]
    assert not bad, "\n".join(sorted(bad))


def test_the_root_package_imports_nothing_heavy():
    assert GRAPH["hystdisc"] <= {"hystdisc.errors"}


#: Underscored names that are public by a documented protocol.
PUBLIC_BY_PROTOCOL = {"_exit", "_repr_html_"}  # os._exit in a forked child; IPython display


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_private_attribute_of_another_object(module):
    tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
    bad = []
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and node.attr.startswith("_")
            and not node.attr.startswith("__")
            and node.attr not in PUBLIC_BY_PROTOCOL
            and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))
        ):
            bad.append(f"line {node.lineno}: .{node.attr}")
    assert not bad, f"{module} reads private attributes: {bad}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_module_size(module):
    n = len(MODULES[module].read_text(encoding="utf-8").splitlines())
    assert n <= 900, f"{module} has {n} lines (900 at most; about 600 is the aim)"
