"""The explorer's web server: a Starlette ASGI app over :mod:`linkage.explore.protocol` and :mod:`.space`.

Routes (JSON in, JSON out; see ``docs/explorer.md``):

* ``GET /`` the page, ``/static/...`` its files (Starlette's ``StaticFiles``: nothing outside the folder);
* ``GET /api/config`` the chain the server was started with;
* ``POST /api/motion`` a motion (:func:`.protocol.motion_request`, :func:`.protocol.solve_motion`);
* ``POST /api/space`` the configuration space's geometry (:func:`.space.space_payload`);
* ``POST /api/project`` a dragged hinge projected onto the constraints, or a velocity onto the tangent space;
* ``POST /api/pose`` the configuration at a point of chart 0's sphere, or under a point of the torus of rod angles;
* ``WS /api/stream`` a motion streamed window by window, each window solved when the page asks for it.

Solves run in worker threads, at most ``workers`` at once (default: the number of cores), so the event loop
keeps answering while they run; a client that disconnects stops its solve at the next progress report.
"""

from __future__ import annotations

import asyncio
import json
import os
import threading
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

try:
    import anyio
    from starlette.applications import Starlette
    from starlette.requests import Request
    from starlette.responses import FileResponse, JSONResponse, Response
    from starlette.routing import Mount, Route, WebSocketRoute
    from starlette.staticfiles import StaticFiles
    from starlette.websockets import WebSocket, WebSocketDisconnect
except ImportError as err:  # pragma: no cover - the message is the point
    raise ImportError("the explorer needs its optional dependencies (Starlette, uvicorn): "
                      "pip install -e '.[explore]'  (or pip install 'linkage-manifolds[explore]')") from err

from .protocol import (CHAIN_FIELDS, MOTION_FIELDS, PRECISIONS, Cancelled, Limits, MotionRequest, RequestError,
                       as_pairs, check_fields, drag_hinge, motion_payload, motion_request, parse_chain, parse_complex,
                       parse_configuration, solve_motion, tangent_velocity, read_integer, read_number, read_numbers)
from .space import pose_from_angles, pose_from_sphere, space_payload

__all__ = ["STATIC", "ServerConfig", "create_app"]

#: The page's folder: the only files the server serves.
STATIC = Path(__file__).with_name("static")
#: Largest request body read, in bytes.
MAX_BODY = 1 << 20

T = TypeVar("T")


@dataclass(frozen=True)
class ServerConfig:
    """What the server starts with: the chain shown first, the limits of a request, the worker threads."""

    lengths: int | list[float] = 4
    L: float = 3.0
    limits: Limits = field(default_factory=Limits)
    workers: int = field(default_factory=lambda: os.cpu_count() or 1)

    def chain_json(self) -> dict[str, Any]:
        """The chain as ``GET /api/config`` gives it to the page."""
        return {"lengths": self.lengths, "L": self.L}


def _error(err: RequestError) -> JSONResponse:
    return JSONResponse(err.as_json(), status_code=err.status)


async def _body(request: Request) -> Any:
    raw = await request.body()
    if len(raw) > MAX_BODY:
        raise RequestError("body", f"the request body has {len(raw)} bytes, more than the {MAX_BODY} this server "
                                   "reads", status=413)
    try:
        return json.loads(raw)
    except (ValueError, UnicodeDecodeError) as err:
        raise RequestError("body", f"is not valid JSON: {err}") from None


