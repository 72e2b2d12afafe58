"""The packages' one-way data flow: ``recon`` and ``fmc`` import ``mpeg4``; ``fmc`` never
imports ``recon``; ``recon`` imports nothing from ``fmc``; what needs both is ``chain``."""

import ast
import subprocess
import sys
from pathlib import Path

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
