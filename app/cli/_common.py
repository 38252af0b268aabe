"""Helpers shared by the command modules: errors, show loading, JSON output, progress."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2


class CliError(Exception):
    """A one-line reason shown on stderr; ``exit_code`` is 2 (bad input) unless given."""

    def __init__(self, message: str, *, exit_code: int = EXIT_USAGE) -> None:
        super().__init__(message)
        self.exit_code = exit_code


def load_show_arg(path: str):  # -> formations.ShowFile (import kept lazy for start-up time)
    """Read and validate a show file; bad input becomes a ``CliError`` (exit 2)."""
    from formations import ShowValidationError, load_show

    try:
        return load_show(Path(path))
    except FileNotFoundError as exc:
        raise CliError(f"{path}: no such file") from exc
    except IsADirectoryError as exc:
        raise CliError(f"{path}: is a directory") from exc
    except ShowValidationError as exc:
        raise CliError(f"{path}: {exc.one_line()}") from exc


def print_json(obj: Any) -> None:
    """Print one JSON object on stdout (numpy scalars and arrays are converted)."""
    print(json.dumps(obj, default=_json_default, allow_nan=False))


def _json_default(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


@contextmanager
def progress_bar(desc: str, *, enabled: bool = True) -> Iterator[Callable[[float], None]]:
    """Yield ``update(fraction)`` drawing a tqdm bar on stderr (hidden when not a TTY or disabled).

    The callback signature matches the ``progress`` arguments of the planning
    and simulation functions: a float in [0, 1].
    """
    from tqdm import tqdm

    bar = tqdm(
        total=1000,
        desc=desc,
        file=sys.stderr,
        disable=not enabled or not sys.stderr.isatty(),
        bar_format="{desc}: {percentage:3.0f}%|{bar}| {elapsed}<{remaining}",
        leave=False,
    )
    last = [0]

    def update(fraction: float) -> None:
        target = int(round(min(max(fraction, 0.0), 1.0) * 1000))
        if target > last[0]:
            bar.update(target - last[0])
            last[0] = target

    try:
        yield update
    finally:
        bar.close()
