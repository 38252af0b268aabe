"""A command piped into a reader that stops early (``swarmshow schema | head -1``) exits quietly: no
"cannot write to stdout: Broken pipe" on stderr and no traceback, exit 0 or 141 (128 + SIGPIPE, the shell's
convention), the same for every subcommand (the handler is one, in ``app.cli.main``).

Failed before: stderr said ``swarmshow: error: cannot write to stdout: Broken pipe`` and the exit was 2.
A stdout closed outright (``>&-``) or full is still an error (tests/test_cli_qa3.py and friends).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run_into_closed_pipe(args: list[str]) -> subprocess.CompletedProcess:
    """Run ``swarmshow args`` with stdout a pipe whose only reader is closed before the command writes."""
    read_fd, write_fd = os.pipe()
    os.close(read_fd)  # no reader left: the first write (or flush) fails with EPIPE, deterministically
    try:
        proc = subprocess.run([sys.executable, "-c", "from app.cli import main; main()", *args], cwd=ROOT,
                              stdout=write_fd, stderr=subprocess.PIPE, timeout=120,
                              env={**os.environ, "PYTHONPATH": str(ROOT)})
    finally:
        os.close(write_fd)
    return proc


@pytest.mark.parametrize("args", [["schema"], ["--help"], ["validate", "formations/data/demo_show.json"]])
def test_reader_gone_is_quiet(args):
    proc = _run_into_closed_pipe(args)
    assert proc.returncode in (0, 141), (proc.returncode, proc.stderr)
    assert proc.stderr == b"", proc.stderr.decode()


def test_head_reads_one_line_of_schema():
    """The real pipe: ``head -1`` reads a line then goes; the schema (longer than a pipe's buffer or not)
    still ends quietly."""
    swarmshow = subprocess.Popen([sys.executable, "-c", "from app.cli import main; main()", "schema"], cwd=ROOT,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert swarmshow.stdout is not None
    first = swarmshow.stdout.readline()
    swarmshow.stdout.close()
    _, err = swarmshow.communicate(timeout=120)
    assert first.strip(), first
    assert swarmshow.returncode in (0, 141), (swarmshow.returncode, err)
    assert err == b"", err.decode()
