"""A motion as one self-contained HTML file: ``ChainMotion.to_html(path)``.

The file holds the motion's samples (:func:`linkage.explore.protocol.motion_payload` on an even grid of its
dense output) as JSON and three.js (the vendored module, base64) and replays them with no server and nothing
from the network: the chain in the plane with a trail, the path on chart 0's sphere coloured by the
integrating chart with the switches marked, and the relative energy error against time.  It needs no web
framework.
"""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .protocol import motion_payload

if TYPE_CHECKING:
    from ..motion import ChainMotion

__all__ = ["replay_html", "write_replay"]

STATIC = Path(__file__).with_name("static")


def replay_html(motion: ChainMotion, samples: int = 600, title: str | None = None) -> str:
    """The replay page of ``motion`` as a string (see :func:`write_replay`)."""
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 2:
        raise ValueError(f"samples must be an integer >= 2, got {samples!r}")
    times = np.linspace(0.0, float(motion.solution.t_reached), int(samples))
    payload = motion_payload(motion, times=times)
    chain = motion.chain
    payload.update(lengths=chain.lengths.tolist(), L=chain.L, summary=chain.topology().summary())
    three = base64.b64encode((STATIC / "vendor" / "three" / "three.module.min.js").read_bytes()).decode("ascii")
    name = title if title is not None else f"Free motion of {chain.n} rods, L = {chain.L:g}"
    # JSON inside <script>: '</' would end the element, so it is written '<\/', which JSON reads the same
    data = json.dumps(payload).replace("</", "<\\/")
    page = (STATIC / "replay.html").read_text()
    return page.replace("__TITLE__", _escape(name)).replace("__MOTION__", data).replace("__THREE__", three)


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def write_replay(motion: ChainMotion, path: str | Path, samples: int = 600, title: str | None = None) -> Path:
    """Write ``motion`` as a self-contained HTML replay to ``path`` and return the path.

    Parameters
    ----------
    motion
        A solved motion with dense output (``dense=False`` is refused by the motion's own evaluation).
    path
        The file to write (``.html``).
    samples
        Samples on an even grid over the solved span (three.js draws them; nothing is integrated in the page).
    title
        The page's title (default: the number of rods and ``L``).
    """
    out = Path(path)
    out.write_text(replay_html(motion, samples, title), encoding="utf-8")
    return out