def create_app(config: ServerConfig | None = None) -> Starlette:
    """The explorer's ASGI app (serve it with uvicorn, or test it with Starlette's ``TestClient``)."""
    config = ServerConfig() if config is None else config
    limits = config.limits
    limiter = anyio.CapacityLimiter(config.workers)

    async def in_worker(fn: Callable[..., T], *args: Any) -> T:
        return await anyio.to_thread.run_sync(fn, *args, limiter=limiter)

    def json_route(handler: Callable[[Any], Awaitable[dict[str, Any]]]) -> Callable[[Request], Awaitable[Response]]:
        async def endpoint(request: Request) -> Response:
            try:
                return JSONResponse(await handler(await _body(request)))
            except RequestError as err:
                return _error(err)
        return endpoint

    async def index(request: Request) -> Response:
        return FileResponse(STATIC / "index.html")

    async def get_config(request: Request) -> Response:
        return JSONResponse({**config.chain_json(), "precisions": list(PRECISIONS), "limits": {
            "maxCost": limits.max_cost, "maxSamples": limits.max_samples, "maxN": limits.max_n}})

    async def motion(request: Request) -> Response:
        try:
            req = motion_request(await _body(request), limits)
        except RequestError as err:
            return _error(err)
        gone = threading.Event()

        async def watch() -> None:  # a client that goes away stops its solve
            while not gone.is_set():
                if await request.is_disconnected():
                    gone.set()
                await asyncio.sleep(0.05)

        watcher = asyncio.ensure_future(watch())
        try:
            solved = await in_worker(_solve_json, req, limits, gone.is_set)
        except RequestError as err:
            return _error(err)
        except Cancelled:
            app.state.cancelled_solves += 1
            return JSONResponse({"error": "the client went away", "field": "", "status": 499}, status_code=499)
        finally:
            gone.set()
            watcher.cancel()
        return JSONResponse(solved)

    async def space(body: Any) -> dict[str, Any]:
        body = check_fields(body, (*CHAIN_FIELDS, "resolution"), ("lengths", "L"))
        chain = parse_chain(body, limits)
        resolution = read_integer("resolution", body.get("resolution", 24), 4, 64)
        return await in_worker(space_payload, chain, resolution)

    async def project(body: Any) -> dict[str, Any]:
        body = check_fields(body, (*CHAIN_FIELDS, "hinges", "hinge", "target", "velocity"), ("lengths", "L", "hinges"))
        chain = parse_chain(body, limits)
        hinges = parse_configuration(chain, "hinges", body["hinges"])
        if "hinge" in body or "target" in body:
            index = read_integer("hinge", body.get("hinge"), 0, chain.n - 2)
            x, y = read_numbers("target", body.get("target"), 2)
            hinges = await in_worker(drag_hinge, chain, hinges, index, complex(x, y))
        out: dict[str, Any] = {"hinges": as_pairs(hinges)}
        if "velocity" in body:
            velocity = parse_complex("velocity", body["velocity"], chain.n - 1)
            out["velocity"] = as_pairs(tangent_velocity(chain, hinges, velocity))
        return out

    async def pose(body: Any) -> dict[str, Any]:
        body = check_fields(body, (*CHAIN_FIELDS, "sphere", "angles", "direction", "hinges"), ("lengths", "L"))
        chain = parse_chain(body, limits)
        if ("sphere" in body) == ("angles" in body):
            raise RequestError("sphere", "give either 'sphere' (a point of chart 0's sphere) or 'angles' (rod angles "
                                         "with the configuration 'hinges' to start from), not both or neither")
        if "angles" in body:
            if "hinges" not in body:
                raise RequestError("hinges", "is required with 'angles': the configuration to start from")
            hinges = parse_configuration(chain, "hinges", body["hinges"])
            angles = body["angles"]
            if not isinstance(angles, list) or not 1 <= len(angles) <= chain.n:
                raise RequestError("angles", f"must be a list of 1 to n = {chain.n} rod angles, got {angles!r}")
            target = read_numbers("angles", angles)
            direction = read_numbers("direction", body["direction"], len(angles)) if "direction" in body else None
            if direction is not None and not np.any(direction):
                raise RequestError("direction", "must be a nonzero vector (a line of sight)")
            return {"hinges": as_pairs(await in_worker(pose_from_angles, chain, hinges, target, direction))}
        if "direction" in body or "hinges" in body:
            raise RequestError("direction" if "direction" in body else "hinges", "is read only with 'angles'")
        point = read_numbers("sphere", body["sphere"], chain.n - 1)
        if not np.any(point):
            raise RequestError("sphere", "must be a nonzero point (it is read by its direction)")
        if not chain.has_atlas:
            raise RequestError("sphere", f"this chain has no atlas, so no sphere picture: {chain.topology().summary()}")
        return {"hinges": as_pairs(pose_from_sphere(chain, point))}

    async def stream(websocket: WebSocket) -> None:
        await websocket.accept()
        app.state.cancelled_solves += await _stream(websocket, limits, in_worker)

    routes = [
        Route("/", index),
        Route("/api/config", get_config),
        Route("/api/motion", motion, methods=["POST"]),
        Route("/api/space", json_route(space), methods=["POST"]),
        Route("/api/project", json_route(project), methods=["POST"]),
        Route("/api/pose", json_route(pose), methods=["POST"]),
        WebSocketRoute("/api/stream", stream),
        Mount("/static", app=StaticFiles(directory=STATIC), name="static"),
    ]
    app = Starlette(routes=routes)
    app.state.cancelled_solves = 0  # solves stopped because their client went away (read by the tests)
    return app


