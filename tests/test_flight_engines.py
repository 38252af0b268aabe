"""The fused numba kernel computes what the readable numpy step computes."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sim.flight import (
    IsmcGains,
    QuadrotorParams,
    TrackingReference,
    error_preset,
    hover_state,
    make_disturbance,
    simulate,
)
from sim.flight.engines._numba import run_chunk_numba
from sim.flight.engines._numpy import init_controller
from sim.flight.engines._numpy import run_chunk_numpy as _run_chunk_numpy
from sim.flight.engines._state import C_ROTOR, STATS_SIZE, TEL_SIZE
from tests.conftest import fleet_off_its_circles
from tests.kernel_witness import FLY_AND_SAVE, FLY_LOADED


@pytest.mark.parametrize("disturbance", ["none", "wind", "paper"])
def test_engines_agree_over_one_second(disturbance):
    ref, start = fleet_off_its_circles(24, 3, velocity_sd_mps=0.02)
    kw = dict(duration_s=1.0, initial_state=start, disturbance=disturbance, output_every=25, telemetry=True,
              chunk_steps=300)
    a = simulate(ref, engine="numba", **kw)
    b = simulate(ref, engine="numpy", **kw)
    assert np.abs(a.final_state - b.final_state).max() < 1e-9
    assert np.abs(a.positions_m - b.positions_m).max() < 1e-9
    assert np.nanmax(np.abs(a.telemetry - b.telemetry)) < 1e-9
    np.testing.assert_allclose(a.rms_error_m, b.rms_error_m, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a.max_thrust_step_n, b.max_thrust_step_n, rtol=1e-9, atol=1e-12)


def test_one_step_agrees_from_arbitrary_states():
    rng = np.random.default_rng(5)
    n = 64
    ref = TrackingReference.circle(rng.normal(size=(n, 3)) * 10.0, radius_m=2.0, omega_rad_s=1.0)
    params = QuadrotorParams()
    plant = params.mismatched(fraction=0.1)
    gains = IsmcGains()
    dist = make_disturbance("paper")
    state = hover_state(rng.normal(size=(n, 3)) * 10.0)
    state[:, 3:6] = rng.normal(size=(n, 3))
    state[:, 6:9] = rng.normal(scale=0.3, size=(n, 3))
    state[:, 9:12] = rng.normal(size=(n, 3))
    times = np.array([0.0, 1e-3, 2e-3])
    chunk = ref.chunk(times)
    ctrl0 = init_controller(state, ref, chunk, params=params, gains=gains)
    ctrl0[:, 0:30] += rng.normal(scale=0.1, size=(n, 30))
    opts = {"params": params, "plant": plant, "gains": gains, "disturbance": dist, "dt_s": 1e-3,
            "integrator": "euler", "divergence_limit_m": 100.0}
    out = []
    for runner in (_run_chunk_numpy, run_chunk_numba):
        s, c = state.copy(), ctrl0.copy()
        runner(s, c, np.zeros((n, STATS_SIZE)), np.full(n, -1), np.zeros(n, dtype=np.int64), ref=ref,
               chunk=chunk, dist=dist.signals(times), step0=0, times=times, every=1,
               frames=np.zeros((3, n, 3)), tel=None, opts=opts)
        out.append((s, c))
    assert np.abs(out[0][0] - out[1][0]).max() < 1e-11
    assert np.abs(out[0][1][:, :C_ROTOR] - out[1][1][:, :C_ROTOR]).max() < 1e-9
    # The rotor state holds ω² (~1e6-1e7 rad²/s²): equal to the last few ulps.
    np.testing.assert_allclose(out[0][1][:, C_ROTOR:], out[1][1][:, C_ROTOR:], rtol=1e-11,
                               atol=1e-11 * plant.omega_max_sq)


def test_engines_agree_across_each_drones_own_breaks(staggered_small):
    # Per-drone polynomial pieces (quintic and cubic legs, zero-length pieces, each drone's
    # own breaks): from arbitrary states, a few steps straddling one drone's break at a
    # time. Over long runs of plan windows the two engines drift apart inside the sliding
    # modes' chattering (module docstring of sim.flight.engines._numba), with the plan's
    # own shared-window motion as much as with staggered pieces, so this compares single
    # steps, like test_one_step_agrees_from_arbitrary_states, where every reference term
    # (p, v, a) enters the step.
    from sim.flight import plan_reference

    plan, _ = staggered_small
    ref = plan_reference(plan)
    n = plan.drone_count
    rng = np.random.default_rng(9)
    params, gains, dist = QuadrotorParams(), IsmcGains(), make_disturbance("paper")
    opts = {"params": params, "plant": params, "gains": gains, "disturbance": dist, "dt_s": 1e-3,
            "integrator": "euler", "divergence_limit_m": 100.0}
    breaks = plan.motion.breaks_s
    inner = np.unique(breaks[:, 1:-1][np.diff(breaks, axis=1)[:, 1:] > 0])
    assert len(inner) > 20
    for tb in rng.choice(inner, 12, replace=False):
        times = (int(np.floor(tb / 1e-3)) - 1 + np.arange(4)) * 1e-3  # two steps before the break, two after
        chunk = ref.chunk(times)
        p, v, a = ref.at_step(chunk, 0)
        state = hover_state(p + rng.normal(size=(n, 3)))
        state[:, 3:6] = v + rng.normal(size=(n, 3))
        state[:, 6:9] = rng.normal(scale=0.3, size=(n, 3))
        state[:, 9:12] = rng.normal(size=(n, 3))
        ctrl0 = init_controller(state, ref, chunk, params=params, gains=gains)
        ctrl0[:, 0:30] += rng.normal(scale=0.1, size=(n, 30))
        out = []
        for runner in (_run_chunk_numpy, run_chunk_numba):
            s, c = state.copy(), ctrl0.copy()
            tel, frames = np.zeros((4, n, TEL_SIZE)), np.zeros((4, n, 3))
            # (step0 only numbers the frames; the chunk's times drive the reference.)
            runner(s, c, np.zeros((n, STATS_SIZE)), np.full(n, -1), np.zeros(n, dtype=np.int64), ref=ref,
                   chunk=chunk, dist=dist.signals(times), step0=0, times=times, every=1,
                   frames=frames, tel=tel, opts=opts)
            out.append((s, c, tel))
            # Each engine tracked plan.evaluate at each step (p_ref = p - e1).
            want = plan.evaluate(times).positions_m
            assert np.abs(frames - tel[..., 0:3] - want).max() < 1e-9
        assert np.abs(out[0][0] - out[1][0]).max() < 1e-9
        assert np.abs(out[0][1][:, :C_ROTOR] - out[1][1][:, :C_ROTOR]).max() < 1e-9
        # ω² to the last few ulps of its range (a desaturated rotor lands on a bound, 0 in one engine and
        # an ulp of ω_max² off it in the other).
        np.testing.assert_allclose(out[0][1][:, C_ROTOR:], out[1][1][:, C_ROTOR:], rtol=1e-11,
                                   atol=1e-11 * params.omega_max_sq)
        assert np.abs(out[0][2] - out[1][2]).max() < 1e-9


def test_read_only_inputs_run_the_same_compiled_kernel():
    """Arrays from Dask's pickle-5 buffers can arrive read-only; numba would compile a second
    specialisation for them (possibly contracted differently), breaking local/Dask bit-identity.
    The driver hands the kernel writable arrays, so read-only references give the same bits and
    never add a read-only signature."""
    from numba import types

    from sim.flight.engines._numba import _kernel

    rng = np.random.default_rng(11)
    n = 20
    centers = rng.uniform(-20.0, 20.0, (n, 3)) + [0.0, 0.0, 40.0]
    kw = dict(duration_s=0.3, initial_state=hover_state(centers + [3.0, 0.0, 0.0]), disturbance="wind",
              output_every=10, chunk_steps=100)
    ref = TrackingReference.circle(centers, radius_m=3.0, omega_rad_s=0.7)
    a = simulate(ref, engine="numba", **kw)
    frozen = TrackingReference.circle(centers, radius_m=3.0, omega_rad_s=0.7)
    for arr in (frozen.motion.breaks_s, frozen.motion.coeffs_m):
        arr.flags.writeable = False
    b = simulate(frozen, engine="numba", **kw)
    assert np.array_equal(a.final_state, b.final_state)
    assert np.array_equal(a.positions_m, b.positions_m)
    # numba types a read-only array as Array(..., readonly=True), i.e. ``mutable`` False.
    assert not any(isinstance(t, types.Array) and not t.mutable for sig in _kernel.signatures for t in sig)


def test_a_few_remaining_steps_ride_with_the_last_chunk_and_change_nothing():
    # A whole-second flight has round(d/dt) + 1 steps: without the merge its last chunk is one step
    # long and pays a chunk's table set-up. The chunks the driver takes, seen through on_chunk, and
    # the same bits as a chunking that leaves no short remainder.
    rng = np.random.default_rng(2)
    n = 6
    centers = rng.uniform(-20.0, 20.0, (n, 3)) + [0.0, 0.0, 40.0]
    ref = TrackingReference.circle(centers, radius_m=3.0, omega_rad_s=0.7)
    kw = dict(duration_s=1.0, engine="numba", output_every=10, errors=error_preset("gusty-rtk"), seed=3)
    runs = {}
    for chunk_steps in (1000, 250, 600, 77):
        done: list[int] = []
        res = simulate(ref, chunk_steps=chunk_steps, on_chunk=lambda k, _d, done=done: done.append(k), **kw)
        runs[chunk_steps] = (res, done)
    assert runs[1000][1] == [1001]
    assert runs[250][1] == [250, 500, 750, 1001]
    assert runs[600][1] == [600, 1001]  # 401 steps left: more than 600 // 16, a chunk of their own
    assert runs[77][1][-2:] == [924, 1001]  # 77 left after 924: more than 77 // 16
    for chunk_steps in (250, 600, 77):
        assert np.array_equal(runs[chunk_steps][0].positions_m, runs[1000][0].positions_m)
        assert np.array_equal(runs[chunk_steps][0].final_state, runs[1000][0].final_state)


def test_a_process_that_compiles_the_kernel_matches_one_that_loads_it(tmp_path, cold_kernel_flight):
    # numba's in-process JIT and its cached object code of the parallel kernel differ in the
    # last bit; a process that compiled the kernel used to disagree with every process that
    # loaded it (a Dask worker, the next run). Both now run the cached code: a cold cache
    # (this process compiles) and then a warm one (it loads) give the same bits. The cold
    # process is the session's warm-up when it met a cold cache (a fresh clone; it flew the
    # same flight, tests/kernel_witness.py), else one of ours on a fresh cache of our own.
    if cold_kernel_flight is not None:
        env, outs = dict(os.environ), [np.load(cold_kernel_flight)]
    else:
        env, outs = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache")), []
        subprocess.run([sys.executable, "-c", FLY_AND_SAVE, str(tmp_path / "cold.npy")], env=env, check=True,
                       timeout=1200)
        outs.append(np.load(tmp_path / "cold.npy"))
    subprocess.run([sys.executable, "-c", FLY_LOADED, str(tmp_path / "warm.npy")], env=env, check=True, timeout=1200,
                   cwd=Path(__file__).resolve().parents[1])
    outs.append(np.load(tmp_path / "warm.npy"))
    assert np.array_equal(outs[0], outs[1])


_COMPILE_IN_CHILD = """
import sim.flight.engines._numba as K
K._cached_machine_code(K._sig_scale, (1.0, 2.0, 3.0, 0.5))
"""


def test_the_compiling_child_imports_the_parents_code_not_the_working_directorys(tmp_path):
    # _cached_machine_code compiles a cache miss in a child process that must import the same
    # code as the parent. ``python -c`` puts the working directory first on sys.path, so a
    # ``sim`` package there (another checkout) was imported instead: the child then failed,
    # this process compiled the kernel itself, and its bits differed from the cached code's.
    work = tmp_path / "elsewhere"
    (work / "sim").mkdir(parents=True)
    marker = work / "decoy-imported"
    (work / "sim" / "__init__.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    script = tmp_path / "probe.py"
    script.write_text(_COMPILE_IN_CHILD)
    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               PYTHONPATH=os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]))
    subprocess.run([sys.executable, str(script)], cwd=work, env=env, check=True, timeout=600)
    assert any((tmp_path / "cache").rglob("*.nbi")), "nothing was compiled into the fresh cache"
    assert not marker.exists(), "the compiling child imported the working directory's sim package"


def test_the_lane_scratch_starts_on_a_cache_line():
    # numba aligns arrays to 32 bytes; the kernel's scratch must start on a 64-byte line so that
    # its 8-wide field accesses never straddle two (issue 20 item 6). Many sizes and allocations:
    # an allocator that returns 32-byte aligned blocks hits both cases.
    from sim.flight.engines._numba import _aligned_zeros

    keep = []
    for size in list(range(1, 40)) + [3200, 3201, 25600]:
        for _ in range(4):
            a = _aligned_zeros(size)
            keep.append(a)  # held, so that later allocations land elsewhere
            assert a.ctypes.data % 64 == 0, (size, a.ctypes.data % 64)
            assert a.shape == (size,) and a.dtype == np.float64 and not a.any()


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_a_drone_that_sinks_below_the_ground_stops_there_with_reason_ground(engine):
    """Issue 20 QA: a drone that falls through the ground of a show must stop ("ground") in the flight itself.

    Drone 0 tracks a hover 3 m under its start (it descends through the ground), drone 1 hovers at 2 m.
    With ``ground_m = 0`` drone 0 is stopped at the first step whose true height is below -GROUND_STRIKE_M
    (read back from the per-step frames: the step before is above), drone 1 flies on. Without a ground
    (free-space references, the paper scenario) nobody stops.
    """
    from sim.flight.engines._state import GROUND_STRIKE_M

    ref = TrackingReference.hover(np.array([[0.0, 0.0, -3.0], [5.0, 0.0, 2.0]]))
    start = hover_state(np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 2.0]]))
    kw = dict(duration_s=3.0, initial_state=start, output_every=1, engine=engine)
    free = simulate(ref, **kw)
    assert free.diverged() == [] and free.final_state[0, 2] < -2.0
    res = simulate(ref, ground_m=0.0, **kw)
    z = free.positions_m[:, 0, 2]  # the same flight up to the strike: frame k is the state at step k
    first = int(np.flatnonzero(z < -GROUND_STRIKE_M)[0])
    assert res.diverged() == [(0, pytest.approx(first * 1e-3), "ground")]
    assert res.final_state[0, 2] == z[first]  # stopped where it struck
    assert res.diverged_step[1] == -1 and abs(res.final_state[1, 2] - 2.0) < 1e-6
    # A ground 1 m lower lets it sink 1 m further.
    low = simulate(ref, ground_m=-1.0, **kw)
    assert low.diverged()[0][2] == "ground" and low.final_state[0, 2] < -1.0 - GROUND_STRIKE_M
