"""The explorer's HTTP and WebSocket API (linkage.explore.app) against the library it serves.

The motions it answers must be free_motion's own (compared number for number: JSON carries a float's repr,
which round-trips exactly); malformed requests must each get a 4xx naming the field while the server keeps
answering; 50 concurrent T = 10 motions are answered by a real uvicorn server.
"""

from __future__ import annotations

import asyncio
import json
import math
import warnings

import httpx
import numpy as np
import pytest

with warnings.catch_warnings():  # Starlette's test client would rather have the httpx2 fork; httpx serves it
    warnings.simplefilter("ignore")
    from starlette.testclient import TestClient

from linkage import Chain, HingeConstraints
from linkage.explore.app import ServerConfig, create_app
from linkage.explore.cli import serve_in_thread
from linkage.explore.protocol import Cancelled, Limits, as_pairs, motion_request, solve_motion
from linkage.motion import free_motion
from linkage.sampling import sample_starts
from manifold import Precision, SaveAt


CHAIN = Chain(4, 3.0)


def pole_start() -> tuple[np.ndarray, np.ndarray]:
    """A unit-speed start of four unit rods (L = 3) heading over the pole phi_4 = pi/2 of chart 0."""
    chart0 = CHAIN.atlas().charts[0]
    a0, c0 = np.array([1.2, 0.3]), np.array([1.0, 0.2])
    v0 = CHAIN.from_point(chart0.tangent_vector(a0, c0))
    return chart0.hinges(a0), v0 / np.sqrt(2 * CHAIN.kinetic_energy(v0))


def random_start(seed: int) -> tuple[np.ndarray, np.ndarray]:
    H, V = sample_starts(CHAIN, 1, 0.5, np.random.default_rng(seed))
    return H[0], V[0]


def body(h: np.ndarray, v: np.ndarray, **extra: object) -> dict:
    return {"lengths": 4, "L": 3.0, "hinges": as_pairs(h), "velocity": as_pairs(v), "T": 10.0, "samples": 101,
            **extra}


def complex_of(pairs: list) -> np.ndarray:
    a = np.array(pairs)
    return a[..., 0] + 1j * a[..., 1]


@pytest.fixture(scope="module")
def client() -> TestClient:
    return TestClient(create_app())


@pytest.mark.parametrize("method", ["charts", "hinges"])
def test_motion_is_free_motions(client: TestClient, method: str) -> None:
    h, v = random_start(3)
    answer = client.post("/api/motion", json=body(h, v, method=method))
    assert answer.status_code == 200, answer.text
    got = answer.json()
    times = np.linspace(0.0, 10.0, 101)
    ref = free_motion(CHAIN, h, v, 10.0, method=method, save=SaveAt(t_eval=times))
    assert got["times"] == times.tolist()
    assert np.array_equal(complex_of(got["hinges"]), ref.hinges)
    assert np.array_equal(complex_of(got["velocities"]), ref.velocities)
    assert got["method"] == method and got["precision"] == "float64"
    assert max(got["energyError"]) <= 1e-12 and got["maxEnergyError"] <= 1e-12
    assert np.max(CHAIN.closure_residual(complex_of(got["hinges"]))) < 1e-12
    # the rod angles and chart-0 sphere points are those of the hinges: |s| = 1, and angles reproduce the rods
    assert np.allclose(np.linalg.norm(got["sphere"], axis=1), 1.0, atol=1e-12)
    rods = np.diff(np.concatenate([np.zeros((101, 1)), complex_of(got["hinges"]), np.full((101, 1), 3.0)], axis=1))
    assert np.allclose(np.exp(1j * np.array(got["angles"])), rods, atol=1e-12)


def test_precision_names_reach_the_solver(client: TestClient) -> None:
    h, v = random_start(4)
    got = client.post("/api/motion", json=body(h, v, precision="longdouble", T=1.0, samples=5)).json()
    ref = free_motion(CHAIN, h, v, 1.0, method="charts", save=SaveAt(t_eval=np.linspace(0, 1, 5)),
                      precision=Precision(fp_type=np.longdouble))
    assert got["precision"] == "longdouble"
    assert np.array_equal(complex_of(got["hinges"]), ref.hinges)


