"""``swarmshow bench plan|check``: small runs whose figures are checked against independent computations."""

from __future__ import annotations

import json

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

from app.cli import main as cli_main
from sim.bench._shows import grid_to_sphere_input


def test_bench_plan_json_matches_dense_optimum(capsys) -> None:
    assert cli_main(["bench", "plan", "--drones", "150", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    starts, goals = grid_to_sphere_input(150)
    r, c = linear_sum_assignment(cdist(starts, goals, "sqeuclidean"))
    assert np.isclose(out["assignment_cost_m2"], ((starts[r] - goals[c]) ** 2).sum(), rtol=1e-9)
    assert out["cost_equal"] is True
    assert out["min_distance_m"] >= out["capt_guarantee_m"] - 1e-9


def test_bench_check_json_exact_minimum_bounds_sampling(capsys) -> None:
    assert cli_main(["bench", "check", "--drones", "64", "--formations", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["violations"] == 0 and out["formations"] == 2
    # A sampled minimum can never be below the exact continuous-time minimum.
    assert out["sampled_10hz_min_distance_m"] >= out["exact_min_distance_m"] - 1e-9


def test_bench_rejects_bad_sizes(capsys) -> None:
    assert cli_main(["bench", "plan", "--drones", "1"]) == 2
    assert "--drones" in capsys.readouterr().err
