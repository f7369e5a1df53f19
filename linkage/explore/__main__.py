"""``python -m linkage.explore``: the same as the ``linkage-explore`` command."""

from .cli import main

if __name__ == "__main__":
    raise SystemExit(main())