def test_pole_crossing_reports_its_switch(client: TestClient) -> None:
    h, v = pole_start()
    got = client.post("/api/motion", json=body(h, v, samples=501)).json()
    sphere = np.array(got["sphere"])
    assert sphere[:, 0].max() > 0.99  # over chart 0's pole: sin(phi_4) -> 1
    assert len(got["switches"]) >= 1
    times, charts = np.array(got["times"]), np.array(got["chart"])
    for s in got["switches"]:  # the sampled chart is the switch's 'from' before it and its 'to' just after
        before, after = np.flatnonzero(times < s["t"])[-1], np.flatnonzero(times >= s["t"])[0]
        assert charts[before] == s["from"] and charts[after] == s["to"]
    assert got["chartIds"][got["switches"][0]["to"]].startswith("shift")


def malformed_requests() -> list[tuple[object, str, int]]:
    h, v = random_start(5)
    good = body(h, v)
    far = as_pairs(h + 0.1)
    sideways = as_pairs(1j * v)
    cases: list[tuple[object, str, int]] = [
        ([1, 2], "body", 400),
        ("hello", "body", 400),
        ({**good, "colour": "red"}, "colour", 400),
        ({k: x for k, x in good.items() if k != "hinges"}, "hinges", 400),
        ({k: x for k, x in good.items() if k != "T"}, "T", 400),
        ({**good, "T": math.nan}, "T", 400),
        ({**good, "T": math.inf}, "T", 400),
        ({**good, "T": 0}, "T", 400),
        ({**good, "T": "10"}, "T", 400),
        ({**good, "T": True}, "T", 400),
        ({**good, "L": math.nan}, "L", 400),
        ({**good, "L": -1.0}, "L", 400),
        ({**good, "L": 5.0}, "L", 400),  # an empty configuration space: L longer than the four rods
        ({**good, "lengths": [1, 1, 1, 10]}, "lengths", 400),  # empty: one rod longer than the rest
        ({**good, "lengths": 1}, "lengths", 400),
        ({**good, "lengths": "four"}, "lengths", 400),
        ({**good, "lengths": [1, 1, -1, 1]}, "lengths", 400),
        ({**good, "masses": [1, 1]}, "masses", 400),
        ({**good, "masses": 0}, "masses", 400),
        ({**good, "masses": 1e200}, "masses", 400),  # beyond the masses' range: refused by Chain, named as masses
        ({**good, "hinges": as_pairs(h[:2])}, "hinges", 400),
        ({**good, "hinges": [[0, 0, 0]] * 3}, "hinges", 400),
        ({**good, "hinges": [[math.nan, 0]] * 3}, "hinges", 400),
        ({**good, "hinges": far}, "hinges", 400),  # off the constraints
        ({**good, "velocity": sideways}, "velocity", 400),  # not tangent
        ({**good, "velocity": [[0, 0]] * 3}, "velocity", 400),
        ({**good, "method": "euler"}, "method", 400),
        ({**good, "precision": "float16"}, "precision", 400),
        ({**good, "samples": 1}, "samples", 400),
        ({**good, "samples": 10**7}, "samples", 400),
        ({**good, "T": 1e6}, "T", 413),  # over the budget of work
    ]
    return cases


def test_malformed_requests_are_refused_and_the_server_stays_up(client: TestClient) -> None:
    cases = malformed_requests()
    assert len(cases) == 31
    for request, field, status in cases:
        answer = client.post("/api/motion", content=json.dumps(request))  # NaN and inf written as JSON5 does
        assert answer.status_code == status, (request, answer.text)
        error = answer.json()
        assert error["field"].split("[")[0] == field, (request, error)  # 'hinges[0]' names an entry of hinges
        assert len(error["error"]) > 10
    raw = client.post("/api/motion", content=b'{"lengths": 4, "L": NaN, "hinges": [], "velocity": [], "T": 1}')
    assert raw.status_code == 400 and raw.json()["field"] == "L"
    assert client.post("/api/motion", content=b"{not json").status_code == 400
    h, v = random_start(6)
    assert client.post("/api/motion", json=body(h, v)).status_code == 200


def test_a_solve_over_its_step_budget_is_refused_with_the_solvers_reason() -> None:
    tight = TestClient(create_app(ServerConfig(limits=Limits(max_steps=20))))
    h, v = random_start(7)
    answer = tight.post("/api/motion", json=body(h, v))
    assert answer.status_code == 422
    assert "budget" in answer.json()["error"]


