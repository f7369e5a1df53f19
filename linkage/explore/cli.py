"""The ``linkage-explore`` command: serve the explorer on this machine and open it in the browser.

``linkage-explore --n 4 --L 3`` serves the page for four unit rods with base ``L = 3`` on
``http://127.0.0.1:8765/`` and opens it; ``--port 0`` picks a free port, ``--no-browser`` only prints the URL,
``--host`` binds another address (see ``docs/explorer.md`` for what exposing the server means).
"""

from __future__ import annotations

import argparse
import socket
import threading
import webbrowser
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING

from ..chain import Chain
from .protocol import Limits

if TYPE_CHECKING:
    import uvicorn
    from starlette.applications import Starlette

__all__ = ["main", "serve_in_thread"]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="linkage-explore", description=(
        "Serve the interactive explorer of planar closed chains: drag the chain, flick it, and watch the geodesic "
        "that the library computes."))
    p.add_argument("--n", type=int, default=4, help="number of unit rods (default 4; ignored with --lengths)")
    p.add_argument("--L", type=float, default=None, help="distance of the two pins (default n - 1 for unit rods)")
    p.add_argument("--lengths", type=str, default=None, help="rod lengths, comma-separated (e.g. 1,2,1.5,2.5)")
    p.add_argument("--port", type=int, default=8765, help="port (default 8765; 0 picks a free one)")
    p.add_argument("--host", type=str, default="127.0.0.1",
                   help="address to bind (default 127.0.0.1: this machine only)")
    p.add_argument("--no-browser", action="store_true", help="print the URL without opening a browser")
    p.add_argument("--budget", type=float, default=Limits().max_cost,
                   help=f"largest estimated cost |T| (n - 1) w of one request (default {Limits().max_cost:g})")
    return p


def _chain_arguments(args: argparse.Namespace, parser: argparse.ArgumentParser) -> tuple[int | list[float], float]:
    lengths: int | list[float]
    if args.lengths is not None:
        try:
            lengths = [float(x) for x in args.lengths.split(",")]
        except ValueError:
            parser.error(f"--lengths must be comma-separated numbers, got {args.lengths!r}")
        L = args.L if args.L is not None else 0.5 * sum(lengths)
    else:
        lengths = args.n
        L = args.L if args.L is not None else args.n - 1.0
    try:
        Chain(lengths, L)
    except ValueError as err:
        parser.error(f"--n/--lengths/--L: {err}")
    return lengths, L


def _bind(host: str, port: int) -> socket.socket:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind((host, port))
    return sock


def _url(sock: socket.socket) -> str:
    host, port = sock.getsockname()[:2]
    return f"http://{f'[{host}]' if ':' in host else host}:{port}/"


def _server(lengths: int | list[float], L: float, budget: float, app: Starlette | None = None) -> uvicorn.Server:
    import uvicorn

    from .app import ServerConfig, create_app
    if app is None:
        app = create_app(ServerConfig(lengths=lengths, L=L, limits=Limits(max_cost=budget)))
    return uvicorn.Server(uvicorn.Config(app, log_level="warning", ws="websockets-sansio"))


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the options, bind, print the URL, open the browser unless told not to, and serve until Ctrl-C."""
    parser = _parser()
    args = parser.parse_args(argv)
    lengths, L = _chain_arguments(args, parser)
    server = _server(lengths, L, args.budget)
    sock = _bind(args.host, args.port)
    url = _url(sock)
    print(f"linkage explorer: {url}  (Ctrl-C stops it)", flush=True)
    if not args.no_browser:
        threading.Timer(0.5, webbrowser.open, args=(url,)).start()
    server.run(sockets=[sock])
    return 0


@contextmanager
def serve_in_thread(lengths: int | list[float] = 4, L: float = 3.0, *, host: str = "127.0.0.1", port: int = 0,
                    budget: float = Limits().max_cost, app: Starlette | None = None) -> Iterator[str]:
    """Run the server in a background thread for the block (tests, notebooks); yields its URL.

    ``app`` serves a given app (:func:`linkage.explore.app.create_app`) instead of one for the chain and budget.
    """
    server = _server(lengths, L, budget, app)
    sock = _bind(host, port)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    try:
        while not server.started:
            if not thread.is_alive():
                raise RuntimeError("the explorer's server stopped while starting")
            threading.Event().wait(0.02)
        yield _url(sock)
    finally:
        server.should_exit = True
        thread.join(timeout=10)
        sock.close()
