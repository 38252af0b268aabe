"""Shared benchmark builders: the three-layer knot-planned show (exports, lights) and a real
``swarmshow serve`` process on a free loopback port (API load, fairness)."""

from __future__ import annotations

import math
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from formations import parse_show
from sim import Segment, ShowPlan, min_transition_duration
from sim.bench._shows import BENCH_SPACING_M
from tests.live_server import free_port

#: Points per formation of the layered show (a benchmark of fewer drones takes the first ones).
LAYER_POINTS = 5000


def layers(z0_m: float, angle_rad: float, shift_m: tuple[float, float], count: int = LAYER_POINTS) -> np.ndarray:
    """(count, 3) points in two horizontal grids 6 m apart, spaced BENCH_SPACING_M, rotated about z
    by ``angle_rad`` and shifted by ``shift_m``, the lower at ``z0_m``."""
    per = count // 2
    side = math.ceil(math.sqrt(per))
    i, j = np.divmod(np.arange(per), side)
    xy = np.c_[(j - (side - 1) / 2) * BENCH_SPACING_M, (i - (side - 1) / 2) * BENCH_SPACING_M]
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    xy = xy @ np.array([[c, -s], [s, c]]).T + np.asarray(shift_m)
    out: np.ndarray = np.r_[np.c_[xy, np.full(per, z0_m)], np.c_[xy, np.full(per, z0_m + 6.0)]]
    return out


def knot_show(drones: int, duration_s: float, *, name: str,
              effects: Sequence[Mapping[str, Any]] | None = None) -> tuple[Any, ShowPlan]:
    """A ``drones``-drone show (takeoff, three layered formations "layers", "turned", "shifted",
    landing) lasting about ``duration_s`` (the three holds stretched to it), with ``effects`` as its
    light effects, and a plan built straight from its knots: each drone flies to the point with its
    own index, which has the shape and size of a real plan (CAPT is benchmarked in bench_plan.py).

    Returns:
        (the parsed show, its plan).
    """
    formations = [
        ("layers", layers(30.0, 0.0, (0.0, 0.0))[:drones], (1.0, 0.0, 0.0)),
        ("turned", layers(40.0, 0.5, (20.0, 10.0))[:drones], (0.0, 1.0, 0.0)),
        ("shifted", layers(25.0, 1.0, (-20.0, 0.0))[:drones], (0.0, 0.0, 1.0)),
    ]
    side = math.ceil(math.sqrt(drones))

    def build(hold_s: float) -> tuple[Any, ShowPlan]:
        doc: dict[str, Any] = {
            "format": "swarmshow/1", "name": name, "drones": drones,
            "home": {"grid": {"rows": side, "cols": side, "spacing_m": BENCH_SPACING_M}},
            "formations": [{"name": n, "hold_s": hold_s, "points": np.round(p, 6).tolist(), "color": "#ffffff"}
                           for n, p, _ in formations],
        }
        if effects is not None:
            doc["lights"] = {"effects": list(effects)}
        show = parse_show(doc)
        s = show.settings
        limits = {"max_speed_xy_mps": s.max_speed_xy_mps, "max_speed_z_mps": s.max_speed_z_mps,
                  "max_accel_mps2": s.max_accel_mps2}
        home = np.asarray(show.home_positions_m)
        lift = np.array([0.0, 0.0, s.takeoff_altitude_m])
        black = np.zeros((drones, 3))
        knots: list[tuple[np.ndarray, np.ndarray, str | None, str]] = [
            (home, black, None, "start"), (home + lift, black, "takeoff", "takeoff")]
        for label, pts, rgb in formations:
            col = np.broadcast_to(np.asarray(rgb, dtype=float), (drones, 3))
            knots += [(pts, col, "transition", label), (pts, col, "hold", label)]
        knots += [(home + lift, black, "transition", "landing"), (home, black, "landing", "landing")]
        times, segments = [0.0], []
        for k in range(1, len(knots)):
            pos, _, kind, label = knots[k]
            dur = hold_s if kind == "hold" else min_transition_duration(knots[k - 1][0], pos, **limits)
            segments.append(Segment(k - 1, kind, label, times[-1], float(dur)))
            times.append(times[-1] + float(dur))
        plan = ShowPlan(
            knot_times_s=np.array(times), knot_positions_m=np.stack([k[0] for k in knots]),
            knot_colors_rgb=np.stack([np.asarray(k[1], dtype=float) for k in knots]),
            segments=tuple(segments), transitions=(), settings=s, show_name=show.name,
        )
        return show, plan

    _, plan = build(10.0)
    return build(10.0 + max(0.0, (duration_s - plan.duration_s) / 3))


@contextmanager
def serve(data_dir: Path, env: Mapping[str, str] | None = None, *, start_timeout_s: float = 60.0) -> Iterator[str]:
    """A real ``swarmshow serve`` (one simulation worker) on a free 127.0.0.1 port, with ``env`` added
    to the environment; yields its base URL once /api/health answers, stops it (SIGINT, then kill)."""
    port = free_port()
    exe = shutil.which("swarmshow", path=str(Path(sys.executable).parent))
    cmd = [exe] if exe else [sys.executable, "-c", "import sys; from app.cli import main; sys.exit(main())"]
    proc = subprocess.Popen([*cmd, "serve", "--port", str(port), "--data-dir", str(data_dir), "--workers", "1"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env={**os.environ, "PYTHONUNBUFFERED": "1", **(env or {})})
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + start_timeout_s
        while True:
            try:
                if httpx.get(f"{base}/api/health", timeout=1).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            assert proc.poll() is None and time.monotonic() < deadline, "server did not start"
            time.sleep(0.2)
        yield base
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