def test_a_cancelled_solve_stops() -> None:
    h, v = random_start(8)
    request = motion_request(body(h, v, T=500.0), Limits())
    with pytest.raises(Cancelled):
        solve_motion(request, Limits(), lambda: True)


def test_static_files_stay_in_their_folder(client: TestClient) -> None:
    assert client.get("/").status_code == 200
    assert client.get("/static/vendor/three/LICENSE").status_code == 200
    for path in ("/static/../app.py", "/static/%2e%2e/app.py", "/static/..%2fprotocol.py", "/app.py"):
        assert client.get(path).status_code == 404, path


def test_space_of_four_rods_is_a_sphere_of_configurations(client: TestClient) -> None:
    got = client.post("/api/space", json={"lengths": 4, "L": 3.0, "resolution": 8}).json()
    sphere = got["sphere"]
    # vertex k of the mesh is the configuration in row k of the torus fields
    vertices, hinges = np.array(sphere["vertices"]), complex_of(got["torus"]["hinges"])
    assert len(hinges) == len(vertices) == 9 * 17
    assert np.allclose(np.linalg.norm(vertices, axis=1), 1.0)
    assert np.max(CHAIN.closure_residual(hinges)) < 1e-9
    # the pose of a vertex is its configuration (the picture's inverse)
    for k in (40, 100):
        pose = client.post("/api/pose", json={"lengths": 4, "L": 3.0, "sphere": vertices[k].tolist()}).json()
        assert np.allclose(complex_of(pose["hinges"]), hinges[k], atol=1e-9)
    # Gauss-Bonnet: the curvature integrates to 4 pi over the sphere. Area elements from the metric's own
    # Gram determinant on the mesh would repeat the library; instead the mean of K over the round picture must
    # be positive and K finite
    assert np.all(np.isfinite(sphere["curvature"])) and np.mean(sphere["curvature"]) > 0
    # second fundamental form: K = <II_11, II_22> - |II_12|^2 <= max_v |II(v, v)|^2 <= |II|^2 (unit v)
    K, stiff, bend = (np.array(sphere[k]) for k in ("curvature", "stiffness", "bending"))
    assert np.all(K <= stiff**2 * (1 + 1e-9)) and np.all(stiff**2 <= bend * (1 + 1e-9))
    assert got["torus"]["name"].startswith("the configuration sphere")


def numeric_fields(payload: object, path: str = "") -> dict[str, np.ndarray]:
    """Every list of numbers in a JSON payload, by its path, as an array of one row per entry of its first axis."""
    if isinstance(payload, dict):
        return {k: v for key, value in payload.items() for k, v in numeric_fields(value, f"{path}.{key}").items()}
    if isinstance(payload, list) and payload and not isinstance(payload[0], (str, dict)):
        a = np.array(payload, dtype=float)
        return {path: a.reshape(len(a), -1)}
    return {}


@pytest.mark.parametrize("lengths,L", [(4, 3.0), (3, 2.0), (4, 1.0)])
def test_space_sends_each_column_once(client: TestClient, lengths: int, L: float) -> None:
    """No column of numbers (one number per configuration: a coordinate of a hinge, a rod angle, a point of the
    picture) is sent twice in the payload of /api/space, in two fields or twice in one."""
    got = client.post("/api/space", json={"lengths": lengths, "L": L, "resolution": 8}).json()
    columns = [(f"{path}[:, {j}]", a[:, j]) for path, a in numeric_fields(got).items() if len(a) > 8
               for j in range(a.shape[1])]
    assert len(columns) >= 9
    for i, (name, column) in enumerate(columns):
        for other, again in columns[i + 1:]:
            assert not np.array_equal(column, again), f"{name} and {other} carry the same numbers"


