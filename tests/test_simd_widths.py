"""Ensembles on any SIMD width: heyoka reports 2 (SSE2, NEON), 4 (AVX2) or 8 (AVX-512) lanes of float64, and the
default batch size follows it.  Each width, forced, must give the single solves' motions and the same refusals.

The whole suite under a forced width: ``LINKAGE_TEST_SIMD_WIDTH=8 python -m pytest`` (see ``conftest.py``); the
slow study below runs the ensemble and budget tests that way for every width.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import heyoka as hy
import numpy as np
import pytest

from linkage import Chain
from linkage.motion import free_motion, free_motions
from linkage.sampling import sample_starts
from manifold.constrained_batch import DEFAULT_WIDTHS, MAX_BATCH_LANES

from .conftest import SIMD_WIDTH_VARIABLE
from .test_ensembles import FAST

CHAIN = Chain(4, 2.6)
WIDTHS = (1, 2, 4, 8)


@pytest.mark.parametrize("width", WIDTHS)
def test_the_default_batch_follows_the_width_and_agrees_with_single_solves(width, monkeypatch):
    monkeypatch.setattr(hy, "recommended_simd_size", lambda *args, **kwargs: width)
    H, V = sample_starts(CHAIN, 5, 0.5, np.random.default_rng(0))  # full and short batches up to 4; one of 8
    ensemble = free_motions(CHAIN, H, V, 3.0, **FAST)
    assert ensemble.solution.batch_size == DEFAULT_WIDTHS[True] * width  # compact mode: wider batches share calls
    assert ensemble.success.all(), ensemble.messages
    for k, (h, v) in enumerate(zip(H, V)):
        single = free_motion(CHAIN, h, v, 3.0, method="hinges", **FAST)
        end = CHAIN.from_point(np.asarray(single.solution.end_state()[0], dtype=float))
        assert np.max(np.abs(ensemble.end_hinges[k] - end)) <= 1e-12
    with pytest.raises(ValueError, match=f"beyond what SIMD makes useful.*{width}"):
        free_motions(CHAIN, H, V, 1.0, batch_size=MAX_BATCH_LANES * width + 1)


@pytest.mark.slow
@pytest.mark.parametrize("width", WIDTHS)
def test_the_ensemble_and_budget_tests_pass_on_every_width(width):
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, SIMD_WIDTH_VARIABLE: str(width)}
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests/test_ensembles.py",
                           "tests/test_budget.py"], cwd=root, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-3000:]
