"""Bond diagrams and linkage poses: the drawings show the mathematics (line counts, rigid links)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from linkage.spatial.draw import draw_bond_diagram, link_segments  # noqa: E402
from linkage.spatial.examples import bennett  # noqa: E402


def _connection_lines(ax, color="C3"):
    return [ln for ln in ax.get_lines() if ln.get_color() == color and len(ln.get_xdata()) > 2]


def test_one_curve_per_unit_of_connection_dashed_when_negative():
    fig, ax = plt.subplots()
    draw_bond_diagram(ax, 5, {(1, 3): 2, (2, 5): -1, (1, 4): 1})
    lines = _connection_lines(ax)
    assert len(lines) == 4
    assert sorted(ln.get_linestyle() for ln in lines) == ["-", "-", "-", "--"]
    plt.close(fig)


def test_chain_draws_its_own_connections():
    """Figure 1.a: the Bennett diagram has two connecting lines, h1-h3 and h2-h4."""
    fig, ax = plt.subplots()
    bennett().draw_bond_diagram(ax)
    assert len(_connection_lines(ax)) == 2
    plt.close(fig)


def test_bad_diagram_arguments_are_named():
    fig, ax = plt.subplots()
    with pytest.raises(ValueError, match="n must be"):
        draw_bond_diagram(ax, 2, {})
    with pytest.raises(ValueError, match=r"outside 1\.\.4"):
        draw_bond_diagram(ax, 4, {(1, 5): 1})
    plt.close(fig)


def test_links_stay_rigid_and_meet_on_their_axes():
    """Along the real curve each link keeps its length, and the end of o_j and the start of
    o_{j+1} lie on the same (moved) axis h_{j+1}: the chain closes in space."""
    chain = bennett()
    curve = chain.configuration_curve()
    home, _ = link_segments(chain, (complex("inf"),) * 4)
    lengths = [np.linalg.norm(b - a) for a, b in home]
    for t in np.linspace(-5, 5, 11):
        links, axes = link_segments(chain, curve(t))
        assert np.allclose([np.linalg.norm(b - a) for a, b in links], lengths, atol=1e-9)
        for j in range(4):
            point, direction = axes[(j + 1) % 4]
            for q in (links[j][1], links[(j + 1) % 4][0]):
                off = q - point
                assert np.linalg.norm(off - (off @ direction) * direction) < 1e-9
