"""The friendlier surface: precision by name, the demo's command line, version and licence."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import heyoka as hy
import numpy as np
import pytest

import linkage
import manifold
from linkage import Chain
from linkage.motion import free_motion
from manifold import Precision
from manifold.precision import MultiPrecision, resolve_fp_type

from .conftest import unit_speed_start

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("name, expected", [("float64", float), ("longdouble", np.longdouble),
                                            ("real128", hy.real128), ("mp200", MultiPrecision(200))])
def test_precision_by_name(name, expected):
    assert resolve_fp_type(name) == expected


@pytest.mark.parametrize("bad", ["float32", "mp", "quad"])
def test_unknown_precision_names_list_the_valid_ones(bad):
    with pytest.raises(ValueError, match="'float64', 'longdouble', 'real128' or 'mp<bits>'"):
        resolve_fp_type(bad)
    with pytest.raises(ValueError, match=r"bits must be an integer in \[24, 1000\]"):
        resolve_fp_type("mp12")


def test_a_real128_run_by_name_matches_the_type():
    chain = Chain(4, 2.7)
    h0, v0 = unit_speed_start(chain, [0.3, 0.4], [1.0, 0.2])
    by_name = free_motion(chain, h0, v0, 0.5, precision=Precision(fp_type="real128"))
    by_type = free_motion(chain, h0, v0, 0.5, precision=Precision(fp_type=hy.real128))
    assert by_name.solution.fp_type is hy.real128
    assert np.array_equal(by_name.solution.end_state()[0], by_type.solution.end_state()[0])
    assert by_name.relative_energy_error <= 1e-30


def test_version_and_licence():
    assert linkage.__version__ == manifold.__version__ != "0+unknown"
    assert "MIT License" in (ROOT / "LICENSE").read_text()


@pytest.mark.parametrize("args, code, text", [(["--help"], 0, "usage: linkage-demo"),
                                              (["--n", "4", "--L", "5"], 2, "2 < L < 4"),
                                              (["--n", "2"], 2, "--n must be an integer >= 3"),
                                              (["--T", "0"], 2, "--T must be a finite positive time, got 0.0"),
                                              (["--T", "nan"], 2, "--T must be a finite positive time, got nan")])
def test_demo_command_line(args, code, text):
    run = subprocess.run([sys.executable, "-m", "linkage", *args], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == code
    assert text in run.stdout + run.stderr and "Traceback" not in run.stderr


@pytest.mark.parametrize("precision, floor", [("float64", 1e-17), ("longdouble", 1e-21)])
def test_demo_compares_in_the_working_precision_and_prints_no_nan(precision, floor, tmp_path):
    """A short run: the distance to the hinge method is computed in the working precision (rounded to complex128
    first, a long-double run reported exactly 0), its horizon is the run's, and no exp(nan t) is printed."""
    from linkage.demo import run as demo_run

    stats = demo_run(4, 2.6, 8.0, precision, str(tmp_path / "demo.png"), samples=200)
    assert floor < stats["hinge_distance_10"] < 1e-12
    assert stats["early_horizon"] == 8.0
    out = subprocess.run([sys.executable, "-m", "linkage", "--T", "8", "--out", str(tmp_path / "d.png")], cwd=ROOT,
                         capture_output=True, text=True).stdout
    assert "nan" not in out and "for t <= 8 " in out
