"""Progress of long solves and compiles, reported only when asked: a tqdm bar or a callback.

A ``progress`` argument (:func:`manifold.solve_chart_exp_ode`,
``linkage.motion.free_motion``, :func:`reporting`) is one of

* ``None`` (default): report to the callback of an enclosing
  :func:`reporting` block, if any; otherwise stay silent;
* ``False``: report nothing, even inside such a block;
* ``True`` or ``"tqdm"``: a :class:`TqdmProgress` bar on stderr (needs the
  optional ``tqdm``: ``pip install 'linkage-manifolds[progress]'``);
* a callable ``f(update)`` taking a :class:`ProgressUpdate`.

A solve reports the time reached ``t`` of ``t_final`` after every segment (a
chart switch ends one), between them at most every
:data:`STEP_INTERVAL` seconds (from heyoka's per-step callback, which reads
the integrator and changes nothing), and once when it ends.
Compiles report when they start, saying what they compile and where heyoka
keeps the machine code on disk, and when they end, with the seconds taken.
Compiles run inside library calls that take no ``progress`` argument too
(``Atlas.best_chart`` builds the quality function, for instance): wrap them in
``with reporting(True): ...``.

The active callback lives in a :class:`contextvars.ContextVar`, so
concurrent solves in other threads keep their own (a new thread starts with
none).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any, Union

import heyoka as hy

__all__ = ["ProgressArgument", "ProgressCallback", "ProgressUpdate", "SolveProgress", "TqdmProgress", "as_callback",
           "compiling", "reporting", "solve_progress", "step_callback"]

#: Least wall time, in seconds, between two reports from inside a segment (``kind="step"``).
STEP_INTERVAL = 0.2

@dataclass(frozen=True)
class ProgressUpdate:
    """One progress report.

    Attributes
    ----------
    kind
        ``"compile"`` (a compile starts), ``"compiled"`` (it ended),
        ``"step"`` (a solve is inside a segment), ``"solve"`` (a segment of a
        solve ended), ``"done"`` (the solve ended, successfully or not).
    message
        A sentence for a person: what is compiled, the chart of the segment
        that ended, how the solve ended (empty for ``"step"``).
    t, t_final
        Time reached and final time of the solve (0 for compiles).
    n_steps, n_switches
        Steps and chart switches so far (0 for compiles).
    seconds
        Wall time of a finished compile (``"compiled"``), else 0.
    """

    kind: str
    message: str
    t: float = 0.0
    t_final: float = 0.0
    n_steps: int = 0
    n_switches: int = 0
    seconds: float = 0.0

    @property
    def fraction(self) -> float:
        """``|t| / |t_final|`` in ``[0, 1]``: the share of the solve done (1 for ``t_final = 0``)."""
        return 1.0 if self.t_final == 0 else min(1.0, abs(self.t) / abs(self.t_final))


#: What receives progress: any callable taking a :class:`ProgressUpdate`.
ProgressCallback = Callable[[ProgressUpdate], None]
#: What a ``progress`` argument accepts (see the module docstring).
ProgressArgument = Union[ProgressCallback, bool, str, None]

_ACTIVE: ContextVar[ProgressCallback | None] = ContextVar("manifold_progress", default=None)
_STEP: ContextVar[Callable[[Any], bool] | None] = ContextVar("manifold_progress_step", default=None)


class TqdmProgress:
    """A tqdm bar over the time of each solve; compile messages printed above it.

    One bar per solve, from 0 to ``|t_final|`` in units of time, with the steps
    and switches so far as its postfix; it closes when the solve ends.

    Parameters
    ----------
    **tqdm_kwargs
        Passed to ``tqdm.tqdm`` (``leave``, ``file``, ``mininterval``, ...).

    Raises
    ------
    ImportError
        If ``tqdm`` is not installed (it is the optional extra ``progress``).
    """

    def __init__(self, **tqdm_kwargs: Any) -> None:
        try:
            import tqdm  # optional: only a bar needs it
        except ImportError as e:
            raise ImportError("progress=True draws a tqdm bar, but tqdm is not installed: "
                              "pip install 'linkage-manifolds[progress]' (or tqdm), or pass a callable "
                              "progress=f that takes a manifold.progress.ProgressUpdate") from e
        self._tqdm = tqdm.tqdm
        self._kwargs = {"unit": " time", "dynamic_ncols": True, **tqdm_kwargs}
        self._bar: Any = None

    def __call__(self, update: ProgressUpdate) -> None:
        if update.kind in ("compile", "compiled"):
            self._tqdm.write(update.message, file=self._kwargs.get("file"))
            return
        if self._bar is None:
            self._bar = self._tqdm(total=abs(update.t_final), bar_format="{l_bar}{bar}| t = {n:.4g} / {total:.4g} "
                                   "[{elapsed}<{remaining}{postfix}]", **self._kwargs)
        self._bar.update(min(abs(update.t), abs(update.t_final)) - self._bar.n)
        self._bar.set_postfix(steps=update.n_steps, switches=update.n_switches, refresh=False)
        if update.kind == "done":
            self._bar.set_description(update.message, refresh=False)
            self._bar.close()
            self._bar = None


def as_callback(progress: ProgressArgument) -> ProgressCallback | None:
    """The callback a ``progress`` argument stands for (see the module docstring); ``None``: report nothing.

    Raises
    ------
    ValueError
        For a string other than ``"tqdm"`` or an object that is neither a bool nor callable.
    ImportError
        For ``True`` / ``"tqdm"`` without tqdm installed.
    """
    if progress is None:
        return _ACTIVE.get()
    if progress is False:
        return None
    if progress is True or (isinstance(progress, str) and progress == "tqdm"):
        return TqdmProgress()
    if callable(progress):
        return progress
    raise ValueError(f"progress must be None, False, True, 'tqdm' or a callable taking a ProgressUpdate, "
                     f"got {progress!r}")


@contextmanager
def reporting(progress: ProgressArgument = True) -> Iterator[ProgressCallback | None]:
    """Within the block, solves with ``progress=None`` and every compile report to ``progress``.

    Yields the callback (``None`` if nothing is reported).  Example::

        with reporting(True):          # a tqdm bar, and a line per compile
            atlas.best_chart(p)
    """
    token = _ACTIVE.set(as_callback(progress))
    try:
        yield _ACTIVE.get()
    finally:
        _ACTIVE.reset(token)


class SolveProgress:
    """The reports of one solve to ``callback``: segment ends, throttled steps, the end.

    Parameters
    ----------
    callback
        Receives the :class:`ProgressUpdate` s.
    solution
        The solution being built (anything with ``t_span``, ``n_steps`` and
        ``n_switches``, such as :class:`~manifold.solution.GeodesicSolution`):
        the counts are read from it when a report is sent.
    """

    def __init__(self, callback: ProgressCallback, solution: Any) -> None:
        self.callback, self.solution = callback, solution
        self.t_final = float(solution.t_span[1])
        self._steps = 0  # steps of the segment in progress (not yet in the solution)
        self._last = time.perf_counter()

    def _send(self, kind: str, message: str, t: Any, extra_steps: int = 0) -> None:
        sol = self.solution
        self.callback(ProgressUpdate(kind, message, float(t), self.t_final, sol.n_steps + extra_steps, sol.n_switches))

    def segment(self, t: Any, message: str) -> None:
        """A segment ended at ``t`` (``message``: where it was integrated)."""
        self._steps, self._last = 0, time.perf_counter()
        self._send("solve", message, t)

    def done(self, t: Any, message: str) -> None:
        """The solve ended at ``t`` (``message``: why)."""
        self._send("done", message, t)

    def step(self, ta: Any) -> bool:
        """heyoka's step callback: count the step, report at most every :data:`STEP_INTERVAL` s; never stop."""
        self._steps += 1
        now = time.perf_counter()
        if now - self._last >= STEP_INTERVAL:
            self._last = now
            self._send("step", "", ta.time, self._steps)
        return True


