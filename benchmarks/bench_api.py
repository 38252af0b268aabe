"""REST API under load: 50 concurrent loopback clients reading and updating shows for 20 s.

``make bench`` or ``pytest -m slow benchmarks/bench_api.py``. A real ``swarmshow serve``
process on a free 127.0.0.1 port; each client (its own connection) loops: 80 % ``GET`` of a
random show, 20 % revision-checked ``PUT`` of it. A 409 (another client updated that show
first) is the store doing its job and is counted apart from errors (transport failures,
5xx, anything unexpected). Reports p50/p99 latency per operation, throughput and errors.
``SWARMSHOW_BENCH_S`` and ``SWARMSHOW_BENCH_CLIENTS`` override the duration and client count.
"""

from __future__ import annotations

import asyncio
import json
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import numpy as np
import pytest

pytestmark = pytest.mark.slow

DURATION_S = float(os.environ.get("SWARMSHOW_BENCH_S", "20"))
CLIENTS = int(os.environ.get("SWARMSHOW_BENCH_CLIENTS", "50"))
SHOWS = 20
WRITE_SHARE = 0.2


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _show_doc() -> dict:
    try:
        from formations import dump_show
        from formations._demo import load_demo_show

        return json.loads(dump_show(load_demo_show()))
    except ImportError:  # the bundled demo is optional here: a small show measures the same path
        return {
            "format": "swarmshow/1", "name": "bench", "drones": 4,
            "home": {"grid": {"rows": 2, "cols": 2, "spacing_m": 4.5}},
            "formations": [{"name": "square", "hold_s": 5.0,
                            "points": [[0, 0, 20], [5, 0, 20], [0, 0, 25], [5, 0, 25]], "color": "#ff0000"}],
        }


async def _client(base: str, ids: list[str], doc: dict, stop_at: float, rng: random.Random, out: dict) -> None:
    async with httpx.AsyncClient(base_url=base, timeout=30.0, limits=httpx.Limits(max_connections=1)) as http:
        while time.monotonic() < stop_at:
            sid = rng.choice(ids)
            write = rng.random() < WRITE_SHARE
            t0 = time.perf_counter()
            try:
                if write:
                    rev = (await http.get(f"/api/shows/{sid}")).json()["revision"]
                    body = {"revision": rev, "show": {**doc, "name": f"bench {rng.randrange(10**9)}"}}
                    t0 = time.perf_counter()  # time the update itself
                    r = await http.put(f"/api/shows/{sid}", json=body)
                    ok = r.status_code in (200, 409)
                    out["conflicts"] += r.status_code == 409
                else:
                    r = await http.get(f"/api/shows/{sid}")
                    ok = r.status_code == 200
            except httpx.HTTPError:
                ok = False
            (out["write_s"] if write else out["read_s"]).append(time.perf_counter() - t0)
            out["errors"] += not ok


def _pct(values: list[float], q: float) -> float | None:
    return round(float(np.percentile(values, q)) * 1000, 2) if values else None


def test_bench_api_50_clients_read_update(tmp_path, record_result) -> None:
    port = _free_port()
    exe = shutil.which("swarmshow", path=str(Path(sys.executable).parent))
    cmd = [exe] if exe else [sys.executable, "-c", "import sys; from app.cli import main; sys.exit(main())"]
    proc = subprocess.Popen([*cmd, "serve", "--port", str(port), "--data-dir", str(tmp_path), "--workers", "1"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                if httpx.get(f"{base}/api/health", timeout=1).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            assert proc.poll() is None and time.monotonic() < deadline, "server did not start"
            time.sleep(0.2)
        doc = _show_doc()
        ids = [httpx.post(f"{base}/api/shows", json={**doc, "name": f"bench {k}"}, timeout=30).json()["id"]
               for k in range(SHOWS)]
        out = {"read_s": [], "write_s": [], "errors": 0, "conflicts": 0}

        async def run() -> None:
            stop_at = time.monotonic() + DURATION_S
            await asyncio.gather(*(_client(base, ids, doc, stop_at, random.Random(k), out) for k in range(CLIENTS)))

        t0 = time.monotonic()
        asyncio.run(run())
        wall = time.monotonic() - t0
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
    every = out["read_s"] + out["write_s"]
    figures = {
        "clients": CLIENTS,
        "duration_s": round(wall, 2),
        "show_bytes": len(json.dumps(doc)),
        "requests": len(every),
        "requests_per_s": round(len(every) / wall, 1),
        "reads": len(out["read_s"]),
        "updates": len(out["write_s"]),
        "conflicts_409": out["conflicts"],
        "errors": out["errors"],
        "p50_ms": _pct(every, 50),
        "p99_ms": _pct(every, 99),
        "read_p50_ms": _pct(out["read_s"], 50),
        "read_p99_ms": _pct(out["read_s"], 99),
        "update_p50_ms": _pct(out["write_s"], 50),
        "update_p99_ms": _pct(out["write_s"], 99),
    }
    record_result(figures)
    assert out["errors"] == 0
    assert len(every) > 0