def test_space_of_four_rods_sends_what_the_page_draws_per_vertex(client: TestClient) -> None:
    """Per vertex of the sphere the page needs its point of the picture (3 numbers), three colourings (3), its
    rod angles in the cube (3), its configuration (3 hinges: 6) and about two triangles (6 indices): at most 21
    numbers a vertex, whatever the resolution."""
    for resolution in (8, 16):
        got = client.post("/api/space", json={"lengths": 4, "L": 3.0, "resolution": resolution}).json()
        vertices = len(got["sphere"]["vertices"])
        numbers = sum(a.size for a in numeric_fields(got).values())
        assert numbers <= 21 * vertices, f"{numbers / vertices:.1f} numbers a vertex at resolution {resolution}"


@pytest.mark.parametrize("lengths,L,kind", [(3, 2.0, "circle"), (4, 1.0, "projection"), (5, 4.0, "projection")])
def test_space_of_other_chains_is_named(client: TestClient, lengths: int, L: float, kind: str) -> None:
    got = client.post("/api/space", json={"lengths": lengths, "L": L}).json()
    assert got["sphere"] is None
    assert kind in got["torus"]["name"]
    assert np.all(np.abs(got["torus"]["angles"]) <= np.pi)
    chain = Chain(lengths, L)
    hinges = complex_of(got["torus"]["hinges"])
    assert np.allclose(chain.angles(hinges)[:, :3], got["torus"]["angles"], atol=1e-12)
    if kind == "circle":  # point k of chart 0's circle is the configuration in row k of the torus fields
        chart0 = chain.atlas().charts[0]
        assert np.allclose(chart0.sphere_point(chart0.get_parameters(chain.to_point(hinges))),
                           got["circle"]["points"], atol=1e-9)


def wrapped(x: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * x))


def test_a_line_of_sight_through_the_cube_poses_the_configuration_under_it(client: TestClient) -> None:
    """n = 4: a line of sight through a configuration's point of the cube of rod angles, from a configuration
    nearby, gives back that configuration; the torus payload's configurations are those of its angles."""
    chart0 = CHAIN.atlas().charts[0]
    space = client.post("/api/space", json={"lengths": 4, "L": 3.0, "resolution": 8}).json()["torus"]
    assert np.allclose(CHAIN.angles(complex_of(space["hinges"]))[:, :3], space["angles"], atol=1e-12)
    for a, seed, d in [((0.7, -0.2), (0.6, -0.1), (2.2, 1.6, 2.6)), ((-0.3, 2.0), (-0.25, 2.1), (-1.0, 0.3, 0.2))]:
        target, start = chart0.hinges(np.array(a)), chart0.hinges(np.array(seed))
        angles = CHAIN.angles(target)[:3] + 0.4 * np.array(d)  # another point of the same line
        got = client.post("/api/pose", json={"lengths": 4, "L": 3.0, "angles": angles.tolist(), "direction": d,
                                             "hinges": as_pairs(start)})
        assert got.status_code == 200, got.text
        pose = complex_of(got.json()["hinges"])
        assert np.max(CHAIN.closure_residual(pose)) <= 1e-12
        assert np.max(np.abs(pose - target)) < 1e-9


def test_a_point_of_the_torus_poses_the_nearest_configuration(client: TestClient) -> None:
    """n = 3: the pose nearest a point of the torus T^2 is the nearest of 200 001 points of chart 0's circle; for
    n = 5 (S^3 seen through three rod angles) the line of sight meets the picture, and the pose lies on it."""
    c3 = Chain(3, 2.0)
    circle = c3.atlas().charts[0].hinges(np.linspace(-np.pi, np.pi, 200_001)[:, None])
    point = np.array([0.9, -0.2])
    dense = np.linalg.norm(wrapped(c3.angles(circle)[:, :2] - point), axis=1)
    start = circle[np.argmin(dense) + 20_000]  # a tenth of the circle away from the nearest point
    got = client.post("/api/pose", json={"lengths": 3, "L": 2.0, "angles": point.tolist(), "hinges": as_pairs(start)})
    pose = complex_of(got.json()["hinges"])
    assert np.max(c3.closure_residual(pose)) <= 1e-12
    assert abs(np.linalg.norm(wrapped(c3.angles(pose)[:2] - point)) - dense.min()) < 1e-9
    c5 = Chain(5, 3.5)
    h = c5.diagonal_space().sample(2, np.random.default_rng(3)).hinges
    d = np.array([0.2, -1.0, 0.5])
    got = client.post("/api/pose", json={"lengths": 5, "L": 3.5, "angles": c5.angles(h[1])[:3].tolist(),
                                         "direction": d.tolist(), "hinges": as_pairs(h[0])})
    pose = complex_of(got.json()["hinges"])
    off = wrapped(c5.angles(pose)[:3] - c5.angles(h[1])[:3])
    assert np.max(c5.closure_residual(pose)) <= 1e-12 and np.linalg.norm(off - (off @ d) / (d @ d) * d) < 1e-12