def step_callback() -> Callable[[Any], bool] | None:
    """The per-step callback of the solve in progress (for heyoka's ``propagate_until(callback=...)``), or ``None``."""
    return _STEP.get()


@contextmanager
def solve_progress(callback: ProgressCallback | None, solution: Any) -> Iterator[SolveProgress | None]:
    """Within the block, compiles report to ``callback`` and Taylor steps call :meth:`SolveProgress.step`.

    Yields the :class:`SolveProgress` of ``solution`` (``None`` if ``callback`` is ``None``).
    """
    progress = None if callback is None else SolveProgress(callback, solution)
    token, step_token = _ACTIVE.set(callback), _STEP.set(None if progress is None else progress.step)
    try:
        yield progress
    finally:
        _STEP.reset(step_token)
        _ACTIVE.reset(token)


def _disk_cache() -> str:
    if hy.llvm_state.get_diskcache_enabled():
        return (f"heyoka keeps its machine code in the disk cache {hy.llvm_state.get_diskcache_path()}, "
                "so the next process skips most of this")
    return "heyoka's disk cache is off: every new process compiles it again"


@contextmanager
def compiling(what: str, machine_code: bool = True) -> Iterator[None]:
    """Report the compile of ``what`` around the block, if a callback is active.

    Parameters
    ----------
    what
        What is compiled, as a noun phrase (``"the Taylor integrator of ..."``).
    machine_code
        True if the block makes LLVM machine code (which heyoka caches on
        disk); false for symbolic work in Python (which is not cached).
    """
    callback = _ACTIVE.get()
    if callback is None:
        yield
        return
    callback(ProgressUpdate("compile", f"compiling {what}" + (f" ({_disk_cache()})" if machine_code else "")))
    t0 = time.perf_counter()
    yield
    seconds = time.perf_counter() - t0
    callback(ProgressUpdate("compiled", f"compiled {what} in {seconds:.1f} s", seconds=seconds))
