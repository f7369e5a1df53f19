"""Long propagations that Ctrl-C stops within a fraction of a second, with their partial result.

Python runs its signal handlers only between bytecodes, and heyoka's
``propagate_until`` runs in C++: a ``KeyboardInterrupt`` pressed during one long
propagation waited until it returned (a Lyapunov run near the stretched chain
ignored Ctrl-C for over four minutes).  :func:`propagate_until` runs it in chunks
of steps (heyoka's ``max_steps``), sized from the last chunk's wall time to take
about :data:`CHUNK_SECONDS` each, and looks for a Ctrl-C between them and after
every step a callback runs (a flag set by a temporary SIGINT handler: an
exception raised inside a step callback could leave half of a step recorded).
Chunks change no digit: a Taylor step depends only on the state it starts from,
and events and cooldowns live in the integrator.  :func:`propagate_grid` runs in one call with a step
callback that reads the flag instead (see there).  The solvers then stop with
what they computed and raise :class:`SolveInterrupted`, a ``KeyboardInterrupt``
that carries it.

Ensembles (:func:`manifold.ensemble.map_chunks`) hold a block open in the main
thread while worker threads run the chunks; a block opened in a worker thread
then reads the main thread's flag, so one Ctrl-C stops every worker's solve,
and each chunk returns what it computed.  SIMD batches
(:mod:`manifold.constrained_batch`) read the flag in a step callback of
heyoka's ``propagate_grid``.  Not interruptible: a compile (LLVM runs in C++
to its end: seconds for a large system, once; heyoka caches the result on
disk) and a Dask cluster's workers (separate processes: Ctrl-C stops the
client's wait as usual, without partial results).
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import NDArray

from .budget import out_of_time
from .solution import SolveStatus

__all__ = ["BUDGET", "CHUNK_SECONDS", "INTERRUPTED", "Listener", "SolveInterrupted", "interruptible", "propagate_grid",
           "propagate_until", "settled"]

#: Wall time a chunk of steps is sized to take: how long a Ctrl-C waits at most, about.
CHUNK_SECONDS = 0.1
#: The first chunk's steps, before any is timed.
FIRST_CHUNK = 64
#: Steps between two readings of the CPU clock by :func:`propagate_grid`'s step callback (a reading costs about as
#: much as a short step).
TIME_CHECK_STEPS = 256
#: The failure message of an interrupted propagation.
INTERRUPTED = "interrupted (KeyboardInterrupt)"
#: The failure message of a propagation stopped by its budget of steps or CPU time (:mod:`manifold.budget`).
BUDGET = "budget spent"


class SolveInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a solve: a ``KeyboardInterrupt`` (so a script stops as usual) that carries the partial result.

    Attributes
    ----------
    result
        What was computed up to the interrupt (a :class:`~manifold.solution.GeodesicSolution`, or the
        solver's own result type), with its status saying so.
    """

    def __init__(self, message: str, result: Any) -> None:
        super().__init__(message)
        self.result = result


_STATE: dict[str, Any] = {"depth": 0, "pressed": False, "previous": None}


def _on_interrupt(signum: int, frame: Any) -> None:
    _STATE["pressed"] = True


class Listener:
    """What an :func:`interruptible` block gets: called, whether Ctrl-C was pressed; ``live``, whether a Ctrl-C can
    reach it at all (a solver passes heyoka a step callback only then: it costs ~0.25 us a step)."""

    def __init__(self, live: bool) -> None:
        self.live = live

    def __call__(self) -> bool:
        return self.live and _STATE["depth"] > 0 and bool(_STATE["pressed"])


def interruptible() -> AbstractContextManager[Listener]:
    """For the block: Ctrl-C sets a flag instead of raising, and the block gets the :class:`Listener` that reads it.

    The flag's handler goes in only in the main thread and only over Python's default SIGINT handler (any other
    handler is left alone, and the block reads ``False``); nested blocks share the outermost one's flag, and the
    default handler is back when it ends.  A block in another thread reads the main thread's flag while the main
    thread is inside a block (an ensemble waiting for its workers), else ``False``.
    """
    return _Block()


class _Block:
    """:func:`interruptible`'s context manager (a class: a generator's costs ~1 us more a block, and every solve
    opens two)."""

    __slots__ = ("install",)

    def __enter__(self) -> Listener:
        main = threading.current_thread() is threading.main_thread()
        self.install = main and (_STATE["depth"] > 0 or signal.getsignal(signal.SIGINT) is signal.default_int_handler)
        if self.install:
            if _STATE["depth"] == 0:
                _STATE["pressed"], _STATE["previous"] = False, signal.signal(signal.SIGINT, _on_interrupt)
            _STATE["depth"] += 1
        return Listener(self.install or (not main and _STATE["depth"] > 0))

    def __exit__(self, *exc: object) -> None:
        if self.install:
            _STATE["depth"] -= 1
            if _STATE["depth"] == 0:
                signal.signal(signal.SIGINT, _STATE["previous"])


def settled(pressed: bool, status: SolveStatus, message: str, t: Any) -> tuple[SolveStatus, str]:
    """A solve's ``(status, message)`` at its end: :attr:`~manifold.solution.SolveStatus.INTERRUPTED` if Ctrl-C was
    pressed at all during it (``pressed``), even where another failure ended the run, whose message is kept."""
    if not pressed or status is SolveStatus.INTERRUPTED:
        return status, message
    return SolveStatus.INTERRUPTED, f"{INTERRUPTED} at t = {float(t)} ({message or 'reached t_final'})"


