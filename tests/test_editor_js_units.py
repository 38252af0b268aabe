"""The editor's geometry and spacing modules under ``node --test`` (tests/js/*.test.mjs).

The JavaScript copies of the geometry (resampling, fit to a count, scale/rotate) and of the
spacing checks run in the browser for instant feedback; these tests hold them to brute
force and closed forms like their Python counterparts.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

JS_TESTS = sorted((Path(__file__).parent / "js").glob("*.test.mjs"))
NODE = shutil.which("node")


@pytest.mark.skipif(NODE is None, reason="node is not installed")
@pytest.mark.parametrize("path", JS_TESTS, ids=lambda p: p.name)
def test_node_unit_tests(path: Path) -> None:
    proc = subprocess.run([NODE, "--test", str(path)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert "# fail 0" in proc.stdout and "# pass 0" not in proc.stdout
