"""Drawings: they work on a plain matplotlib Figure, and matplotlib loads only when one is drawn."""

import numpy as np
from matplotlib.figure import Figure

from linkage import Chain, draw_configuration, draw_configurations


def test_draw_configurations_puts_rods_hinges_and_pins_on_the_axes():
    chain = Chain(3, 2.0)
    h = np.array([np.exp(1j * np.pi / 3), 1 + np.exp(1j * np.pi / 3)])
    ax = Figure().add_subplot()
    assert draw_configurations(ax, [h, h.conj()], chain.L, labels=["up", "down"]) is ax
    assert len(ax.lines) == 2 * 3  # per configuration: rods, hinges, pins
    np.testing.assert_allclose(ax.lines[0].get_xydata(), [[0, 0], [h[0].real, h[0].imag], [h[1].real, h[1].imag], [2, 0]])
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["up", "down"]
    assert draw_configuration(Figure().add_subplot(), h, chain.L) is not None
