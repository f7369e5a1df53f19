"""Configuration curves of 6R chains from their axes alone, against the curves the paper prints
for Examples 11 and 12 (found there by motion polynomial factorisation, not by elimination)."""

from __future__ import annotations

import sympy

from linkage.spatial import RevoluteChain
from linkage.spatial.examples import example_11_axes, example_12

s = sympy.Symbol("s")
# Example 11, printed with parameter s
EX11 = [s, (s**2 - 3 * s + 1) / (2 * s - 3), -s, s**2 - 5 * s + 7, -s + 1, -s + 3]
# Example 12, printed
EX12 = [3 + s, -(s**2 + 3 * s + 1) / (2 * s + 3), s, s**2 + 5 * s + 7, s + 1, s]


def _same_curve(found, printed):
    """The eliminated curve is parametrised by t = t6; the printed one by s with t6 = t6(s)
    (linear in both examples), so substitute t = t6(s) and compare as rational functions."""
    t = sympy.Symbol("t")
    return all(sympy.simplify(f.subs(t, printed[5]) - p) == 0 for f, p in zip(found.expressions(), printed))


def test_example_11_curve_by_elimination_is_the_printed_one():
    chain = RevoluteChain(example_11_axes())
    curve = chain.configuration_curve()
    assert curve.is_rational and curve.genus == 0
    assert _same_curve(curve, EX11)


def test_example_12_curve_by_elimination_is_the_printed_one():
    chain = RevoluteChain(example_12().axes)
    assert _same_curve(chain.configuration_curve(), EX12)
