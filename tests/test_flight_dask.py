"""The Dask engine: a LocalCluster on loopback with 2 worker processes flies shards of drones.

Checks that the merged result equals the local numba engine's (arrays bit for bit, the
flown distance over all drones, divergences), that a worker killed mid-run loses no
drone, that progress rises to 1, that a raising progress callback cancels the run, and
the CLI and server-setting entry points.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import time

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from app.cli import main  # noqa: E402
from sim import plan_show  # noqa: E402
from sim.flight import FlightResult, SchedulerUnreachableError, fly_show  # noqa: E402
from tests.conftest import fibonacci_sphere, make_show, ring  # noqa: E402

ARRAYS = ("times_s", "positions_m", "colors_rgb", "drone_ids", "tracking_rms_m", "tracking_max_m",
          "max_thrust_step_n")


@pytest.fixture(scope="module")
def client():
    """Two single-threaded worker processes on 127.0.0.1 (no dashboard)."""
    with distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1", dashboard_address=None,
    ) as cluster, distributed.Client(cluster, set_as_default=False) as c:
        # Load the numba kernels from the on-disk cache once per worker, outside the timings.
        c.run(_warm)
        yield c


def _warm() -> None:
    from sim.flight.engines import warm_up

    warm_up()


def _assert_same(local: FlightResult, dask: FlightResult) -> None:
    for name in ARRAYS:
        a, b = getattr(local, name), getattr(dask, name)
        assert a.shape == b.shape, name
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12, err_msg=name)
        assert np.array_equal(a, b), name  # the same kernel on the same inputs: bit for bit
    assert dask.flown_min_distance_m == local.flown_min_distance_m
    assert dask.flown_min_distance_pair == local.flown_min_distance_pair
    assert dask.flown_min_distance_time_s == local.flown_min_distance_time_s
    assert dask.diverged == local.diverged
    s_local, s_dask = local.summary(), dask.summary()
    for key in ("engine", "wall_time_s", "drone_steps_per_s"):
        s_local.pop(key), s_dask.pop(key)
    assert s_dask == s_local


def test_dask_equals_local_with_wind_and_progress(client, small_plan):
    local = fly_show(small_plan, disturbance="wind", seed=3, output_hz=10)
    seen: list[float] = []
    dask = fly_show(small_plan, engine="dask", scheduler=client, disturbance="wind", seed=3, output_hz=10,
                    shards=5, progress=seen.append)
    assert dask.engine == "dask" and dask.extra["shards"] == 5 and dask.extra["workers"] == 2
    _assert_same(local, dask)
    assert seen and all(b > a for a, b in zip(seen, seen[1:], strict=False))
    assert 0.0 <= seen[0] < 1.0 and seen[-1] == 1.0
    assert len(seen) >= 5  # at least one report per shard, not just the end


def test_dask_equals_local_on_per_drone_timing(client, staggered_small):
    # Each drone's own pieces travel with the plan (plan.motion, a plain class that Dask
    # ships whole) and each shard flies them with its own piece cursors: bit for bit.
    plan, _ = staggered_small
    local = fly_show(plan, output_hz=10)
    dask = fly_show(plan, engine="dask", scheduler=client, shards=3, output_hz=10)
    _assert_same(local, dask)


def test_dask_merges_divergences_and_distance_over_all_drones(client, small_plan):
    # A runaway limit at the median of the baseline's worst error in the wind stops about
    # half the drones, at different times; the flown distance skips each from then on.
    opts = {"controller": "baseline", "disturbance": "wind", "output_hz": 10}
    worst_m = np.asarray(fly_show(small_plan, **opts).tracking_max_m)
    opts["divergence_limit_m"] = float(np.median(worst_m))
    local = fly_show(small_plan, **opts)
    assert 0 < len(local.diverged) < 16  # the check below must merge real, partial divergences
    dask = fly_show(small_plan, engine="dask", scheduler=client, shards=3, **opts)
    _assert_same(local, dask)


def test_dask_subset_of_drones(client, small_plan):
    subset = np.array([11, 2, 7, 3, 15])
    local = fly_show(small_plan, drones=subset, output_hz=5)
    dask = fly_show(small_plan, engine="dask", scheduler=client, drones=subset, shards=2, output_hz=5)
    _assert_same(local, dask)


def _wide_show(drones: int):
    rows = 6
    return plan_show(make_show(
        [
            {"name": "ring", "hold_s": 20.0, "points": ring(drones, 40.0), "color": "#ff0000"},
            {"name": "sphere", "hold_s": 20.0, "points": fibonacci_sphere(drones, 30.0), "color": "#00ff00"},
        ],
        drones=drones, rows=rows, cols=-(-drones // rows), spacing_m=4.5,
    ))


def _shard_starts(dask_scheduler) -> dict[str, int]:
    """How many times each shard task of any run was sent to a worker (scheduler side)."""
    counts: dict[str, int] = {}
    for key, _start, finish, *_ in dask_scheduler.transition_log:
        if str(key).startswith("swarmshow-shard-") and finish == "processing":
            counts[str(key)] = counts.get(str(key), 0) + 1
    return counts


def test_worker_killed_mid_run_loses_no_drone(client):
    plan = _wide_show(48)
    opts = {"disturbance": "wind", "output_hz": 5}
    before = client.run(os.getpid)
    killed: list[int] = []

    def progress(fraction: float) -> None:
        # Both workers are flying a shard (4 shards, 2 single-thread workers): kill one
        # as soon as the run is under way.
        if not killed and 0.02 < fraction < 0.5:
            pid = sorted(before.values())[0]
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    seen_before = set(client.run_on_scheduler(_shard_starts))
    dask = fly_show(plan, engine="dask", scheduler=client, shards=4, progress=progress, **opts)
    assert killed, "the run finished before a worker could be killed (shards too fast)"
    starts = {k: n for k, n in client.run_on_scheduler(_shard_starts).items() if k not in seen_before}
    assert len(starts) == 4 and max(starts.values()) >= 2  # a shard of the killed worker ran again
    assert sorted(dask.drone_ids.tolist()) == list(range(48))
    # The nanny restarts the killed worker; the run itself did not need it. (Asked of the
    # scheduler: LocalCluster.wait_for_workers can miss a restarted worker.)
    deadline = time.monotonic() + 60
    while len(client.nthreads()) < 2 and time.monotonic() < deadline:
        time.sleep(0.1)
    assert len(client.nthreads()) == 2
    assert killed[0] not in client.run(os.getpid).values()
    local = fly_show(plan, **opts)
    _assert_same(local, dask)


def test_raising_progress_cancels_the_run(client):
    plan = _wide_show(24)

    class Stop(Exception):
        pass

    def progress(fraction: float) -> None:
        if fraction > 0.0:
            raise Stop

    start = time.monotonic()
    with pytest.raises(Stop):
        fly_show(plan, engine="dask", scheduler=client, shards=2, progress=progress, output_hz=5)
    assert time.monotonic() - start < 30

    def flight_tasks(dask_scheduler) -> list[str]:
        return [str(k) for k in dask_scheduler.tasks if "swarmshow-" in str(k)]

    # The futures were cancelled: the scheduler forgets every task of the run, and the
    # shards running on the workers stop at their next chunk.
    deadline = time.monotonic() + 15
    while client.run_on_scheduler(flight_tasks) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert client.run_on_scheduler(flight_tasks) == []
    deadline = time.monotonic() + 15
    while any(client.processing().values()) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(client.processing().values())


def _unused_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_scheduler_fails_fast(small_plan, tmp_path, capsys):
    address = f"tcp://127.0.0.1:{_unused_port()}"
    with pytest.raises(SchedulerUnreachableError, match="cannot reach the Dask scheduler"):
        fly_show(small_plan, engine="dask", scheduler=address, connect_timeout_s=1.0)
    with pytest.raises(ValueError, match="needs a scheduler"):
        fly_show(small_plan, engine="dask")
    with pytest.raises(ValueError, match="only used with engine='dask'"):
        fly_show(small_plan, scheduler=address)

    from formations import dump_show

    show = tmp_path / "show.json"
    show.write_text(dump_show(make_show(
        [{"name": "ring", "hold_s": 1.0, "points": ring(4, 6.0), "color": "#ff0000"}],
        drones=4, rows=2, cols=2, spacing_m=4.5,
    )))
    capsys.readouterr()
    start = time.monotonic()
    code = main(["simulate", str(show), "--engine", "dask", "--scheduler", address, "--scheduler-timeout", "2"])
    elapsed = time.monotonic() - start
    err = capsys.readouterr().err.strip()
    assert code == 2 and elapsed < 15
    assert len(err.splitlines()) == 1 and "cannot reach the Dask scheduler" in err and address in err
    assert main(["simulate", str(show), "--scheduler", address]) == 2
    assert "--engine dask" in capsys.readouterr().err


def test_cli_simulate_on_the_cluster(client, tmp_path, capsys, small_show):
    from formations import dump_show

    show = tmp_path / "show.json"
    show.write_text(dump_show(small_show))
    address = client.scheduler.address
    assert address.startswith("tcp://127.0.0.1:")
    assert main(["simulate", str(show), "--json", "--output-hz", "10"]) == 0
    local = json.loads(capsys.readouterr().out)
    assert main(["simulate", str(show), "--json", "--output-hz", "10", "--engine", "dask", "--scheduler", address]) == 0
    dask = json.loads(capsys.readouterr().out)
    assert dask["engine"] == "dask"
    for key in ("engine", "wall_time_s", "drone_steps_per_s"):
        local.pop(key), dask.pop(key)
    assert dask == local


def test_server_setting_switches_simulate_jobs_to_dask(client, small_show, monkeypatch):
    import queue
    import threading

    from app import tasks
    from formations import dump_show

    text = dump_show(small_show)
    options = {"engine": "numba", "controller": "ismc", "disturbance": "none", "output_hz": 10.0, "seed": 0}
    # The environment is not read by the task: a stray variable changes nothing.
    monkeypatch.setenv("SWARMSHOW_DASK_SCHEDULER", "tcp://127.0.0.1:1")
    local = tasks.simulate_task(text, tasks.flight_options(options, None), "job-local", queue.SimpleQueue(),
                                threading.Event())
    assert local["flight"]["engine"] == "numba"

    updates: queue.SimpleQueue = queue.SimpleQueue()
    out = tasks.simulate_task(text, tasks.flight_options(options, client.scheduler.address), "job-dask", updates,
                              threading.Event())
    assert out["flight"]["engine"] == "dask"
    assert out["flight"]["tracking_max_m"] == local["flight"]["tracking_max_m"]
    assert out["flight"]["flown_min_distance_m"] == local["flight"]["flown_min_distance_m"]
    fractions = []
    while not updates.empty():
        job, kind, value = updates.get()
        if kind == "progress":
            fractions.append(value)
    # The job's queue is throttled (1 % steps), so the last report need not be exactly 1.
    assert fractions and fractions == sorted(fractions) and fractions[-1] > 0.9

    # An unreachable cluster is a 503 of the job, not an internal error (after a 1 s
    # instead of the default 10 s connection timeout, to keep the test short).
    # The server resolves the engine from its settings (workers never read the environment).
    down = tasks.flight_options({**options, "engine": "numba"}, f"tcp://127.0.0.1:{_unused_port()}")
    assert down["engine"] == "dask"
    with pytest.raises(tasks.TaskFailure) as exc:
        tasks.simulate_task(text, {**down, "connect_timeout_s": 1.0}, "job-down", queue.SimpleQueue(),
                            threading.Event())
    assert exc.value.kind == tasks.FailureKind.UNAVAILABLE and "cluster unavailable" in str(exc.value)
