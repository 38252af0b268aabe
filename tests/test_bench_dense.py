"""The dense-suite generator and its lower bound, against brute force."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching
from scipy.spatial import cKDTree

from app.cli import main as cli_main
from sim.bench._dense import DENSE_KINDS, bottleneck_time, dense_points, hopcroft_karp, leg_time_lower_bound

LIM = {"v_xy": 10.0, "v_z": 2.0, "a": 4.0, "v_down": None}


def test_hopcroft_karp_matches_scipy_on_random_graphs() -> None:
    rng = np.random.default_rng(0)
    for _ in range(300):
        n = int(rng.integers(1, 30))
        m = int(rng.integers(n, 40))
        g = csr_matrix(rng.random((n, m)) < rng.uniform(0.02, 0.3))
        ours = hopcroft_karp(g.indptr.astype(np.int64), g.indices.astype(np.int64), n, m)
        assert ours == int((maximum_bipartite_matching(g, perm_type="column") >= 0).sum())


@pytest.mark.parametrize("seed", range(6))
def test_bottleneck_bound_against_all_permutations(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 6
    x = rng.uniform(-20, 20, (n, 3)) + np.array([0, 0, 30])
    g = rng.uniform(-20, 20, (n, 3)) + np.array([0, 0, 30])
    t = leg_time_lower_bound(x[:, None], g[None], **LIM)
    best = min(max(t[i, p[i]] for i in range(n)) for p in itertools.permutations(range(n)))
    got = bottleneck_time(x, g, tol_s=1e-3, **LIM)
    assert best - 2e-3 <= got <= best + 1e-6  # a lower bound, within the tolerance


def test_trapezoid_leg_time_closed_form() -> None:
    # 100 m horizontal at 10 m/s, 4 m/s²: 100/10 + 10/4 = 12.5 s; 2 m: 2·√(2/4).
    x = np.zeros((2, 3))
    g = np.array([[100.0, 0, 0], [2.0, 0, 0]])
    assert leg_time_lower_bound(x, g, **LIM) == pytest.approx([12.5, 2 * np.sqrt(0.5)])


@pytest.mark.parametrize("kind", DENSE_KINDS)
def test_dense_formations_are_drawn_at_exactly_the_minimum_distance(kind: str) -> None:
    pts = dense_points(kind, 120, 3.0, np.random.default_rng(1))
    assert pts.shape == (120, 3)
    d, _ = cKDTree(pts).query(pts, k=2)
    assert d[:, 1].min() >= 3.0 - 1e-9
    if kind != "cloud":  # lattices: the closest pairs are exactly at the minimum distance
        assert d[:, 1].min() == pytest.approx(3.0)


def test_cli_bench_plan_dense_small(capsys) -> None:
    assert cli_main(["bench", "plan", "--dense", "--drones", "30", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    (show,) = out["shows"]
    assert show["unresolved"] == 0
    assert show["sampled_min_distance_m"] >= 3.0 * (1 - 1e-9)
    assert show["ratio_to_bound"] == pytest.approx(show["show_duration_s"] / show["lower_bound_s"])
    assert show["ratio_to_bound"] >= 1.0
    assert show["kdtree_same_result"] is True  # the reference candidate search agrees on the same plan
    assert len(show["transitions"]) == 7  # six formations and the landing approach


def test_cli_bench_plan_dense_table(capsys) -> None:
    assert cli_main(["bench", "plan", "--dense", "--drones", "20"]) == 0
    text = capsys.readouterr().out
    assert "kdtree x" in text and "per transition" in text


@pytest.mark.slow
def test_cli_bench_plan_dense_cold_and_warm_processes(capsys) -> None:
    """--cold plans in fresh processes: the first compiles every kernel into an empty numba cache, the second
    loads them, so it is much cheaper, and both give the same plan."""
    assert cli_main(["bench", "plan", "--dense", "--drones", "12", "--cold", "--json"]) == 0
    (fresh,) = json.loads(capsys.readouterr().out)["fresh"]
    cold, warm = fresh["cold"], fresh["warm"]
    assert fresh["same_plan"] is True and cold["violations"] == warm["violations"] == 0
    assert warm["plan_cpu_s"] + warm["check_cpu_s"] < 0.5 * (cold["plan_cpu_s"] + cold["check_cpu_s"])
