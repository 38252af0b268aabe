"""The ``sim`` packages' warnings as ``swarmshow: ...`` lines on stderr, the one implementation the command
line (``app.cli._common.show_library_notes``) and the Dask workers (``sim.flight._dask.worker_notes``) share.

The only such warning today is the flight kernel's cold-cache compile note
(``sim.flight.engines._numba.COMPILE_NOTE``): without a handler it reached stderr through logging's last-resort
handler as a bare sentence, unlike every other line swarmshow prints.
"""

from __future__ import annotations

import logging
import sys


class NoteHandler(logging.Handler):
    """Prints a log record as one ``swarmshow: ...`` line on the *current* ``sys.stderr`` (not the one at
    construction: a redirected or captured stderr gets it)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            print(f"swarmshow: {record.getMessage()}", file=sys.stderr, flush=True)
        except Exception:  # logging's contract: a failing handler must not raise
            self.handleError(record)


def say_notes(*, unless_heard: bool = False) -> None:
    """Print the ``sim`` packages' warnings as ``swarmshow: ...`` lines on stderr (idempotent: one handler, so
    one line per warning, whichever of the command line and a worker in its process asked first).

    Args:
        unless_heard: add nothing where a handler already hears the ``sim`` logger, its own or an ancestor's
            (a Dask worker whose logging was configured). The command line passes False: it wants the line
            even where the root logger has a handler of its own.
    """
    logger = logging.getLogger("sim")
    if any(isinstance(h, NoteHandler) for h in logger.handlers):
        return
    if unless_heard and logger.hasHandlers():
        return
    logger.addHandler(NoteHandler(logging.WARNING))


__all__ = ["NoteHandler", "say_notes"]
