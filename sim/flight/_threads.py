"""Plain threads for the error models' per-chunk tables: compiled ``nogil`` loops on every core.

The wind tables' mode sum (:mod:`sim.flight._windsum`) and the GNSS tables
(:mod:`sim.flight.engines._tables`) run between two calls of the flight kernel, on one
thread they were ~30 % of a 1-s, 4,000-drone flight's wall time (issue 20). Both are
compiled ``nogil`` loops or numpy ufuncs, which release the GIL, so ordinary Python threads
run them in parallel without numba's parallel machinery: a ``prange`` over the same blocks
measured 3.5x slower (its parfor body was not vectorised) and its parallel region cost
~50 ms to start on the loaded machine (:mod:`sim.flight._windsum`).

:func:`share_blocks` hands out blocks from a shared counter (each thread takes the next
block when it is done with one), so a thread that the shared machine's other jobs hold back
does fewer blocks instead of making the others wait; :class:`Beside` runs one task on its own
thread while the caller does something else. Each block's and task's arithmetic is the same
whichever thread does it, so the results are the same bits for any thread count. A fresh
thread per call (~0.1 ms) rather than a pool: a pool's threads do not survive a ``fork``
(Dask's worker processes), and the tables' work is ~10-50 ms per chunk.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable
from typing import Generic, TypeVar

import numba

__all__ = ["Beside", "share_blocks", "table_threads"]

T = TypeVar("T")


def table_threads() -> int:
    """Threads for the tables: numba's thread count (``NUMBA_NUM_THREADS``; Dask's workers pin it to 1)."""
    return max(1, int(numba.get_num_threads()))


class Beside(Generic[T]):
    """``fn()`` on a thread of its own, started at once; :meth:`result` waits and re-raises its exception.

    Args:
        fn: The task (its work should release the GIL, or it only interleaves with the caller).
    """

    def __init__(self, fn: Callable[[], T]) -> None:
        self._fn = fn
        self._value: T | None = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="swarmshow-tables", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            self._value = self._fn()
        except BaseException as exc:  # re-raised in the caller's thread by result()
            self._error = exc

    def result(self) -> T:
        """Wait for the task; its return value, or its exception raised here."""
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._value  # type: ignore[return-value]


def share_blocks(blocks: int, work: Callable[[int], None], *, threads: int) -> None:
    """Call ``work(b)`` for every ``b`` in ``0 .. blocks - 1``, on ``threads`` threads (the caller's included).

    Blocks are taken in order from a shared counter (``next`` on an ``itertools.count`` is
    atomic under the GIL). The first exception stops the other threads after their current
    block and is raised here.
    """
    counter = itertools.count()
    failed: list[BaseException] = []

    def run() -> None:
        try:
            while not failed:
                b = next(counter)
                if b >= blocks:
                    return
                work(b)
        except BaseException as exc:
            failed.append(exc)

    helpers = [Beside(run) for _ in range(max(1, min(threads, blocks)) - 1)]
    run()
    for h in helpers:
        h.result()
    if failed:
        raise failed[0]
