"""Worker tasks for the round-two hardening tests (top level, so the spawned workers import them by name)."""

from __future__ import annotations

import os
import signal
import time
from typing import Any


def spin(seconds: float) -> int:
    """Burn CPU in pure Python for ``seconds`` (bytecode runs, so a budget's timer can stop it)."""
    end = time.monotonic() + seconds
    n = 0
    while time.monotonic() < end:
        n += 1
    return n


def stuck_in_c(seconds: float) -> None:
    """Sit in one C call with SIGALRM blocked: only ending the process stops it."""
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGALRM})
    time.sleep(seconds)


def pid() -> int:
    """The worker's process id."""
    return os.getpid()


def slow_job(show_text: str, options: dict, job_id: str, queue: Any, cancel: Any) -> dict:
    """A long job (20 s) that reports progress, so that a cancel stops it."""
    from app.tasks import Progress

    progress = Progress(job_id, queue, cancel)
    progress.started()
    for i in range(200):
        time.sleep(0.1)
        progress(i / 200)
    return {"done": True}


def hog(gigabytes: float) -> int:
    """Allocate and touch ``gigabytes`` of memory."""
    import numpy as np

    return int(np.ones(int(gigabytes * (1 << 30)) // 8).sum())
