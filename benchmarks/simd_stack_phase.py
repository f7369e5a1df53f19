"""heyoka's SIMD batch code against the calling thread's stack alignment: ``python -m benchmarks.simd_stack_phase``.

heyoka's unrolled batch integrators keep their Taylor coefficients on the stack of the thread that calls them.
This measures how the speed of one batch solve depends on where that stack stands: the hinge method's
Baumgarte-stabilised equations (as ``free_motions`` integrates them), ``COUNT`` generic starts to T = ``--T``
(``benchmarks.taylor_options.hinge_problem``), batch after batch (``propagate_grid`` from 0 to T, as
``free_motions`` calls it), for each lane count of ``--lanes`` (unrolled code, the default to n = 12 in
float64) and 8 lanes of compact code, with the stack pointer at each of its four 16-byte positions
modulo 64 (the phase).

The phase is moved by calling the loop through 0-3 nested C-level calls (a ``map``), each of which moves the stack
pointer by one frame of the interpreter's C loop (16 bytes modulo 64 on CPython 3.11 for x86-64, so the four levels
reach the four phases), and read with glibc's ``getcontext`` (x86-64 Linux only) in the frame that calls heyoka.
Each row: the CPU time of the whole loop of batches at each phase reached (the fastest of ``--rounds``, levels in
turn, after one untimed pass), the slowest over the fastest, and whether the end states at every phase are equal
bit for bit (the arithmetic is the same wherever its values sit).  Run in the main thread (whose stack the kernel
places at random, so its phase differs from process to process) and in a worker thread (whose phase the code path
sets, the same every time); ``unplaced at``: the phase without nesting.
"""

from __future__ import annotations

import argparse
import ctypes
import platform
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import heyoka as hy
import numpy as np

from .taylor_options import hinge_problem

#: The cache line: a 64-byte (8-lane) vector straddles two unless aligned to it.
ALIGNMENT = 64
#: The x86-64 ABI keeps the stack pointer a multiple of 16 at every call.
STEP = 16
#: The starts of each solve.
COUNT = 64
#: glibc's ``ucontext_t`` on x86-64: ``uc_flags``, ``uc_link`` and ``uc_stack`` (40 bytes), then the general
#: registers, ``RSP`` the 16th (``REG_RSP = 15``).
RSP_OFFSET = 40 + 8 * 15


def getcontext() -> Any:
    """glibc's ``getcontext`` through ctypes, or ``None`` where this is not x86-64 Linux with glibc."""
    if platform.system() != "Linux" or platform.machine() != "x86_64" or platform.libc_ver()[0] != "glibc":
        return None
    function = ctypes.CDLL(None).getcontext
    function.argtypes, function.restype = [ctypes.c_char_p], ctypes.c_int
    return function


GETCONTEXT = getcontext()


def stack_pointer(context: Any) -> int:
    """The stack pointer inside a ``getcontext`` call made from the caller's frame, read into ``context`` (a ctypes
    buffer of at least 968 bytes, glibc's ``ucontext_t`` on x86-64): a fixed distance from every other C call that
    frame makes (heyoka's included)."""
    if GETCONTEXT(context) != 0:
        raise OSError("getcontext failed")
    return int.from_bytes(context.raw[RSP_OFFSET : RSP_OFFSET + 8], "little")


def read_phase(context: Any) -> int:
    """:func:`stack_pointer` modulo 64: the phase that decides the speed of 64-byte vectors kept on the stack."""
    return stack_pointer(context) % ALIGNMENT


def nested(levels: int, fn: Callable[[], Any]) -> Any:
    """``fn()`` called under ``levels`` nested C-level calls: each (a ``map`` calling back into Python) adds a frame
    of the interpreter's C loop, the same size at every level, and moves the stack pointer by it."""
    if levels == 0:
        return fn()
    return next(map(lambda _: nested(levels - 1, fn), (None,)))


def batches(problem: tuple, lanes: int, compact: bool, T: float) -> Callable[[], tuple[int, list]]:
    """The loop of batch solves of ``problem`` (:func:`~benchmarks.taylor_options.hinge_problem`'s equations, starts
    and parameters) to ``T``, returning the stack's phase where it calls heyoka and the end states."""
    equations, Y, P, _ = problem
    ta = hy.taylor_adaptive_batch(equations, np.zeros((Y.shape[1], lanes)), compact_mode=compact)
    npars = len(ta.pars)
    grid = np.ascontiguousarray(np.repeat(np.array([0.0, T])[:, None], lanes, axis=1))

    context = ctypes.create_string_buffer(4096)  # more than glibc's ucontext_t (968 bytes on x86-64)

    def run() -> tuple[int, list]:
        phase = read_phase(context)  # in the frame that calls heyoka below
        ends = []
        for i in range(0, COUNT, lanes):
            ta.set_time(0.0)
            ta.state[:], ta.pars[:] = Y[i : i + lanes].T, P[i : i + lanes, :npars].T
            ta.propagate_grid(grid)
            ends.append(np.array(ta.state))
        return phase, ends

    return run


