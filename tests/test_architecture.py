"""The layout shows the architecture: manifold <- charts <- linkage, never back; no module uses another's private names."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FORBIDDEN = {"manifold": {"charts", "linkage"}, "charts": {"linkage"}}


def _imported_packages(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_lower_layers_do_not_import_higher_ones(package):
    files = sorted((ROOT / package).glob("*.py"))
    assert files
    for f in files:
        bad = _imported_packages(f) & FORBIDDEN[package]
        assert not bad, f"{f.relative_to(ROOT)} imports {bad}"


# -- private names ------------------------------------------------------------------------------
#: Every package whose modules must keep to each other's public names.
CHECKED = ["manifold", "charts", "linkage", "benchmarks", "tests"]

def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _own_names(tree: ast.Module) -> set[str]:
    """Names the module itself binds: defs, classes, assignment targets (``self._x = ...`` too), arguments, aliases."""
    own = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            own.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            own.add(node.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            own.add(node.attr)
        elif isinstance(node, ast.arg):
            own.add(node.arg)
        elif isinstance(node, ast.alias) and node.asname:
            own.add(node.asname)
    return own


def private_name_uses(source: str) -> list[tuple[int, str, str]]:
    """``(line, name, code)`` for every use of another module's private (``_x``, not dunder) name.

    Counted: ``from m import _x``, importing a private module (``m._sub``), and
    an attribute ``obj._x`` where ``obj`` is not ``self``/``cls`` and ``_x`` is
    not bound in this module itself.
    """
    tree = ast.parse(source)
    own = _own_names(tree)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            module = "." * node.level + (node.module or "")
            found += [(node.lineno, p, f"from {module} import ...") for p in module.split(".") if _is_private(p)]
            found += [(node.lineno, a.name, f"from {module} import {a.name}") for a in node.names if _is_private(a.name)]
        elif isinstance(node, ast.Import):
            found += [(node.lineno, p, f"import {a.name}") for a in node.names for p in a.name.split(".") if _is_private(p)]
        elif isinstance(node, ast.Attribute) and _is_private(node.attr) and node.attr not in own:
            if not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
                found.append((node.lineno, node.attr, ast.unparse(node)))
    return found


def _checked_files() -> list[Path]:
    return [f for package in CHECKED for f in sorted((ROOT / package).rglob("*.py"))]


@pytest.mark.parametrize("package", CHECKED)
def test_no_module_uses_another_modules_private_names(package):
    files = sorted((ROOT / package).rglob("*.py"))
    assert files
    bad = [
        f"{f.relative_to(ROOT)}:{line}: {code}"
        for f in files
        for line, name, code in private_name_uses(f.read_text())
    ]
    assert not bad, "private names of other modules (make them public and documented):\n" + "\n".join(bad)


def test_the_private_name_check_catches_each_kind_of_use():
    source = '''
from manifold.geodesic_solver import _ChartNumerics, solve_chart_exp_ode
from . import _helpers
import numpy._core.numeric
from .chain import Chain, _positive_vector as positive


class A:
    def __init__(self, chain):
        self._own = chain._hinge_array(1)
        self.__dict__.update(x=chain.__class__)

    @classmethod
    def make(cls, other):
        return cls._own, other._own, other._foreign, super()._base, _module_private_ok()


def _module_private_ok():
    return A(None)._own
'''
    found = sorted((line, name) for line, name, _ in private_name_uses(source))
    assert found == [(2, "_ChartNumerics"), (3, "_helpers"), (4, "_core"), (5, "_positive_vector"),
                     (10, "_hinge_array"), (15, "_base"), (15, "_foreign")]


def test_import_linkage_loads_no_plotting_library():
    """``linkage.draw`` imports matplotlib inside its functions only (checked in a fresh interpreter)."""
    code = "import linkage, sys; assert not any(m.startswith('matplotlib') for m in sys.modules), 'matplotlib loaded'"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr


LENGTH_GENERIC = ("lengths.py", "topology.py", "diagonals.py")


@pytest.mark.parametrize("name", LENGTH_GENERIC)
def test_length_generic_core_has_no_plotting(name):
    """The mathematics the Chain class delegates to stays importable without matplotlib."""
    assert "matplotlib" not in _imported_packages(ROOT / "linkage" / name)
