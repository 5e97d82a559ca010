"""The layers of docs/architecture.md, checked on the source: each top-level package is one layer and
imports only the layers below it, whether at module level or inside a function (no special case: the
command line is the top layer, ``flocksweep/``); inside ``analysis/`` the viewer, reports and calibration
are ordered the same way; neither the module graph nor the folder graph has a cycle, deferred imports
included; no module is absurdly long (a sanity cap that should never bind: one concept per module is the
rule, not a line count); the packaging installs every subpackage under the one import name, ``flocksweep``, and nothing imports
a layer by its folder name."""
from __future__ import annotations

import ast
import re
import sys
import tomllib
from pathlib import Path

import pytest
from paths import ROOT

# bottom to top; docs/architecture.md states the same table. Each layer is a top-level folder of the
# repository, installed as a subpackage of the one import name (simcore/ is flocksweep.simcore); the
# command line's folder, flocksweep/, is the top layer, except for the namespace root below every layer:
# flocksweep/__init__.py, flocksweep/lazy.py and flocksweep/ticker.py, which import only the standard library.
PACKAGES = ("simcore", "observables", "sweeps", "analysis", "flocksweep")
ROOT_MODULES = ("flocksweep", "flocksweep.lazy", "flocksweep.ticker")
# inside analysis/, bottom to top (analysis/__init__.py is a namespace below all three: it imports nothing)
ANALYSIS = ("viewer", "reports", "calibration")
SANITY_CAP = 800


def folder_of(module: str) -> tuple[str, ...]:
    """The repository path parts of a module's layer name: ``flocksweep.simcore.kernel`` -> (simcore,
    kernel); ``flocksweep.cli`` -> (flocksweep, cli)."""
    parts = module.split(".")[1:]
    if parts and parts[0] in PACKAGES[:-1]:
        return tuple(parts)
    return ("flocksweep", *parts)


def layer(module: str) -> tuple[int, int]:
    """(top-level layer, sub-layer inside analysis/) of a module: imports may only go to a lower or equal
    pair (the analysis namespace package itself is (3, -1), below its subpackages; the namespace root is
    (-1, 0), below everything)."""
    if module in ROOT_MODULES:
        return -1, 0
    parts = folder_of(module)
    top = PACKAGES.index(parts[0])
    if parts[0] == "analysis":
        return top, ANALYSIS.index(parts[1]) if len(parts) > 1 and parts[1] in ANALYSIS else -1
    return top, 0


def folder(module: str) -> str:
    """The folder a module belongs to for the folder graph (analysis split into its subpackages)."""
    if module in ROOT_MODULES:
        return "root"
    parts = folder_of(module)
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
            name = ".".join(parts) if package == "flocksweep" else "flocksweep." + ".".join(parts)
            out[name] = path
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
            if name.split(".")[0] == "flocksweep":
                yield name, node.lineno, id(node) in top_level


def resolve(name: str, known: dict) -> str:
    """The module an imported name lives in (``from flocksweep.sweeps.store import X`` names sweeps.store)."""
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
            if folder(target) != folder(m) and target != "flocksweep.analysis":
                deps.setdefault(folder(m), set()).add(folder(target))
    assert _cycle(deps) is None, deps
    order = ["root", "simcore", "observables", "sweeps", "analysis", "analysis.viewer", "analysis.reports",
             "analysis.calibration", "flocksweep"]
    upward = [(a, b) for a, targets in deps.items() for b in targets if order.index(b) > order.index(a)]
    assert not upward, upward


def test_simcore_imports_nothing_of_ours_and_observables_only_simcore(graph):
    known, edges = graph
    for m, imports in edges.items():
        targets = {folder(resolve(name, known)) for name, _, _ in imports}
        if folder(m) == "simcore":
            assert targets <= {"simcore", "root"}, m
        if folder(m) == "observables":
            assert targets <= {"simcore", "observables", "root"}, m


def test_the_namespace_root_imports_only_the_standard_library():
    for name in ROOT_MODULES:
        path = modules()[name]
        tree = ast.parse(path.read_text())
        imported = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
        imported |= {node.module for node in ast.walk(tree)
                     if isinstance(node, ast.ImportFrom) and node.module and not node.level}
        relative = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.level}
        assert relative <= {"lazy"}, (name, relative)
        assert all(m.split(".")[0] in sys.stdlib_module_names for m in imported), (name, imported)


OLD_NAMES = re.compile(r"^\s*(?:from|import)\s+(simcore|observables|sweeps|analysis)\b", re.M)


def test_nothing_imports_a_layer_by_its_folder_name():
    """Every import of ours goes through the one import name (``flocksweep.simcore``, never ``simcore``): a
    layer imported by its folder name would be a second copy of its modules (and of numba's kernels) when
    Python is started in the repository, and would not exist at all in an installed wheel."""
    sources = [p for p in ROOT.rglob("*.py") if not {".git", ".venv", "build"} & set(p.relative_to(ROOT).parts)]
    wrong = [f"{p.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 1}" for p in sources
             for text in [p.read_text()] for m in OLD_NAMES.finditer(text)]
    assert not wrong, wrong


def test_no_module_is_absurdly_long():
    long = {str(p.relative_to(ROOT)): n for p in modules().values()
            if (n := len(p.read_text().splitlines())) > SANITY_CAP}
    assert not long, long


