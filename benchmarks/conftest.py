"""Benchmark fixtures: every benchmark prints one JSON line and records it in ``benchmarks/results.json``."""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path
from typing import Any

import pytest

RESULTS = Path(__file__).with_name("results.json")


@pytest.fixture
def record_result(request):
    """``record_result(dict)``: print the figures as JSON and merge them into results.json under the test's name."""

    def record(figures: dict[str, Any]) -> None:
        print(json.dumps(figures))
        data = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
        data[request.node.name] = {
            "measured_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
            **figures,
        }
        # Write-then-rename so an interrupted run never leaves a truncated file.
        tmp = RESULTS.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
        tmp.replace(RESULTS)

    return record
