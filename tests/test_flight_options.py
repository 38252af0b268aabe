"""FlightOptions: one checked value shared by fly_show, the CLI, the API and the job cache key."""

from __future__ import annotations

import numpy as np
import pytest

from sim import plan_show
from sim.bench._shows import benchmark_show
from sim.flight import CONTROLLERS, DISTURBANCES, ENGINES, FlightOptions, fly_show
from sim.flight._disturbance import Disturbance


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"engine": "cuda"}, "engine"),
        ({"controller": "pid"}, "controller"),
        ({"disturbance": "storm"}, "disturbance"),
        ({"output_hz": 0.0}, "output_hz"),
        ({"output_hz": float("nan")}, "output_hz"),
        ({"chunk_s": -1.0}, "chunk_s"),
        ({"scheduler": "tcp://127.0.0.1:1"}, "engine='dask'"),
        ({"shards": 2}, "engine='dask'"),
    ],
)
def test_bad_options_name_the_field(changes: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        FlightOptions(**changes)


def test_name_sets_are_the_accepted_values() -> None:
    assert set(ENGINES) == {"numba", "numpy", "dask"}
    assert set(CONTROLLERS) == {"ismc", "baseline"}
    assert set(DISTURBANCES) == {"none", "paper", "wind"}
    for e in ENGINES:
        FlightOptions(engine=e)
    for c in CONTROLLERS:
        FlightOptions(controller=c)
    for d in DISTURBANCES:
        FlightOptions(disturbance=d)


def test_old_keywords_and_options_fly_the_same() -> None:
    plan = plan_show(benchmark_show(4, formations=1))
    a = fly_show(plan, FlightOptions(disturbance="wind", seed=3, output_hz=10), drones=[0, 2])
    b = fly_show(plan, disturbance="wind", seed=3, output_hz=10, drones=[0, 2])
    np.testing.assert_array_equal(a.positions_m, b.positions_m)
    assert a.summary()["disturbance"] == "wind" and a.positions_m.shape[1] == 2
    with pytest.raises(TypeError, match="not both"):
        fly_show(plan, FlightOptions(), seed=1)
    with pytest.raises(TypeError, match="unknown flight option"):
        fly_show(plan, engne="numpy")


def test_cache_key_separates_what_changes_the_flight() -> None:
    base = FlightOptions()
    assert hash(base.cache_key()) == hash(FlightOptions().cache_key())
    # The Dask engine flies the numba kernel bit for bit; where and in how many chunks is not in the key.
    assert FlightOptions(engine="dask", scheduler="local", shards=3).cache_key() == base.cache_key()
    assert base.with_(chunk_s=0.5).cache_key() == base.cache_key()
    keys = {
        base.with_(**c).cache_key()
        for c in ({}, {"engine": "numpy"}, {"controller": "baseline"}, {"disturbance": "wind"}, {"seed": 1},
                  {"output_hz": 50.0}, {"mismatch": 0.1}, {"divergence_limit_m": 5.0})
    }
    assert len(keys) == 8
    custom = Disturbance.none()
    assert FlightOptions(disturbance=custom).cache_key() != base.cache_key()


def test_colours_are_only_evaluated_when_asked_for() -> None:
    # The Monte-Carlo runs fly with colors=False: the same flight, no colour arrays.
    plan = plan_show(benchmark_show(8, formations=2))
    with_colours = fly_show(plan, FlightOptions(output_hz=10.0, seed=1))
    without = fly_show(plan, FlightOptions(output_hz=10.0, seed=1, colors=False))
    assert without.colors_rgb.shape == (0, plan.drone_count, 3)
    np.testing.assert_array_equal(without.positions_m, with_colours.positions_m)
    # The colours asked for are the plan's own at the frame times.
    np.testing.assert_allclose(with_colours.colors_rgb,
                               plan.evaluate(with_colours.times_s).colors_rgb.astype(np.float32), atol=1e-7)
    assert FlightOptions(colors=False).cache_key() != FlightOptions().cache_key()
