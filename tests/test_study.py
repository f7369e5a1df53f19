"""The method study's quick mode: the claims the docs make, checked on every CI run.

Ratios of wall times on the same machine in the same process, never absolute times.
"""

import numpy as np
import pytest

from benchmarks.study import experiments as X
from benchmarks.study.report import OURS
from manifold.precision import unit_roundoff


@pytest.fixture(scope="module")
def work_precision():
    return X.work_precision(4, 40.0, quick=True, repeats=3)  # long enough that set-up costs do not blur the ratio


def test_ours_beats_scipy_dop853_at_equal_error(work_precision):
    ratios = X.speed_ratio_at_equal_error(work_precision["rows"], OURS, "scipy DOP853 atlas")
    assert len(ratios) >= 2, "the error ranges must overlap"
    geometric_mean = float(np.exp(np.mean(np.log([r for _, r in ratios]))))
    assert geometric_mean > 1.0, ratios


def test_hinge_method_leads_dop853_on_the_same_hinge_equations(work_precision):
    """Issue 9: the hinge Taylor method against DOP853 on the same compiled right-hand side (target 10x at n = 4)."""
    ratios = X.speed_ratio_at_equal_error(work_precision["rows"], "hinge Taylor (ours)", "scipy DOP853 hinges")
    assert len(ratios) >= 2, "the error ranges must overlap"
    geometric_mean = float(np.exp(np.mean(np.log([r for _, r in ratios]))))
    assert geometric_mean > 3.0, ratios


def test_ours_reaches_errors_dop853_cannot(work_precision):
    rows = work_precision["rows"]
    best = {name: min(r["hinge"] for r in rows if r["method"] == name and not r["failed"])
            for name in (OURS, "scipy DOP853 atlas")}
    assert best[OURS] * 10 < best["scipy DOP853 atlas"]
    assert best[OURS] < 1e-13


def test_single_chart_fails_at_a_pole_and_the_atlas_does_not():
    res = X.through_pole(n=4, T=2.0)
    ours, single = res["runs"][OURS], res["runs"]["single chart Taylor (chart 0)"]
    assert ours["failed"] is None and ours["energy"] < 1e-12 and ours["hinge"] < 1e-12
    assert single["failed"] is not None and single["t"][-1] < 1.0 + 1e-9  # broke down at the pole (t = 1)
    seed = res["runs"]["seed RK4 (h = 0.005)"]
    assert seed["failed"] is not None


def test_plain_sinc_breaks_the_taylor_integrator_and_the_polynomial_does_not():
    res = X.through_circle_pole(T=10.0, max_steps=3000)
    assert res["polynomial sinc (ours)"]["status"] == "reached T"
    assert res["plain sin(x)/x"]["status"].startswith("failed")
    assert res["plain sin(x)/x, off the pole"]["status"] != "reached T"


def test_each_precision_conserves_energy_to_its_own_roundoff():
    """The cost-of-precision table: energy error within 1000 unit roundoffs of each type, in CI's quick mode."""
    rows = X.precision_cost(T=2.0, quick=True)
    fp_of = {label: fp for label, fp, _ in X.PRECISIONS}
    assert [r["precision"] for r in rows] == ["float64", "long double", "real128", "real 113 bits"]
    for r in rows:
        assert r["energy_error"] <= 1e3 * unit_roundoff(fp_of[r["precision"]]), r


def test_a_rewrite_of_the_page_keeps_the_sections_other_runs_wrote(tmp_path):
    """``benchmarks.peers --markdown`` writes its section, and a run on a second machine is pasted by hand: the
    study's rewrite of ``benchmarks.md`` keeps both, in their order, word for word."""
    from benchmarks.study.report import KEPT_SECTIONS, write

    kept = "".join(f"{heading}\n\nwhat {k} said\n\n" for k, heading in enumerate(KEPT_SECTIONS))
    (tmp_path / "benchmarks.md").write_text("# an older study\n\n## Conclusions\n\nold\n\n" + kept)
    page = write({"mode": "quick", "cores": 2, "work_precision": []}, tmp_path).read_text()
    assert "an older study" not in page and "old\n" not in page
    assert page[page.index(KEPT_SECTIONS[0]):].rstrip("\n") == kept.rstrip("\n")
    assert "## The same peers on a second machine" in KEPT_SECTIONS
