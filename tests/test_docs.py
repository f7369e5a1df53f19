"""The documentation site covers every module: each one has an ``automodule`` in ``docs/api``.

Sphinx checks the rest when ``.ci/run`` builds the site (``-W``: a page in no
table of contents, a broken reference or a failing notebook cell fails it), but
it cannot know of a module that no page names.
"""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ["manifold", "charts", "linkage", "linkage/spatial", "linkage/explore"]


def _documented() -> set[str]:
    text = "\n".join(p.read_text() for p in (ROOT / "docs" / "api").glob("*.md"))
    return set(re.findall(r"^\.\. automodule:: ([\w.]+)", text, flags=re.M))


@pytest.mark.parametrize("package", PACKAGES)
def test_every_module_is_in_the_api_reference(package):
    modules = {f"{package.replace('/', '.')}.{f.stem}" for f in (ROOT / package).glob("*.py")
               if f.stem not in ("__init__", "__main__")} | {package.replace("/", ".")}
    missing = modules - _documented()
    assert not missing, f"add these modules to docs/api/*.md: {sorted(missing)}"

