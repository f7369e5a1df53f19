"""``python -m benchmarks.peers``: its peers integrate the hinge method's own equations, and its ratios read
times at equal error as stated (no timing here: the ratios of made-up work-precision curves).

:mod:`benchmarks.transcribed_rhs` writes heyoka's decomposition of the compiled acceleration out as
Python; evaluated as plain Python it must give what the compiled function gives, at states off the
start too (where the Baumgarte terms act), for any mass model.
"""

import numpy as np
import pytest

from benchmarks.peers import Row, cpu_at, front, ratio_cell, ratios
from benchmarks.study.report import replace_section, section
from benchmarks.transcribed_rhs import hinge_rhs, hinge_start, rhs_source
from linkage import Chain
from linkage.constraints import ChainSystem
from manifold.constrained import compiled_constrained


def _start(chain: Chain, seed: int):
    """A closed chain and a tangent velocity, from the atlas (an independent route to a valid start)."""
    rng = np.random.default_rng(seed)
    atlas = chain.atlas()
    a0 = np.append(rng.uniform(-1, 1, chain.n - 3), rng.uniform(-1, 1))
    p0 = atlas.get_point(0, a0)
    v0 = atlas.charts[0].tangent_vector(a0, rng.normal(size=chain.n - 2))
    return chain.from_point(p0), chain.from_point(v0)


@pytest.mark.parametrize("chain", [Chain(3, 1.7), Chain(4, 2.7), Chain(6, 4.6, hinge_masses=[0.3, 2.0, 1.0, 0.5, 4.0]),
                                   Chain(5, 3.6, rod_densities=0.2), Chain(8, 6.8)],
                         ids=["n3", "n4", "n6 masses", "n5 rod densities", "n8"])
def test_transcription_gives_the_compiled_acceleration(chain):
    h0, w0 = _start(chain, seed=chain.n)
    y0, pars = hinge_start(chain, h0, w0, 20.0)
    N = 2 * (chain.n - 1)
    assert np.allclose(y0[:N], chain.to_point(h0), atol=1e-12)
    assert pars[0] > 0  # the Baumgarte rate, forward in time
    acc = compiled_constrained(ChainSystem(chain)).acceleration(float)
    f = hinge_rhs(chain)
    rng = np.random.default_rng(0)
    for scale in (0.0, 1e-6, 1e-2):  # on the constraints and off them
        y = y0 + scale * rng.normal(size=y0.shape)
        expected = np.concatenate([y[N:], acc(y, pars=pars)])
        got = f(y, pars)
        assert got.shape == (2 * N,)
        assert np.max(np.abs(got - expected)) <= 1e-14 * max(1.0, np.max(np.abs(expected)))


def test_transcription_refuses_an_unknown_function():
    class Fake:
        dc = ["x0", "v0", "sin(u_0)", "u_2"]
        nvars, nouts = 2, 1

    with pytest.raises(ValueError, match="no transcription for heyoka function 'sin"):
        rhs_source(Fake())


def test_a_kept_section_is_replaced_in_place_or_appended():
    page = "# Title\n\nintro\n## A\nold\n\n## B\nb\n"
    assert section(page, "## A") == "## A\nold\n\n"
    assert replace_section(page, "## A", "## A\nnew\n") == "# Title\n\nintro\n## A\nnew\n\n## B\nb\n"
    again = replace_section(replace_section(page, "## A", "## A\nnew\n"), "## A", "## A\nnew\n")
    assert again == replace_section(page, "## A", "## A\nnew\n")  # rewriting does not pile up blank lines
    assert replace_section(page, "## C", "## C\nc\n") == page + "\n## C\nc\n"
    assert section(page, "## C") is None


def _curve(method: str, points: list[tuple[float, float]]) -> list[Row]:
    return [Row(method, None, cpu=c, error=e) for e, c in points]


def test_front_drops_runs_beaten_in_both_and_reads_log_log():
    rows = _curve("a", [(1e-6, 2.0), (1e-8, 1.0), (1e-10, 4.0), (1e-12, 16.0), (1e-11, 20.0)])
    assert front(rows, "a") == [(1e-12, 16.0), (1e-10, 4.0), (1e-8, 1.0)]  # 1e-6 is slower than 1e-8; 1e-11 too
    assert cpu_at(front(rows, "a"), 1e-11) == (pytest.approx(8.0), "")  # halfway in log error: sqrt(4 * 16)
    assert cpu_at(front(rows, "a"), 1e-6) == (1.0, "<=")  # the loosest run already beats it: a bound
    assert np.isnan(cpu_at(front(rows, "a"), 1e-13)[0])  # never reached


def test_ratios_at_equal_error_and_their_bounds():
    ours = _curve("ours", [(1e-9, 1.0), (1e-13, 3.0)])
    peer = _curve("peer", [(1e-6, 2.0), (1e-8, 4.0), (1e-10, 9.0), (1e-12, 20.0)])
    (e1, r1, m1), (e2, r2, m2), (e3, r3, m3) = ratios(ours + peer, "ours", "peer")
    assert (e1, m1) == (1e-8, ">=") and r1 == pytest.approx(4.0)  # our loosest run beats 1e-8: at least 4x
    assert (e2, m2) == (1e-10, "") and r2 == pytest.approx(9.0 / 3.0 ** 0.25)
    assert (e3, m3) == (1e-12, "") and r3 == pytest.approx(20.0 / 3.0 ** 0.75)
    assert ratio_cell(ratios(ours + peer, "ours", "peer")) == ">=4.0x / 6.8x / 8.8x"
    # the other way round, "ours" (now the peer) is read at 1e-8 from its loosest run: an upper bound
    assert [mark for _, _, mark in ratios(ours + peer, "peer", "ours")] == ["<=", "", ""]
