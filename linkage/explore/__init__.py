"""An interactive explorer in the browser, fed live by the library: ``linkage-explore`` or ``python -m linkage.explore``.

A local web server (Starlette on uvicorn, the optional extra ``pip install -e '.[explore]'``) serves one page
(three.js, vendored in ``static/vendor/three``): the chain in the plane, its configuration space, and geodesics
that :func:`linkage.motion.free_motion` computes and the server streams to the page.  The same server answers an
HTTP API (``docs/explorer.md``).  The numerical work lives in :mod:`linkage.explore.protocol` and
:mod:`linkage.explore.space`, which need no web framework; :mod:`linkage.explore.app` is the server and
:mod:`linkage.explore.cli` the command.
"""