def test_malformed_poses_name_their_field(client: TestClient) -> None:
    h = as_pairs(CHAIN.atlas().charts[0].hinges(np.array([0.4, 0.4])))
    chain = {"lengths": 4, "L": 3.0}
    for request, field in [({}, "sphere"), ({"sphere": [1, 0, 0], "angles": [0, 0, 0], "hinges": h}, "sphere"),
                           ({"angles": [0, 0, 0]}, "hinges"), ({"angles": [], "hinges": h}, "angles"),
                           ({"angles": [0] * 5, "hinges": h}, "angles"), ({"angles": "x", "hinges": h}, "angles"),
                           ({"angles": [0, math.nan, 0], "hinges": h}, "angles"),
                           ({"angles": [0, 0, 0], "direction": [0, 0, 0], "hinges": h}, "direction"),
                           ({"angles": [0, 0, 0], "direction": [1, 0], "hinges": h}, "direction"),
                           ({"angles": [0, 0, 0], "hinges": as_pairs(complex_of(h) + 0.1)}, "hinges"),
                           ({"sphere": [1, 0, 0], "hinges": h}, "hinges")]:
        answer = client.post("/api/pose", content=json.dumps({**chain, **request}))
        assert answer.status_code == 400, (request, answer.text)
        assert answer.json()["field"].split("[")[0] == field, (request, answer.json())


def test_drag_keeps_the_chain_on_its_constraints(client: TestClient) -> None:
    h, v = random_start(9)
    other = random_start(11)[0]
    target = h[1] + 0.2 * (other[1] - h[1])  # reachable: p_2 lives in the lens |p_2| <= 2, |p_2 - L| <= 2, convex
    got = client.post("/api/project", json={"lengths": 4, "L": 3.0, "hinges": as_pairs(h), "hinge": 1,
                                            "target": [target.real, target.imag], "velocity": as_pairs(v + 0.3)})
    assert got.status_code == 200, got.text
    moved, w = complex_of(got.json()["hinges"]), complex_of(got.json()["velocity"])
    assert np.max(CHAIN.closure_residual(moved)) < 1e-12
    assert abs(moved[1] - target) < 1e-4  # the dragged hinge follows the pointer
    constraints = HingeConstraints(CHAIN)
    assert np.max(np.abs(constraints.jacobian(CHAIN.to_point(moved)) @ CHAIN.to_point(w))) < 1e-12  # tangent
    again = client.post("/api/project", json={"lengths": 4, "L": 3.0, "hinges": as_pairs(moved),
                                              "velocity": as_pairs(w)}).json()
    assert np.allclose(complex_of(again["velocity"]), w, atol=1e-14)  # a projection: idempotent
    bad = client.post("/api/project", json={"lengths": 4, "L": 3.0, "hinges": as_pairs(h), "hinge": 3,
                                            "target": [0, 0]})
    assert bad.status_code == 400 and bad.json()["field"] == "hinge"


def test_stream_continues_window_after_window(client: TestClient) -> None:
    h, v = random_start(10)
    ref = free_motion(CHAIN, h, v, 4.0, method="charts", save=SaveAt(t_eval=np.linspace(0, 4, 21)))
    with client.websocket_connect("/api/stream") as ws:
        ws.send_json({"type": "launch", **{k: x for k, x in body(h, v).items() if k not in ("T", "samples")},
                      "window": 4.0, "rate": 5.0})
        first = ws.receive_json()
        assert first["type"] == "chunk" and first["index"] == 0
        assert np.array_equal(complex_of(first["hinges"]), ref.hinges)
        ws.send_json({"type": "more"})
        second = ws.receive_json()
        assert second["index"] == 1 and second["times"][0] == 4.0 and second["times"][-1] == 8.0
        # the next window starts from the first's end, which the chart solver reads back into its chart (parameters
        # polished by Gauss-Newton): the same point to rounding, not bit for bit (5.6e-16 apart here)
        seam = np.max(np.abs(complex_of(second["hinges"])[0] - complex_of(first["hinges"])[-1]))
        assert seam <= 1e-14
        assert max(second["energyError"]) <= 1e-12  # relative to the launch's energy
        ws.send_json({"type": "launch", "lengths": 4, "L": 3.0, "hinges": as_pairs(h), "velocity": as_pairs(1j * v)})
        error = ws.receive_json()
        assert error["type"] == "error" and error["field"] == "velocity"
        ws.send_json({"type": "warp"})
        assert ws.receive_json()["field"] == "type"
        ws.send_json({"type": "stop"})
        assert ws.receive_json() == {"type": "stopped"}


