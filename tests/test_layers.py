"""The packages' one-way data flow: ``recon`` and ``fmc`` import ``mpeg4``; ``fmc`` never
imports ``recon``; ``recon`` imports nothing from ``fmc``; what needs both is ``chain``."""

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]

#: The packages each package must never import, even lazily inside a function.
FORBIDDEN = {"mpeg4": {"recon", "fmc", "chain"}, "recon": {"fmc", "chain"}, "fmc": {"recon", "chain"}}
#: ``python -m recon`` runs the ``recon`` command, which chain builds; no module imports it.
LAUNCHERS = {Path("recon/__main__.py"): {"chain"}}


def imported_packages(path: Path) -> dict[str, int]:
    """The top-level packages a source file imports anywhere in it, with a line of each.

    Relative imports stay inside the file's own package and are left out; an
    ``importlib.import_module`` or ``__import__`` of a literal name counts as an import.
    """
    found = {}
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant) \
                and isinstance(node.args[0].value, str):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            if name in ("import_module", "__import__"):
                names = [node.args[0].value]
        for n in names:
            found.setdefault(n.split(".")[0], node.lineno)
    return found


def crossings(root: Path) -> list[str]:
    """Every import under ``root`` that goes against the flow, as ``file:line: imports pkg``."""
    bad = []
    for package, forbidden in FORBIDDEN.items():
        for path in sorted((root / package).rglob("*.py")):
            rel = path.relative_to(root)
            allowed = LAUNCHERS.get(rel, set())
            for name, line in imported_packages(path).items():
                if name in forbidden - allowed:
                    bad.append(f"{rel}:{line}: imports {name}")
    return bad


def test_no_package_imports_against_the_flow():
    assert crossings(ROOT) == []


def test_the_scan_sees_lazy_imports(tmp_path):
    # The crossings the scan must catch: inside a function, as a submodule, by name.
    (tmp_path / "recon").mkdir()
    (tmp_path / "recon" / "a.py").write_text("def f():\n    from fmc.clone import clone\n")
    (tmp_path / "recon" / "b.py").write_text("import importlib\n\nimportlib.import_module('chain.cli')\n")
    (tmp_path / "recon" / "__main__.py").write_text("from chain.cli import recon_main\n")
    (tmp_path / "fmc").mkdir()
    (tmp_path / "fmc" / "c.py").write_text("from . import d\nimport recon.mark as m\n")
    assert crossings(tmp_path) == ["recon/a.py:2: imports fmc", "recon/b.py:3: imports chain",
                                   "fmc/c.py:2: imports recon"]


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_importing_every_module_loads_nothing_downstream(package):
    # In a fresh interpreter, so that what other tests imported does not count.
    code = (f"import sys, pkgutil, importlib, {package}\n"
            f"for m in pkgutil.walk_packages({package}.__path__, '{package}.'):\n"
            "    if not m.name.endswith('__main__'):\n"
            "        importlib.import_module(m.name)\n"
            f"bad = sorted(m for m in sys.modules if m.split('.')[0] in {sorted(FORBIDDEN[package])!r})\n"
            "print(bad)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


#: Where the project's modules live: the packages, and the scripts around them.
PACKAGES = ("mpeg4", "recon", "fmc", "chain")
SOURCE_FOLDERS = PACKAGES + ("tests", "benchmarks", "scripts")
#: A reader holds a module of about 500 lines; past this, a module must be split or listed
#: below with its reason.
MAX_LINES = 600
LONG_MODULES: dict[str, str] = {}


def module_name(root: Path, path: Path) -> str:
    """``recon/texture/skin.py`` → ``recon.texture.skin``; a package's ``__init__`` is the package."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def import_graph(root: Path) -> dict[str, set[str]]:
    """Project module → the project modules it imports anywhere in it (lazily too).

    ``from a.b import c`` counts as importing the module ``a.b.c`` when there is one, else
    ``a.b``; relative imports are resolved; ``importlib.import_module`` of a literal name
    counts. The parent packages Python loads on the way are not edges: a package's
    ``__init__`` re-exporting its modules would otherwise be a circle with each of them.
    """
    paths = {module_name(root, p): p for pkg in PACKAGES for p in (root / pkg).rglob("*.py")}
    graph = {}
    for name, path in paths.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
            found = []
            if isinstance(node, ast.Import):
                found = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = package.split(".")[:len(package.split(".")) - (node.level - 1)]
                    base = ".".join(anchor + ([base] if base else []))
                found = [f"{base}.{a.name}" if f"{base}.{a.name}" in paths else base for a in node.names]
            elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant) \
                    and isinstance(node.args[0].value, str):
                func = node.func
                if (func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)) == "import_module":
                    found = [node.args[0].value]
            targets.update(t for t in found if t in paths and t != name)
        graph[name] = targets
    return graph


def import_circles(root: Path) -> list[list[str]]:
    """Every set of project modules that import each other round a circle, sorted."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    graph = import_graph(root)
    names = sorted(graph)
    index = {n: k for k, n in enumerate(names)}
    edges = [(index[a], index[b]) for a, bs in graph.items() for b in bs]
    rows, cols = zip(*edges) if edges else ((), ())
    adjacency = coo_matrix((np.ones(len(edges)), (rows, cols)), shape=(len(names),) * 2)
    _, label = connected_components(adjacency, directed=True, connection="strong")
    groups = {}
    for n, lab in zip(names, label):
        groups.setdefault(lab, []).append(n)
    return sorted(g for g in groups.values() if len(g) > 1)


def test_no_import_circles():
    assert import_circles(ROOT) == []


def test_the_circle_scan_sees_lazy_and_relative_circles(tmp_path):
    # The circle once found between the annotation page and the landmarks, in small.
    for folder in ("recon/annotate", "recon/landmarks", "fmc", "mpeg4", "chain"):
        (tmp_path / folder).mkdir(parents=True)
        (tmp_path / folder / "__init__.py").write_text("")
    (tmp_path / "recon" / "__init__.py").write_text("")
    (tmp_path / "recon" / "annotate" / "placement.py").write_text(
        "import importlib\n\ndef f():\n    return importlib.import_module('recon.landmarks')\n")
    (tmp_path / "recon" / "landmarks" / "__init__.py").write_text("from .side import g\n")
    (tmp_path / "recon" / "landmarks" / "side.py").write_text(
        "def g():\n    from recon.annotate.placement import f\n")
    (tmp_path / "recon" / "landmarks" / "front.py").write_text("from . import side\n")
    assert import_circles(tmp_path) == [["recon.annotate.placement", "recon.landmarks", "recon.landmarks.side"]]


def test_no_module_is_too_long_to_read():
    long = {}
    for folder in SOURCE_FOLDERS:
        for path in (ROOT / folder).rglob("*.py"):
            n = len(path.read_text(encoding="utf-8").splitlines())
            rel = path.relative_to(ROOT).as_posix()
            if n > MAX_LINES and rel not in LONG_MODULES:
                long[rel] = n
    assert long == {}, f"split these modules, or list them in LONG_MODULES with the reason: {long}"
    assert all((ROOT / rel).exists() for rel in LONG_MODULES), "LONG_MODULES names a module that is gone"