def _solve_json(req: MotionRequest, limits: Limits, cancelled: Callable[[], bool]) -> dict[str, Any]:
    payload = motion_payload(solve_motion(req, limits, cancelled))
    return {**payload, "method": req.method, "precision": req.precision}


#: Fields of a launch on the stream: a motion request without ``T`` and ``samples``, with the window's length and
#: the samples per unit time.
LAUNCH_FIELDS = (*[f for f in MOTION_FIELDS if f not in ("T", "samples")], "type", "window", "rate")


async def _stream(websocket: WebSocket, limits: Limits,
                  in_worker: Callable[..., Awaitable[Any]]) -> int:
    """The stream's protocol: the page sends ``{"type": "launch", ...}`` (a motion request with ``window`` and
    ``rate`` instead of ``T`` and ``samples``), ``{"type": "more"}`` for the next window and ``{"type": "stop"}``;
    the server answers each window with ``{"type": "chunk", "index": k, ...}`` (the payload of
    :func:`.protocol.motion_payload`, times counted from the launch, energy errors relative to the launch's energy)
    and a refused launch with ``{"type": "error", "field", "error"}``.  Window ``k + 1`` starts from the end of
    window ``k``.  A new launch, a stop or a disconnect stops the solve in progress.  Returns the number of
    solves stopped so."""
    inbox: asyncio.Queue[dict[str, Any] | None] = asyncio.Queue()
    cancel = threading.Event()

    async def read() -> None:
        try:
            while True:
                text = await websocket.receive_text()
                try:
                    message = json.loads(text)
                except ValueError:
                    message = {"type": "invalid", "text": text[:200]}
                if isinstance(message, dict) and message.get("type") in ("launch", "stop"):
                    cancel.set()
                await inbox.put(message if isinstance(message, dict) else {"type": "invalid"})
        except (WebSocketDisconnect, RuntimeError):
            cancel.set()
            await inbox.put(None)

    reader = asyncio.ensure_future(read())
    current: MotionRequest | None = None
    index, t0, energy0, stopped = 0, 0.0, 0.0, 0
    try:
        while True:
            message = await inbox.get()
            if message is None:
                return stopped
            kind = message.get("type")
            try:
                if kind == "launch":
                    cancel.clear()
                    current, index, t0 = _launch(message, limits), 0, 0.0
                    energy0 = float(current.chain.kinetic_energy(current.velocity))
                elif kind == "more" and current is not None:
                    cancel.clear()
                elif kind == "stop":
                    current = None
                    await websocket.send_json({"type": "stopped"})
                    continue
                else:
                    raise RequestError("type", f"must be 'launch', 'more' (after a launch) or 'stop', got "
                                               f"{message.get('type', message.get('text'))!r}")
                motion = await in_worker(solve_motion, current, limits, cancel.is_set)
                payload = motion_payload(motion, energy0=energy0, t0=t0)
                await websocket.send_json({"type": "chunk", "index": index, "method": current.method,
                                           "precision": current.precision, **payload})
                end_h, end_v = motion(current.T)
                current, index, t0 = replace(current, hinges=end_h, velocity=end_v), index + 1, t0 + current.T
            except RequestError as err:
                current = None
                await websocket.send_json({"type": "error", **err.as_json()})
            except Cancelled:
                stopped += 1
    except WebSocketDisconnect:
        return stopped
    finally:
        cancel.set()
        reader.cancel()


def _launch(message: dict[str, Any], limits: Limits) -> MotionRequest:
    body = {k: v for k, v in message.items() if k not in ("type", "window", "rate")}
    check_fields(message, LAUNCH_FIELDS, ("lengths", "L", "hinges", "velocity"))
    window = read_number("window", message.get("window", 10.0), positive=True)
    rate = read_number("rate", message.get("rate", 50.0), positive=True)
    samples = int(round(window * rate)) + 1
    if samples > limits.max_samples:
        raise RequestError("rate", f"window * rate + 1 = {samples} samples exceeds this server's "
                                   f"{limits.max_samples}", status=413)
    return motion_request({**body, "T": window, "samples": samples}, limits)
