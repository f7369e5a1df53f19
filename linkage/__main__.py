"""``python -m linkage``: the demo (see :mod:`linkage.demo`)."""

from .demo import main

main()
