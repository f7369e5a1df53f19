"""linkage.spatial stands alone: no charts, no manifold, no planar chain, matplotlib only lazily."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SPATIAL = sorted((ROOT / "linkage" / "spatial").glob("*.py"))
FORBIDDEN_TOP = {"charts", "manifold", "heyoka"}


def _imports(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node, a.name, None
        elif isinstance(node, ast.ImportFrom):
            yield node, ("." * node.level) + (node.module or ""), [a.name for a in node.names]


@pytest.mark.parametrize("path", SPATIAL, ids=lambda p: p.name)
def test_spatial_module_imports(path):
    tree = ast.parse(path.read_text())
    module_level = {id(n) for n in tree.body}
    for node, name, names in _imports(tree):
        top = name.lstrip(".").split(".")[0]
        assert top not in FORBIDDEN_TOP, f"{path.name} imports {name}"
        assert not (name.startswith("linkage") and not name.startswith("linkage.spatial")), f"{path.name} imports {name}"
        assert not name.startswith(".."), f"{path.name} reaches out of linkage.spatial: {name}"
        if top == "matplotlib":
            assert id(node) not in module_level, f"{path.name} imports matplotlib at import time"
        if names and name.startswith("."):
            assert not any(n.startswith("_") for n in names), f"{path.name} imports private names {names} from {name}"


def test_importing_spatial_loads_no_planar_code_and_no_matplotlib():
    code = (
        "import sys, linkage.spatial, linkage.spatial.examples, linkage.spatial.draw;"
        "bad = [m for m in ('charts', 'manifold', 'heyoka', 'matplotlib', 'linkage.chain', 'linkage.draw') if m in sys.modules];"
        "print(bad); sys.exit(1 if bad else 0)"
    )
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, env={"PYTHONPATH": str(ROOT)})
    assert r.returncode == 0, r.stdout + r.stderr


def test_planar_names_still_import_from_linkage():
    from linkage import Chain, draw_configuration

    assert Chain.__module__ == "linkage.chain" and callable(draw_configuration)
