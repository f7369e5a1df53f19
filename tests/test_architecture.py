"""The layout shows the architecture: manifold <- charts <- linkage, never back."""

import ast
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


LENGTH_GENERIC = ("lengths.py", "topology.py", "diagonals.py")


@pytest.mark.parametrize("name", LENGTH_GENERIC)
def test_length_generic_core_has_no_plotting_and_no_private_imports(name):
    """The mathematics the Chain class delegates to stays importable without matplotlib."""
    path = ROOT / "linkage" / name
    assert "matplotlib" not in _imported_packages(path)
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            private = [a.name for a in node.names if a.name.startswith("_")]
            assert not private, f"{name} imports private names {private} from {node.module}"