def test_fifty_concurrent_clients_of_a_real_server() -> None:
    starts = [random_start(100 + k) for k in range(5)]

    async def run(url: str) -> list[httpx.Response]:
        async with httpx.AsyncClient(base_url=url, timeout=300) as http:
            return await asyncio.gather(*(http.post("/api/motion", json=body(*starts[k % 5])) for k in range(50)))

    with serve_in_thread(4, 3.0) as url:
        answers = asyncio.run(run(url))
    assert [a.status_code for a in answers] == [200] * 50
    for k, a in enumerate(answers[:5]):
        ref = free_motion(CHAIN, *starts[k], 10.0, method="charts", save=SaveAt(t_eval=np.linspace(0, 10, 101)))
        assert np.array_equal(complex_of(a.json()["hinges"]), ref.hinges)


def test_clients_that_go_away_stop_their_solves() -> None:
    """A solve of T = 20000 (minutes of work) is stopped when its HTTP client disconnects, and likewise the
    window in progress of a WebSocket client that closes."""
    app = create_app(ServerConfig(limits=Limits(max_cost=1e6)))
    h, v = random_start(12)

    async def leave_early(url: str) -> None:
        async with httpx.AsyncClient(base_url=url) as http:
            with pytest.raises(httpx.ReadTimeout):
                await http.post("/api/motion", json=body(h, v, T=20000.0), timeout=0.5)

    with serve_in_thread(app=app) as url:
        asyncio.run(leave_early(url))
        for _ in range(200):  # the server notices within its polling interval and the solver's next report
            if app.state.cancelled_solves == 1:
                break
            asyncio.run(asyncio.sleep(0.05))
        assert app.state.cancelled_solves == 1
    with TestClient(app) as local:
        with local.websocket_connect("/api/stream") as ws:
            ws.send_json({"type": "launch", "lengths": 4, "L": 3.0, "hinges": as_pairs(h), "velocity": as_pairs(v),
                          "window": 20000.0, "rate": 0.5})
        for _ in range(200):
            if app.state.cancelled_solves == 2:
                break
            asyncio.run(asyncio.sleep(0.05))
        assert app.state.cancelled_solves == 2


def test_the_command_serves_and_says_where() -> None:
    import subprocess
    import sys

    process = subprocess.Popen([sys.executable, "-m", "linkage.explore", "--port", "0", "--no-browser", "--n", "5",
                                "--L", "3.5"], stdout=subprocess.PIPE, text=True)
    try:
        assert process.stdout is not None
        line = process.stdout.readline()
        url = line.split()[2]
        assert url.startswith("http://127.0.0.1:")
        for _ in range(100):
            try:
                config = httpx.get(url + "api/config").json()
                break
            except httpx.ConnectError:
                asyncio.run(asyncio.sleep(0.1))
        assert config["lengths"] == 5 and config["L"] == 3.5
    finally:
        process.terminate()
        process.wait(timeout=10)
    refused = subprocess.run([sys.executable, "-m", "linkage.explore", "--n", "4", "--L", "5", "--no-browser"],
                             capture_output=True, text=True)
    assert refused.returncode == 2 and "configuration space is empty" in refused.stderr


def test_without_the_extra_the_error_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib
    import sys

    monkeypatch.setitem(sys.modules, "starlette.applications", None)
    monkeypatch.delitem(sys.modules, "linkage.explore.app")
    with pytest.raises(ImportError, match=r"pip install -e '\.\[explore\]'"):
        importlib.import_module("linkage.explore.app")