def test_packaging_installs_every_subpackage_under_the_one_name():
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    expected = {"flocksweep." + ".".join(p.relative_to(ROOT).parent.parts) for package in PACKAGES[:-1]
                for p in (ROOT / package).rglob("__init__.py")}
    expected |= {".".join(p.relative_to(ROOT).parent.parts) for p in (ROOT / "flocksweep").rglob("__init__.py")}
    assert set(setuptools["packages"]) == expected
    assert setuptools["package-dir"] == {"flocksweep": "flocksweep",
                                         **{f"flocksweep.{p}": p for p in PACKAGES[:-1]}}


@pytest.mark.slow
def test_the_built_wheel_has_exactly_one_top_level_name(tmp_path):
    """The wheel pip builds from this repository installs one top-level package, ``flocksweep``, holding
    every layer and the viewer's files."""
    import subprocess
    import zipfile

    import shutil

    source = tmp_path / "source"       # a copy: pip builds in the source tree (build/, *.egg-info)
    skip = shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc", "*.egg-info")
    for name in PACKAGES:
        shutil.copytree(ROOT / name, source / name, ignore=skip)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source / name)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(source)],
                   check=True, capture_output=True, timeout=600)
    (wheel,) = tmp_path.glob("flocksweep-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert tops == {"flocksweep"}
    top_level = [n for n in names if n.endswith(".dist-info/top_level.txt")]
    if top_level:
        assert zipfile.ZipFile(wheel).read(top_level[0]).decode().split() == ["flocksweep"]
    for needed in ("flocksweep/simcore/kernel.py", "flocksweep/analysis/viewer/templates/viewer.html.j2",
                   "flocksweep/analysis/reports/claims/kinds.py", "flocksweep/cli.py"):
        assert needed in names, needed


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_a_users_own_analysis_package_and_sweeps_module_do_not_shadow_ours(tmp_path):
    """A script next to its own ``analysis/`` package and ``sweeps.py`` still gets flocksweep's report, sweep
    runner and calibration (the layers are not top-level names a user's files could shadow)."""
    import subprocess

    (tmp_path / "analysis").mkdir()
    (tmp_path / "analysis" / "__init__.py").write_text("MINE = True\n")
    (tmp_path / "sweeps.py").write_text("MINE = True\n")
    (tmp_path / "simcore.py").write_text("MINE = True\n")
    code = ("import analysis, sweeps, simcore\nassert analysis.MINE and sweeps.MINE and simcore.MINE\n"
            "import flocksweep as fs\n"
            "print(fs.report.__module__, fs.run_sweep.__module__, fs.calibrate.__module__,"
            " fs.load_preset.__module__)\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["flocksweep.analysis.reports.report", "flocksweep.sweeps.api",
                                   "flocksweep.analysis.calibration.run", "flocksweep.simcore.params"]


def test_the_public_api_loads_its_layers_only_when_used():
    """``import flocksweep`` and its layers loads neither the reports, the calibration, the viewer nor the
    sweep runner; every public name of every package has a home module (its ``public_names`` table) that
    defines it, and every name of ``flocksweep`` resolves to the same object as in its layer."""
    import importlib
    import subprocess

    code = ("import sys, flocksweep, flocksweep.simcore, flocksweep.sweeps, flocksweep.analysis, "
            "flocksweep.observables\n"
            "print(sorted(m for m in sys.modules if m.startswith(('flocksweep.analysis.', 'flocksweep.sweeps.runner', "
            "'flocksweep.sweeps.config', 'matplotlib', 'arviz', 'numba'))))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    for package in ("flocksweep.simcore", "flocksweep.sweeps", "flocksweep.analysis",
                    "flocksweep.analysis.calibration"):
        module = importlib.import_module(package)
        homes = module.__getattr__.homes
        assert sorted(module.__all__) == sorted(homes), package
        for name, (home, attribute) in homes.items():
            path = Path(module.__file__).parent / (home.replace(".", "/") + ".py")
            tree = ast.parse(path.read_text())
            defined = {node.name for node in tree.body if isinstance(node, (ast.FunctionDef, ast.ClassDef))}
            defined |= {t.id for node in tree.body if isinstance(node, ast.Assign) for t in node.targets
                        if isinstance(t, ast.Name)}
            assert attribute in defined, f"{package}.{name}: {attribute} is not defined in {path.name}"
    import flocksweep

    assert sorted(flocksweep.__all__) == sorted(list(flocksweep._HOMES) + ["__version__"])
    for name, (package, attribute) in flocksweep._HOMES.items():
        assert getattr(flocksweep, name) is getattr(importlib.import_module(package), attribute), name


def test_every_package_face_uses_the_one_lazy_name_helper():
    """One mechanism for lazy public names: no package defines its own module ``__getattr__``."""
    own = [str(p.relative_to(ROOT)) for p in modules().values() if p.name == "__init__.py"
           and re.search(r"^def __getattr__", p.read_text(), re.M) and p.parent.name != "flocksweep"]
    assert not own, own


def test_every_command_is_declared_one_way_in_the_command_line_layer():
    """Each subcommand is a module of flocksweep/commands/ holding a Command of its own name, listed in
    ORDER; no module below the command line declares options (argparse, add_argument)."""
    from flocksweep.command import Command
    from flocksweep.commands import ORDER, load

    modules_there = sorted(p.stem for p in (ROOT / "flocksweep" / "commands").glob("*.py") if p.stem != "__init__")
    assert sorted(ORDER) == modules_there
    for name in ORDER:
        command = load(name)
        assert isinstance(command, Command) and command.name == name
    below = [str(p.relative_to(ROOT)) for package in PACKAGES[:-1] for p in (ROOT / package).rglob("*.py")
             if re.search(r"\bargparse\b|\.add_argument\(|add_parser\(", p.read_text())]
    assert not below, below
