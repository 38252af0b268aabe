"""One process-wide thread pool for the planner's independent searches (k-d trees and nogil kernels).

The searches it runs release the GIL (scipy's k-d tree queries, numba kernels compiled ``nogil``), so
the threads use every core; callers combine the results in a fixed order, so plans do not depend on
which thread finishes first.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache

#: Most worker threads (the planner's searches come in small batches).
MAX_WORKERS = 4


def workers() -> int:
    """Threads of :func:`pool`: the cores of this machine, at most :data:`MAX_WORKERS`."""
    return max(1, min(MAX_WORKERS, os.cpu_count() or 1))


@lru_cache(maxsize=1)
def pool() -> ThreadPoolExecutor:
    """The shared pool (created on first use, lives as long as the process)."""
    return ThreadPoolExecutor(max_workers=workers(), thread_name_prefix="swarmshow-plan")
