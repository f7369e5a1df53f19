"""Bounded work and memory: a solve spends at most a budget of Taylor steps, of dense-output bytes and of CPU time.

A chain whose light hinge whips (masses 1e-8 .. 1e8: millions of steps per unit time) or a long run with dense
output (T = 1e5 at n = 4: 6.3 GB) used to run until the machine gave out.  Every solve now spends from a
:class:`Budget` (:data:`DEFAULT_BUDGET` unless given): :func:`spending` opens it for the solve, and each Taylor
propagation asks :func:`allowance` how many steps it may take, given the bytes each of its steps keeps, and stops
between chunks of steps (:func:`manifold.interrupt.propagate_until`) once :func:`out_of_time`.  When the
budget is spent the solve stops with what it computed (status ``BUDGET_EXCEEDED``), and the message names the
budget and the estimated need, extrapolated from the time reached.

Steps alone do not bound the time: a step's cost differs between solvers (measured in CPU time on one machine at
n = 4, 5, 7: 9, 10, 37 us for the hinge method, 240, 410, 810 us for the chart method in Sundman's time, 22-39
times as much; two to four times that in long double), so 1e8 steps are 15 minutes of the one and a day of the
other.  Chart solves take 1e4-1e5 steps per unit time near either end of the range of ``L`` (n = 7,
``L = 5.0136``, T = 2.95: 85,895 steps, 1,230 chart switches, 38 s of CPU; n = 5, ``L = 5 - 1e-7``: 24,000
steps and 300 switches per unit time), so a long one runs for hours within the step budget.  The CPU seconds of
the solving thread bound that.  They are the one part of a budget whose verdict depends on the machine: a run
stopped by them stops at a time that does; ``Budget(seconds=None)`` bounds steps and bytes only,
machine-independent.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Budget", "DEFAULT_BUDGET", "allowance", "dense_bytes_per_step", "out_of_time", "spend", "spending",
           "spent_message"]


@dataclass(frozen=True)
class Budget:
    """How much one solve may spend.

    Attributes
    ----------
    steps
        Taylor steps, all segments together (default 1e8: about 15 minutes of the hinge method's steps, a day of the
        chart method's, which the CPU seconds bound).
    dense_bytes
        Bytes of dense output kept (default 2 GiB, estimated per step from the Taylor coefficients' size).
    seconds
        CPU seconds of the thread that solves (default 300; ``None``: no limit), checked between chunks of about
        0.1 s of steps (module docstring: the one limit whose verdict depends on the machine).
    """

    steps: int = 10**8
    dense_bytes: int = 2 * 2**30
    seconds: float | None = 300.0

    def __post_init__(self) -> None:
        for name in ("steps", "dense_bytes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"Budget.{name} must be an integer >= 1, got {value!r}")
        seconds = self.seconds
        if seconds is not None and (isinstance(seconds, bool) or not isinstance(seconds, (int, float))
                                    or not 0 < seconds < float("inf")):
            raise ValueError(f"Budget.seconds must be None or a finite number of seconds > 0, got {seconds!r}")


#: The budget of a solve that is given none.
DEFAULT_BUDGET = Budget()


@dataclass
class _Account:
    budget: Budget
    steps: int = 0
    dense_bytes: int = 0
    per_step: int = 0  # bytes a dense step kept, the last time one was asked for
    cpu0: float = field(default_factory=time.thread_time)  # the solving thread's CPU clock at the start

    def cpu_seconds(self) -> float:
        return time.thread_time() - self.cpu0


_ACCOUNT: ContextVar[_Account | None] = ContextVar("manifold_budget", default=None)


@contextmanager
def spending(budget: Budget) -> Iterator[_Account]:
    """Within the block, Taylor propagations spend from ``budget`` (see the module docstring)."""
    if not isinstance(budget, Budget):
        raise TypeError(f"budget must be a manifold.budget.Budget, got {budget!r}")
    account = _Account(budget)
    token = _ACCOUNT.set(account)
    try:
        yield account
    finally:
        _ACCOUNT.reset(token)


def allowance(bytes_per_step: int) -> int | None:
    """Steps the next propagation may take, keeping ``bytes_per_step`` of dense output each (0 for none);
    ``None`` outside a :func:`spending` block (no limit)."""
    account = _ACCOUNT.get()
    if account is None:
        return None
    account.per_step = max(account.per_step, bytes_per_step) if bytes_per_step else account.per_step
    if out_of_time():
        return 0
    left = account.budget.steps - account.steps
    if bytes_per_step:
        left = min(left, (account.budget.dense_bytes - account.dense_bytes) // bytes_per_step)
    return max(left, 0)


def out_of_time() -> bool:
    """Whether the solve of the enclosing :func:`spending` block has spent its CPU seconds (outside one: no)."""
    account = _ACCOUNT.get()
    return (account is not None and account.budget.seconds is not None
            and account.cpu_seconds() >= account.budget.seconds)


def dense_bytes_per_step(ta: Any, positions: int = 0) -> int:
    """Bytes one step of dense output keeps: the integrator's Taylor coefficients and the step's time (objects of
    software floating types, real128 and MultiPrecision, counted at 64 bytes each: an estimate); with
    ``positions``, those of :class:`manifold.solution.SecondOrderDense` (the first ``positions`` components'
    coefficients and one more number each)."""
    tc = ta.tc
    item = tc.itemsize if tc.dtype != object else 64
    numbers = tc.size if not positions else positions * (tc.shape[1] + 1)
    return int(numbers * item + item)


def spend(steps: int, bytes_per_step: int) -> None:
    """Record ``steps`` taken, each keeping ``bytes_per_step`` of dense output (outside a block: nothing)."""
    account = _ACCOUNT.get()
    if account is not None:
        account.steps += steps
        account.dense_bytes += steps * bytes_per_step


def spent_message(account: _Account, t: float, t_final: float) -> str:
    """The sentence of a solve stopped by its budget at ``t``: the budget, and the need extrapolated to ``t_final``."""
    scale = abs(t_final) / abs(t) if t else float("inf")
    need = f"about {account.steps * scale:.3g} steps ({account.cpu_seconds() * scale:.3g} s of CPU here)"
    if account.per_step:
        need += f" and {account.dense_bytes * scale / 2**30:.3g} GiB of dense output ({account.per_step} bytes a step)"
    dense = (", or save=SaveAt(dense=False) to keep no dense output (where a solver reads a t_eval grid from a "
             "segment's dense output, also no t_eval)") if account.per_step else ""  # a solve that kept no dense output has no use for the hint
    budget = account.budget
    seconds = "" if budget.seconds is None else f" and {budget.seconds:g} s of CPU"
    return (f"the budget of {budget.steps:.3g} steps, {budget.dense_bytes / 2**30:.3g} GiB of dense output{seconds} "
            f"is spent at t = {t:.6g}: reaching t_final = {t_final:g} would take {need}; pass "
            f"budget=manifold.budget.Budget(...) to allow it{dense}")
