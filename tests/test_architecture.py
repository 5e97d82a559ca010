"""The layers of docs/architecture.md, checked on the source: each top-level package is one layer and
imports only the layers below it, whether at module level or inside a function (no special case: the
command line is the top layer, ``flocksweep/``); inside ``analysis/`` the viewer, reports and calibration
are ordered the same way; neither the module graph nor the folder graph has a cycle, deferred imports
included; no module is absurdly long (a sanity cap that should never bind: one concept per module is the
rule, not a line count); and the packaging installs every subpackage."""
from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest
from paths import ROOT

# bottom to top; docs/architecture.md states the same table
PACKAGES = ("simcore", "observables", "sweeps", "analysis", "flocksweep")
# inside analysis/, bottom to top (analysis/__init__.py is a namespace below all three: it imports nothing)
ANALYSIS = ("viewer", "reports", "calibration")
SANITY_CAP = 800


def layer(module: str) -> tuple[int, int]:
    """(top-level layer, sub-layer inside analysis/) of a module: imports may only go to a lower or equal
    pair (the analysis namespace package itself is (3, -1), below its subpackages)."""
    parts = module.split(".")
    top = PACKAGES.index(parts[0])
    if parts[0] == "analysis":
        return top, ANALYSIS.index(parts[1]) if len(parts) > 1 and parts[1] in ANALYSIS else -1
    return top, 0


def folder(module: str) -> str:
    """The folder a module belongs to for the folder graph (analysis split into its subpackages)."""
    parts = module.split(".")
    if parts[0] == "analysis" and len(parts) > 1 and parts[1] in ANALYSIS:
        return f"analysis.{parts[1]}"
    return parts[0]


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
    """Module-level and deferred imports alike go down the layer table (or stay in their own layer)."""
    known, edges = graph
    wrong = [f"{m}:{line} imports {name} ({'deferred' if not top else 'module level'}: layer {layer(m)} may "
             f"not import layer {layer(resolve(name, known))})"
             for m, imports in edges.items() for name, line, top in imports
             if layer(resolve(name, known)) > layer(m)]
    assert not wrong, "\n".join(wrong)


def _cycle(deps: dict) -> list | None:
    state, stack = {}, []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for d in sorted(deps.get(m, ())):
            if state.get(d) == "open":
                return stack[stack.index(d):] + [d]
            if d not in state and (found := visit(d)):
                return found
        stack.pop()
        state[m] = "done"
        return None

    for m in sorted(deps):
        if m not in state and (found := visit(m)):
            return found
    return None


def test_the_module_import_graph_has_no_cycle_deferred_imports_included(graph):
    known, edges = graph
    deps = {m: {resolve(name, known) for name, _, _ in imports} - {m} for m, imports in edges.items()}
    # a package's own __init__ re-exporting its modules is not an edge back from them
    for m in deps:
        deps[m] = {d for d in deps[m] if not m.startswith(d + ".")}
    found = _cycle(deps)
    assert found is None, "import cycle: " + " -> ".join(found)


def test_the_folder_graph_has_no_cycle_and_goes_down_the_table(graph):
    known, edges = graph
    deps: dict[str, set] = {}
    for m, imports in edges.items():
        for name, _, _ in imports:
            target = resolve(name, known)
            if folder(target) != folder(m) and target != "analysis":
                deps.setdefault(folder(m), set()).add(folder(target))
    assert _cycle(deps) is None, deps
    order = ["simcore", "observables", "sweeps", "analysis.viewer", "analysis.reports", "analysis.calibration",
             "flocksweep"]
    upward = [(a, b) for a, targets in deps.items() for b in targets if order.index(b) > order.index(a)]
    assert not upward, upward


def test_simcore_imports_nothing_of_ours_and_observables_only_simcore(graph):
    known, edges = graph
    for m, imports in edges.items():
        targets = {resolve(name, known).split(".")[0] for name, _, _ in imports}
        if m.split(".")[0] == "simcore":
            assert targets <= {"simcore"}, m
        if m.split(".")[0] == "observables":
            assert targets <= {"simcore", "observables"}, m


def test_no_module_is_absurdly_long():
    long = {str(p.relative_to(ROOT)): n for p in modules().values()
            if (n := len(p.read_text().splitlines())) > SANITY_CAP}
    assert not long, long


def test_packaging_installs_every_subpackage():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    find = config["tool"]["setuptools"]["packages"]["find"]
    from setuptools import find_packages

    found = set(find_packages(where=str(ROOT), include=find["include"]))
    expected = {".".join(p.relative_to(ROOT).parent.parts) for package in PACKAGES
                for p in (ROOT / package).rglob("__init__.py")}
    assert expected <= found, sorted(expected - found)
    assert {"observables", "flocksweep", "analysis.calibration"} <= found


def test_the_public_api_loads_its_layers_only_when_used():
    """``import simcore, observables, sweeps, analysis, flocksweep`` loads neither the reports, the
    calibration, the viewer nor the sweep runner; every public name of ``sweeps`` and ``analysis`` has a
    home module (in its ``_HOMES`` table) that defines it, and every name of ``flocksweep`` resolves to the
    same object as in its layer."""
    import importlib
    import subprocess
    import sys

    code = ("import sys, simcore, sweeps, analysis, observables, flocksweep\n"
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
    import flocksweep

    assert sorted(flocksweep.__all__) == sorted(list(flocksweep._HOMES) + ["__version__"])
    for name, (package, attribute) in flocksweep._HOMES.items():
        assert getattr(flocksweep, name) is getattr(importlib.import_module(package), attribute), name
