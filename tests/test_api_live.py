"""``swarmshow serve`` as a real process on a free loopback port, driven over HTTP; ``swarmshow demo`` seeding."""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from app.cli import build_parser
from app.cli._serve import seed_demo
from app.store import ShowStore
from tests.live_server import free_port, swarmshow_command

SHOW = {
    "format": "swarmshow/1", "name": "live", "drones": 4,
    "home": {"grid": {"rows": 2, "cols": 2, "spacing_m": 4.5}},
    "settings": {"max_speed_z_mps": 5.0, "max_accel_mps2": 8.0, "takeoff_altitude_m": 3.0},
    "formations": [{"name": "square", "hold_s": 2.0, "points": [[0, 0, 6], [5, 0, 6], [0, 0, 11], [5, 0, 11]],
                    "colors": ["#ff0000", "#00ff00", "#0000ff", "#ffffff"]}],
}


@pytest.fixture
def server(tmp_path):
    port = free_port()
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [*swarmshow_command(), "serve", "--host", "127.0.0.1", "--port", str(port), "--data-dir", str(tmp_path),
         "--workers", "1"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env, text=True,
    )
    base = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 60
    while True:
        try:
            if httpx.get(f"{base}/api/health", timeout=1).status_code == 200:
                break
        except httpx.TransportError:
            pass
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"server did not start: {proc.communicate()[0]}")
        time.sleep(0.2)
    try:
        yield base, proc, tmp_path
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


ROOT = Path(__file__).resolve().parent.parent


def dockerfile_healthcheck() -> str:
    """The Python code of the Dockerfile's HEALTHCHECK (run here exactly as Docker would)."""
    text = (ROOT / "Dockerfile").read_text()
    return re.search(r'HEALTHCHECK[^\n]*\\\n\s*CMD python -c "([^"]+)"', text).group(1)


def run_healthcheck(port: int) -> int:
    env = {**os.environ, "SWARMSHOW_PORT": str(port)}
    return subprocess.run([sys.executable, "-c", dockerfile_healthcheck()], env=env, capture_output=True,
                          timeout=30).returncode


def test_dockerfile_command_line_is_the_cli():
    text = (ROOT / "Dockerfile").read_text()
    cmd = json.loads(re.search(r"^CMD (\[.*\])$", text, re.M).group(1))
    assert cmd[:2] == ["swarmshow", "serve"]
    args = build_parser().parse_args(cmd[1:])
    assert args.host == "0.0.0.0" and args.func is not None
    assert "SWARMSHOW_DATA_DIR=/data" in text and "USER swarmshow" in text


def test_live_server_create_check_simulate_export_stop(server):
    base, proc, data_dir = server
    port = int(base.rsplit(":", 1)[1])
    assert run_healthcheck(port) == 0
    with httpx.Client(base_url=base, timeout=60) as http:
        rec = http.post("/api/shows", json=SHOW)
        assert rec.status_code == 201, rec.text
        sid = rec.json()["id"]
        check = http.post(f"/api/shows/{sid}/check")
        assert check.status_code == 200 and check.json()["report"]["ok"] is True

        job = http.post(f"/api/shows/{sid}/simulate", json={"engine": "numba"})
        assert job.status_code == 202
        events = []
        with http.stream("GET", f"/api/jobs/{job.json()['id']}/events") as stream:
            name = None
            for line in stream.iter_lines():
                if line.startswith("event: "):
                    name = line[7:]
                elif line.startswith("data: "):
                    events.append((name, json.loads(line[6:])))
        assert events[-1][0] == "done", events[-1]
        assert any(e == "progress" and 0 < d["progress"] < 1 for e, d in events)
        assert events[-1][1]["result"]["flight"]["drones"] == 4

        export = http.get(f"/api/shows/{sid}/export/show")
        assert export.status_code == 200 and export.json()["name"] == "live"
        assert "attachment" in export.headers["content-disposition"]
        assert http.get("/").status_code == 200

    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, out
    assert run_healthcheck(port) != 0  # and the HEALTHCHECK notices the server is gone
    assert f"{base}/" in out  # the URL was printed
    # The show survived the restart-free stop: it is in the store on disk.
    store = ShowStore(data_dir / "swarmshow.sqlite3")
    try:
        assert store.get(sid).name == "live"
    finally:
        store.close()


def test_serve_refuses_a_busy_port(tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        r = subprocess.run([*swarmshow_command(), "serve", "--port", str(port), "--data-dir", str(tmp_path)],
                           capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "already in use" in r.stderr


def test_demo_seeds_the_store_once(tmp_path):
    first, added = seed_demo(tmp_path)
    again, added_again = seed_demo(tmp_path)
    assert added and not added_again and first == again
    store = ShowStore(tmp_path / "swarmshow.sqlite3")
    try:
        assert store.list()[1] == 1 and store.get(first).drones == 100
    finally:
        store.close()
