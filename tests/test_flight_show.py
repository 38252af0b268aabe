"""Flying a planned show, and the ``simulate`` / ``bench sim`` commands."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.cli import main
from formations import load_demo_show
from sim import plan_show
from sim.flight import FlightResult, fly_show


def test_small_show_flies_with_flown_min_distance(small_plan):
    calls = []
    res = fly_show(small_plan, progress=calls.append)
    assert isinstance(res, FlightResult)
    n_frames = res.times_s.size
    assert res.positions_m.shape == (n_frames, 16, 3) and res.positions_m.dtype == np.float32
    assert res.colors_rgb.shape == (n_frames, 16, 3)
    assert res.times_s[1] - res.times_s[0] == pytest.approx(0.04)
    assert res.times_s[-1] <= small_plan.duration_s + 1e-9
    assert res.diverged == [] and res.ok
    assert res.tracking_max_m.max() < 1e-3  # m, no disturbance
    # The flown separation is close to the planned one and names a real pair.
    planned = small_plan.evaluate(res.times_s).positions_m
    np.testing.assert_allclose(res.positions_m, planned, atol=2e-3)
    assert 3.0 <= res.flown_min_distance_m < 10.0
    i, j = res.flown_min_distance_pair
    f = int(np.argmin(np.abs(res.times_s - res.flown_min_distance_time_s)))
    assert np.linalg.norm(res.positions_m[f, i] - res.positions_m[f, j]) == pytest.approx(
        res.flown_min_distance_m, abs=1e-5)
    assert calls and calls[-1] == pytest.approx(1.0) and calls == sorted(calls)
    s = res.summary()
    json.dumps(s, allow_nan=False)
    assert s["engine"] == "numba" and s["controller"] == "ismc" and s["disturbance"] == "none"
    assert s["flown_min_distance_pair"] == [i, j] and len(s["worst_drones"]) == 5


def test_subset_wind_baseline_and_output_rate(small_plan):
    res = fly_show(small_plan, drones=np.array([0, 5, 9]), disturbance="wind", controller="baseline",
                   output_hz=50.0, seed=2)
    assert res.positions_m.shape[1] == 3 and list(res.drone_ids) == [0, 5, 9]
    assert res.times_s[1] == pytest.approx(0.02)
    assert res.summary()["controller"] == "baseline" and res.summary()["disturbance"] == "wind"
    assert res.flown_min_distance_pair[0] in (0, 5, 9)


def test_progress_exception_cancels(small_plan):
    class Cancelled(Exception):
        pass

    def cancel(fraction: float) -> None:
        raise Cancelled

    with pytest.raises(Cancelled):
        fly_show(small_plan, progress=cancel)


def test_diverging_drone_in_a_show(small_plan):
    from sim.flight import IsmcGains, PositionGains

    res = fly_show(small_plan, drones=slice(0, 4), gains=IsmcGains(position=PositionGains(k1=-80.0)),
                   chunk_s=0.5)
    assert {d for d, _, _ in res.diverged} == {0, 1, 2, 3}
    assert not res.ok and np.all(np.isfinite(res.positions_m))
    json.dumps(res.summary(), allow_nan=False)


def _write_small_show(path, small_show):
    from formations import dump_show

    path.write_text(dump_show(small_show))


def test_cli_simulate_show_json(tmp_path, small_show, capsys):
    show = tmp_path / "show.json"
    _write_small_show(show, small_show)
    code = main(["simulate", str(show), "--json", "--output-hz", "10"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["ok"] and out["drones"] == 16 and out["output_hz"] == pytest.approx(10.0)
    assert out["flown_min_distance_m"] >= 3.0 - 0.01 and out["diverged"] == []


def test_cli_usage_errors(tmp_path, capsys):
    assert main(["simulate"]) == 2
    assert "SHOW" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "missing.json")]) == 2
    capsys.readouterr()
    # The dask engine needs a scheduler (tests/test_flight_dask.py flies it).
    assert main(["simulate", "x.json", "--engine", "dask", "--scheduler-timeout", "1"]) == 2
    assert "dask" in capsys.readouterr().err


def test_cli_paper_scenario(tmp_path, capsys):
    png = tmp_path / "paper.png"
    code = main(["simulate", "--scenario", "paper", "--json", "--plot", str(png)])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["meets_thresholds"]
    for key in ("pos_err_m", "att_err_rad"):
        assert set(out[key]) == {"max_t_ge_8s", "at_20s"}
    assert {"settle_time_s", "max_thrust_step_n", "baseline"} <= set(out)
    assert png.stat().st_size > 10_000


def test_cli_bench_sim(capsys):
    code = main(["bench", "sim", "--drones", "50", "--seconds", "0.1", "--numpy-seconds", "0.02", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["drone_steps_per_s"] > 0 and out["numpy_drone_steps_per_s"] > 0
    assert out["speedup"] == pytest.approx(out["drone_steps_per_s"] / out["numpy_drone_steps_per_s"])


def test_demo_show_flies_with_flown_min_distance():
    show = load_demo_show()
    plan = plan_show(show)
    res = fly_show(plan, output_hz=10.0)
    s = res.summary()
    assert s["drones"] == show.drones and s["diverged"] == []
    assert s["flown_min_distance_m"] >= show.settings.min_distance_m - 0.01
    assert s["flown_min_distance_pair"] is not None and s["tracking_max_m"] < 1e-2


# ---------------------------------------------------------------- per-drone timing


def test_staggered_plan_helper_is_the_closed_form(staggered_small):
    # The test plan's pieces are what its legs say (so the tests below test the consumers).
    plan, legs = staggered_small
    t = np.random.default_rng(4).uniform(0.0, plan.duration_s, 400)
    np.testing.assert_allclose(plan.evaluate(t).positions_m, legs.positions(t), rtol=0, atol=1e-9)
    # Drones really do have their own break times inside the windows.
    assert len({tuple(np.round(row, 9)) for row in plan.motion.breaks_s}) == plan.drone_count


def test_plan_reference_is_each_drones_own_motion(staggered_small):
    from sim.flight import plan_reference

    plan, _ = staggered_small
    rng = np.random.default_rng(5)
    t = np.r_[rng.uniform(0.0, plan.duration_s, 200), plan.motion.breaks_s[3], plan.duration_s + 0.3]
    ids = np.array([1, 3, 4, 9, 15])
    ref = plan_reference(plan, drones=ids)
    chunk = ref.chunk(t)
    want = plan.evaluate(t, drones=ids)
    for j in range(len(t)):
        p, v, a = ref.at_step(chunk, j)
        np.testing.assert_allclose(p, want.positions_m[j], rtol=0, atol=1e-12)
        np.testing.assert_allclose(v, want.velocities_mps[j], rtol=0, atol=1e-12)
        np.testing.assert_allclose(a, want.accelerations_mps2[j], rtol=0, atol=1e-12)


def test_numba_kernel_tracks_each_drones_own_pieces(staggered_small):
    # The kernel's reference at every frame is p - e1 (position minus the recorded error):
    # it must be plan.evaluate at that time, across every drone's own breaks (its piece
    # cursor only moves forward, restarting each chunk).
    from sim.flight import plan_reference, simulate

    plan, _ = staggered_small
    ref = plan_reference(plan)
    res = simulate(ref, duration_s=plan.duration_s, engine="numba", output_every=7, telemetry=True,
                   chunk_steps=997)
    kernel_ref = res.positions_m - res.telemetry[..., 0:3]
    want = plan.evaluate(res.frame_times_s).positions_m
    assert np.abs(kernel_ref - want).max() < 1e-9
    assert res.diverged() == []


def test_staggered_show_flies_on_its_own_timing(staggered_small):
    plan, legs = staggered_small
    res = fly_show(plan)
    assert res.diverged == []
    # The flown drones follow their own re-timed legs (the shared windows' positions are
    # metres away). The test's smoothstep legs jump in acceleration at both ends, which
    # the controller takes a few centimetres to absorb; the quintic legs track to 1 mm.
    flown_error = np.linalg.norm(res.positions_m - legs.positions(res.times_s), axis=2)
    assert flown_error.max() < 0.3
    quintic_only = ~np.any(np.array(legs.cubic), axis=0)
    assert quintic_only.any() and res.tracking_max_m[quintic_only].max() < 1e-3


def test_cli_simulate_flies_a_forced_short_transition_as_designed(tmp_path, capsys):
    """As the app's simulate (a what-if): a transition forced shorter than the limits allow is flown as designed,
    the summary names the field and the command exits 1 (not flyable), where it used to refuse it (exit 2). The
    Monte-Carlo safety margin still refuses it, naming the field (exit 2)."""
    from tests.test_api_forced_short import forced_doc

    show = tmp_path / "forced.json"
    show.write_text(json.dumps(forced_doc()))
    code = main(["simulate", str(show), "--json", "--output-hz", "10"])
    out = json.loads(capsys.readouterr().out)
    assert code == 1
    assert [p["path"] for p in out["problems"]] == ["formations[1].transition_s"]
    assert "shorter than the minimum" in out["problems"][0]["msg"]
    code = main(["simulate", str(show), "--output-hz", "10"])
    text = capsys.readouterr().out
    assert code == 1 and "NOT FLYABLE AS DESIGNED: formations[1].transition_s = 0.2 s" in text
    assert main(["simulate", str(show), "--runs", "2"]) == 2
    err = capsys.readouterr().err
    assert "formations[1].transition_s" in err and len(err.strip().splitlines()) == 1