def scalar_loop(problem: tuple, T: float, rounds: int) -> float:
    """CPU seconds of heyoka's scalar integrator of ``problem``'s equations over its starts, one after the other
    (the fastest of ``rounds``): what a batch's speed-up is counted against."""
    equations, Y, P, compact = problem
    ta = hy.taylor_adaptive(equations, Y[0], compact_mode=compact)
    npars, best = len(ta.pars), np.inf
    for _ in range(rounds):
        c0 = time.thread_time()
        for y, p in zip(Y, P):
            ta.time, ta.state[:], ta.pars[:] = 0.0, y, p[:npars]
            ta.propagate_until(T)
        best = min(best, time.thread_time() - c0)
    return float(best)


def scan(run: Callable[[], tuple[int, list]], rounds: int) -> dict:
    """CPU time of ``run`` (this thread's) under 0-3 nested levels, the phase each ran at, whether all ends agree,
    and whether the levels reached four phases, each the same in every round (``phases ok``): the step of a level
    is the interpreter's C frame, 16 bytes modulo 64 on CPython 3.11 for x86-64 once its calls are specialised,
    but another build may move the stack by another amount."""
    levels = range(ALIGNMENT // STEP)
    for level in levels:  # one untimed pass: the interpreter specialises its calls on the first runs
        nested(level, run)
    best = {level: np.inf for level in levels}
    seen: dict[int, set[int]] = {level: set() for level in levels}
    ends: dict[int, list] = {}
    for _ in range(rounds):
        for level in levels:
            c0 = time.thread_time()
            reached, ends[level] = nested(level, run)
            best[level] = min(best[level], time.thread_time() - c0)
            seen[level].add(reached)
    same = all(all(np.array_equal(a, b) for a, b in zip(ends[0], e)) for e in ends.values())
    phase = {level: min(phases) for level, phases in seen.items()}
    ok = all(len(phases) == 1 for phases in seen.values()) and len(set(phase.values())) == len(levels)
    return {"best": best, "phase": phase, "same": same, "phases ok": ok}


def show(label: str, where: str, out: dict) -> None:
    """One printed row of :func:`scan`'s results: the time at each phase, the spread, and the checks."""
    if not out["phases ok"]:
        print(f"  {label:28s} {where:13s} the levels did not reach four phases, each the same every round: this "
              "interpreter moves the stack by another step; the row would mislabel the phases", flush=True)
        return
    cells = "  ".join(f"{out['phase'][k]:>2}: {1e3 * t:7.2f}" for k, t in sorted(out["best"].items(),
                                                                                    key=lambda kt: out["phase"][kt[0]]))
    times = list(out["best"].values())
    print(f"  {label:28s} {where:13s} {cells}   slowest / fastest {max(times) / min(times):4.2f}   unplaced at "
          f"{out['phase'][0]:>2}   ends equal: {out['same']}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[4, 8])
    parser.add_argument("--lanes", type=int, nargs="+", default=None,
                        help="lane counts of unrolled code (default: the SIMD width, 8 and 16)")
    parser.add_argument("--T", type=float, default=20.0)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    if GETCONTEXT is None:
        sys.exit("this measurement reads the stack pointer with glibc's getcontext: x86-64 Linux only")
    width = hy.recommended_simd_size()
    lanes = args.lanes or sorted({width, 8, 16})
    print(f"heyoka {hy.__version__}, SIMD width {width}; {COUNT} starts to T = {args.T:g}; CPU time (ms) of the "
          f"thread at each stack phase (mod {ALIGNMENT}), fastest of {args.rounds}")
    for n in args.n:
        problem = hinge_problem(n, COUNT, args.T)  # built once: every row integrates the same starts
        default = problem[3]  # the hinge method's compile mode (compact or not) at this n
        print(f"  n = {n}: heyoka's scalar loop over the same starts "
              f"{1e3 * scalar_loop(problem, args.T, args.rounds):.2f} ms")
        for lane_count, compact in [*((k, default) for k in lanes), (8, True)]:
            run = batches(problem, lane_count, compact, args.T)
            label = f"n = {n}, {lane_count} lanes, {'compact' if compact else 'unrolled'}"
            show(label, "main thread", scan(run, args.rounds))
            found: dict = {}
            worker = threading.Thread(target=lambda: found.update(scan(run, args.rounds)))
            worker.start()
            worker.join()
            show(label, "worker thread", found)


if __name__ == "__main__":
    main()
