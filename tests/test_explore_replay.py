"""motion.to_html: one self-contained file that replays a motion (the browser side is in test_explore_browser)."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest

from linkage import Chain
from linkage.explore.replay import STATIC
from linkage.motion import free_motion
from manifold import SaveAt


@pytest.fixture(scope="module")
def motion():
    chain = Chain(4, 3.0)
    chart0 = chain.atlas().charts[0]
    a0, c0 = np.array([1.2, 0.3]), np.array([1.0, 0.2])  # over the pole phi_4 = pi/2 of chart 0
    v0 = chain.from_point(chart0.tangent_vector(a0, c0))
    return free_motion(chain, chart0.hinges(a0), v0 / np.sqrt(2 * chain.kinetic_energy(v0)), 10.0, method="charts")


def test_the_replay_holds_the_motion_and_three_js(motion, tmp_path: Path) -> None:
    path = motion.to_html(tmp_path / "motion.html", samples=101)
    text = path.read_text()
    data = json.loads(re.search(r'<script type="application/json" id="motion">(.*?)</script>', text, re.S)[1])
    times = np.linspace(0.0, 10.0, 101)
    hinges, _ = motion(times)
    got = np.array(data["hinges"])
    assert data["times"] == times.tolist()
    assert np.array_equal(got[..., 0] + 1j * got[..., 1], hinges)
    assert len(data["switches"]) == motion.n_switches >= 1
    assert max(data["energyError"]) <= 1e-12
    assert np.allclose(np.linalg.norm(data["sphere"], axis=1), 1.0)
    three = re.search(r'<script type="text/plain" id="three-source">(.*?)</script>', text, re.S)[1]
    assert base64.b64decode(three) == (STATIC / "vendor" / "three" / "three.module.min.js").read_bytes()
    # nothing is loaded from elsewhere: no script or stylesheet by address
    assert not re.search(r"<(script|link)[^>]*(src|href)=\"(?!data:)", text)


def test_the_replay_needs_dense_output(tmp_path: Path) -> None:
    chain = Chain(4, 3.0)
    chart0 = chain.atlas().charts[0]
    a0, c0 = np.array([0.3, 0.2]), np.array([1.0, 0.2])
    sparse = free_motion(chain, chart0.hinges(a0), chain.from_point(chart0.tangent_vector(a0, c0)), 1.0,
                         method="charts", save=SaveAt(dense=False))
    with pytest.raises(ValueError, match="dense"):
        sparse.to_html(tmp_path / "sparse.html")
    with pytest.raises(ValueError, match="samples"):
        sparse.to_html(tmp_path / "sparse.html", samples=1)