def propagate_until(ta: Any, t_limit: Any, *, callback: Callable[[Any], bool] | None = None,
                    write_tc: bool = False, max_steps: int | None = None) -> tuple[Any, int, str | None]:
    """``ta.propagate_until(t_limit, ...)`` in chunks of steps, stopping cleanly on Ctrl-C.

    Within :func:`interruptible` (the solvers open one for the whole solve; this opens its own otherwise),
    Ctrl-C only sets a flag: a step ``callback`` (Python, after every step) finishes its step and then stops
    the propagation, and without one the next chunk boundary does.  So whatever a callback records stays whole,
    and the state is that after the last accepted step.

    With ``max_steps`` (a :mod:`manifold.budget` allowance) it takes at most that many steps, and it stops between
    chunks once the budget's CPU seconds are spent (:func:`manifold.budget.out_of_time`).

    Returns ``(outcome, steps, stop)``: heyoka's outcome of the last chunk, the steps of all of them, and
    :data:`INTERRUPTED` if Ctrl-C stopped the propagation, :data:`BUDGET` if ``max_steps`` did, else ``None``.
    """
    with interruptible() as pressed:
        def stepped(ta: Any) -> bool:
            go_on = callback(ta) if callback is not None else True
            return bool(go_on) and not pressed()

        total, chunk = 0, FIRST_CHUNK
        while True:
            if max_steps is not None and (total >= max_steps or out_of_time()):
                return hy.taylor_outcome.step_limit, total, BUDGET
            t0 = time.perf_counter()
            size = chunk if max_steps is None else min(chunk, max_steps - total)
            outcome, _, _, steps, *_ = ta.propagate_until(t_limit, callback=None if callback is None else stepped,
                                                          write_tc=write_tc, max_steps=size)
            total += steps
            if pressed():
                return outcome, total, INTERRUPTED
            if outcome != hy.taylor_outcome.step_limit:
                return outcome, total, None
            elapsed = time.perf_counter() - t0  # sizes the next chunk only: the steps do not depend on it
            chunk = max(16, min(10**7, int(chunk * CHUNK_SECONDS / max(elapsed, 1e-6))))


def propagate_grid(ta: Any, grid: NDArray, *, callback: Callable[[Any], bool] | None = None,
                   max_steps: int | None = None) -> tuple[Any, int, str | None, NDArray]:
    """``ta.propagate_grid`` over ``grid``, stopping cleanly on Ctrl-C, as :func:`propagate_until` stops.

    heyoka evaluates the states at the grid's times on each step's Taylor polynomials, in C++.  ``grid`` holds times
    from ``ta.time`` on, in integration order (repeats allowed), and its last time is where the run ends: the steps
    are those of ``propagate_until(grid[-1])``, since heyoka clamps a step only at the grid's end.  It runs as one
    heyoka call, with a step callback that reads the Ctrl-C flag (about 0.1 us a step), not in chunks: a grid
    restarted where a chunk stopped would begin at a float64 time, without the low half of heyoka's double-length
    time, and the samples would then depend on how the machine's speed sized the chunks.  With ``max_steps`` (a
    :mod:`manifold.budget` allowance) it takes at most that many steps, and the callback stops it once the budget's
    CPU seconds are spent (read every :data:`TIME_CHECK_STEPS` steps).

    Returns ``(outcome, steps, stop, states)``: heyoka's outcome and steps, :data:`INTERRUPTED` if Ctrl-C stopped
    the run, :data:`BUDGET` if ``max_steps`` or the CPU seconds did, else ``None``, and the states at the grid's times that the run
    reached, ``states[j]`` at ``grid[j]`` (``len(states) <= len(grid)``; all of them if it reached the end).
    """
    grid = np.asarray(grid)
    if grid.ndim != 1 or len(grid) == 0:
        raise ValueError(f"grid must be a non-empty 1-d array of times, got shape {grid.shape}")
    if max_steps is not None and max_steps < 1:
        return hy.taylor_outcome.step_limit, 0, BUDGET, np.empty((0, len(ta.state)), dtype=ta.state.dtype)
    # heyoka wants a strictly monotonic grid that begins at the integrator's time: integrate over the distinct
    # times after it, then copy rows to repeats and to times at the start
    distinct = np.concatenate([[True], grid[1:] != grid[:-1]])
    times, row = grid[distinct], np.cumsum(distinct) - 1
    at_start = int(times[0] == ta.time)
    start = np.array(ta.state)
    with interruptible() as pressed:
        steps_taken, timed_out = 0, False

        def stepped(ta: Any) -> bool:
            nonlocal steps_taken, timed_out
            go_on = callback(ta) if callback is not None else True
            steps_taken += 1
            if steps_taken % TIME_CHECK_STEPS == 0 and max_steps is not None and out_of_time():
                timed_out = True
            return bool(go_on) and not pressed() and not timed_out

        outcome, _, _, steps, _, out = ta.propagate_grid(np.concatenate([[ta.time], times[at_start:]]),
                                                         callback=stepped, max_steps=max_steps or 0)
        # a run stopped early returns only the rows of the times it passed (its first row is the grid's start)
        states = np.concatenate([start[None, :]] * at_start + [out[1:]])
        if len(states) < len(times) and times[len(states)] == ta.time:  # stopped on a grid time: the state there
            states = np.concatenate([states, np.array(ta.state)[None, :]])
        if pressed():
            stop: str | None = INTERRUPTED
        elif timed_out or (max_steps is not None and outcome == hy.taylor_outcome.step_limit):
            stop = BUDGET
        else:
            stop = None
    filled = len(states)
    return outcome, steps, stop, states[row[row < filled]]
