"""The layers of docs/architecture.md, checked on the source: who may import whom, no import of ours
hidden inside a function (outside the CLI), no import cycle, no module over 500 lines, and a
packaging that installs every subpackage."""
from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest
from paths import ROOT

PACKAGES = ("simcore", "sweeps", "analysis")
CLI = ("sweeps.cli", "sweeps.until_commands")   # the command line: the top layer

# layer -> the layers it may import (itself included); docs/architecture.md states the same table
ALLOWED = {
    "simcore": {"simcore"},
    "observables": {"simcore", "observables"},
    "sweeps": {"simcore", "observables", "sweeps"},
    "viewer": {"simcore", "observables", "sweeps", "viewer"},
    "reports": {"simcore", "observables", "sweeps", "viewer", "reports"},
    "calibration": {"simcore", "observables", "sweeps", "viewer", "reports", "calibration"},
    "cli": {"simcore", "observables", "sweeps", "viewer", "reports", "calibration", "cli", "analysis"},
    "analysis": set(),  # the namespace package analysis/__init__.py imports nothing
}


def layer(module: str) -> str:
    if module in CLI:
        return "cli"
    for prefix, name in (("analysis.observables", "observables"), ("analysis.reports", "reports"),
                         ("analysis.calibration", "calibration"), ("analysis.viewer", "viewer")):
        if module == prefix or module.startswith(prefix + "."):
            return name
    top = module.split(".")[0]
    if top == "analysis":
        return "analysis"
    return top


def modules() -> dict[str, Path]:
    out = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def our_imports(module: str, path: Path):
    """(imported module, line, at module level?) for every import of our packages in ``path``."""
    tree = ast.parse(path.read_text())
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    top_level = {id(node) for node in tree.body}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                prefix = ".".join(base)
                target = f"{prefix}.{node.module}" if node.module else prefix
                names = [target] if node.module else [f"{prefix}.{a.name}" for a in node.names]
            else:
                names = [node.module]
        else:
            continue
        for name in names:
            if name.split(".")[0] in PACKAGES:
                yield name, node.lineno, id(node) in top_level


def resolve(name: str, known: dict) -> str:
    """The module an imported name lives in (``from sweeps.store import X`` names sweeps.store)."""
    while name not in known and "." in name:
        name = name.rsplit(".", 1)[0]
    return name


@pytest.fixture(scope="module")
def graph():
    known = modules()
    return known, {m: list(our_imports(m, p)) for m, p in known.items()}


def test_every_import_follows_the_layers(graph):
    known, edges = graph
    wrong = [f"{m}:{line} imports {name} ({layer(m)} may not import {layer(resolve(name, known))})"
             for m, imports in edges.items() for name, line, _ in imports
             if layer(resolve(name, known)) not in ALLOWED[layer(m)]]
    assert not wrong, "\n".join(wrong)


def test_no_import_across_layers_is_hidden_in_a_function(graph):
    """A deferred import inside one layer (a package loading its own heavier modules on first use) is
    fine; one that reaches another layer would hide the dependency from this graph."""
    known, edges = graph
    hidden = [f"{m}:{line} imports {name} inside a function" for m, imports in edges.items()
              if m not in CLI for name, line, top in imports
              if not top and layer(resolve(name, known)) != layer(m)]
    assert not hidden, "\n".join(hidden)


def test_the_module_import_graph_has_no_cycle(graph):
    known, edges = graph
    deps = {m: {resolve(name, known) for name, _, top in imports if top} - {m} for m, imports in edges.items()}
    # a package's __init__ is imported with each of its modules; do not count that as an edge back
    state, stack = {}, []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for d in sorted(deps.get(m, ())):
            if state.get(d) == "open":
                raise AssertionError("import cycle: " + " -> ".join(stack[stack.index(d):] + [d]))
            if d not in state:
                visit(d)
        stack.pop()
        state[m] = "done"

    for m in sorted(deps):
        if m not in state:
            visit(m)


def test_simcore_imports_nothing_of_ours_and_observables_only_simcore(graph):
    known, edges = graph
    for m, imports in edges.items():
        targets = {layer(resolve(name, known)) for name, _, _ in imports}
        if layer(m) == "simcore":
            assert targets <= {"simcore"}, m
        if layer(m) == "observables":
            assert targets <= {"simcore", "observables"}, m


def test_no_module_is_longer_than_500_lines():
    long = {str(p.relative_to(ROOT)): n for p in modules().values()
            if (n := len(p.read_text().splitlines())) > 500}
    assert not long, long


def test_packaging_installs_every_subpackage():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    find = config["tool"]["setuptools"]["packages"]["find"]
    from setuptools import find_packages

    found = set(find_packages(where=str(ROOT), include=find["include"]))
    expected = {".".join(p.relative_to(ROOT).parent.parts) for package in PACKAGES
                for p in (ROOT / package).rglob("__init__.py")}
    assert expected <= found, sorted(expected - found)
    assert "analysis.observables" in found and "analysis.calibration" in found


def test_the_public_api_loads_its_layers_only_when_used():
    """``import simcore, sweeps, analysis, analysis.observables`` loads neither the reports, the
    calibration, the viewer nor the sweep runner; every public name of ``sweeps`` and ``analysis`` has a
    home module (in its ``_HOMES`` table) that defines it."""
    import importlib
    import subprocess
    import sys

    code = ("import sys, simcore, sweeps, analysis, analysis.observables\n"
            "print(sorted(m for m in sys.modules if m.startswith(('analysis.reports', 'analysis.calibration', "
            "'analysis.viewer', 'sweeps.runner', 'sweeps.config', 'matplotlib', 'arviz'))))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    for package in ("sweeps", "analysis"):
        module = importlib.import_module(package)
        assert sorted(module.__all__) == sorted(module._HOMES), package
        for name, (home, attribute) in module._HOMES.items():
            path = ROOT / package / (home.replace(".", "/") + ".py")
            tree = ast.parse(path.read_text())
            defined = {node.name for node in tree.body if isinstance(node, (ast.FunctionDef, ast.ClassDef))}
            assert attribute in defined, f"{package}.{name}: {attribute} is not defined in {path.name}"
