"""Subset formations (issue 21 item 3): ``make bench`` or ``pytest -m slow benchmarks/bench_groups.py``.

* The count choice: CAPT with free "stay" goals (exact, dense) against its greedy fallback (the n drones
  nearest the formation, assigned exactly among themselves): travel cost and time ratios on one input.
* A 400-drone show whose middle formation is flown by 200 drones (others hold, park or land): planned and
  checked exactly; planning time against the same show with every drone flying a 400-point formation
  there (ratio, same run).
* Random groups of 10-40 drones drawn through the previous formation (tests/test_plan_group_through.py's
  ``random_group_doc``: others park, land with homes on both sides, or "swap", landing while some are down;
  "sphere-swap": 60 drones, groups of 10-25 through a sphere, the swap from a ring tilted towards the audience),
  checked by ``swarmshow check --json``: shows safe / total with the staged plan, and what the staging costs:
  the transition's length against the one-window plan it replaces (unsafe, so the planner stages it) on the
  same shows in the same run, alternating.
"""

from __future__ import annotations

import contextlib
import io
import json
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from app.cli import main as cli_main
from formations import parse_show
from sim import check_plan, plan_show
from sim.plan import _plan, _subset, clear_plan_cache
from tests.test_plan_group_through import _ring_sphere_swap_doc, random_group_doc, sphere_park_doc

pytestmark = pytest.mark.slow


def _sphere(n: int, r: float, c: tuple[float, float, float]) -> np.ndarray:
    k = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * k / n)
    th = np.pi * (1 + 5**0.5) * k
    return np.column_stack([r * np.cos(th) * np.sin(phi), r * np.sin(th) * np.sin(phi), r * np.cos(phi)]) + c


def test_bench_count_choice_exact_vs_greedy(record_result) -> None:
    rng = np.random.default_rng(0)
    starts = _sphere(1500, 40.0, (0, 0, 60)) + rng.normal(0, 0.3, (1500, 3))
    points = _sphere(600, 25.0, (20, -10, 55))
    t = time.perf_counter()
    d_exact, p_exact = _subset.choose_drones(starts, points, 600)
    exact_s = time.perf_counter() - t
    cells = _subset.DENSE_SELECT_MAX_CELLS
    try:
        _subset.DENSE_SELECT_MAX_CELLS = 0  # force the greedy fallback on the same input
        t = time.perf_counter()
        d_greedy, p_greedy = _subset.choose_drones(starts, points, 600)
        greedy_s = time.perf_counter() - t
    finally:
        _subset.DENSE_SELECT_MAX_CELLS = cells
    exact = float(((starts[d_exact] - points[p_exact]) ** 2).sum())
    greedy = float(((starts[d_greedy] - points[p_greedy]) ** 2).sum())
    record_result({"drones": 1500, "points": 600, "count": 600, "exact_cost_m2": exact, "greedy_cost_m2": greedy,
                   "greedy_over_exact_cost": greedy / exact, "exact_over_greedy_time": exact_s / greedy_s})
    assert exact <= greedy * (1 + 1e-9)


@pytest.mark.parametrize("others", ["hold", "park", "land"])
def test_bench_subset_show_400(others: str, record_result) -> None:
    n = 400
    first = _sphere(n, 30.0, (0, 0, 60)).round(6).tolist()
    half = _sphere(200, 18.0, (0, -30, 50)).round(6).tolist()
    full = _sphere(n, 30.0, (0, -30, 60)).round(6).tolist()

    def doc(middle: dict) -> dict:
        return {"format": "swarmshow/1", "name": "subset bench", "drones": n,
                "home": {"grid": {"rows": 20, "cols": 20, "spacing_m": 4.0}},
                "formations": [{"name": "a", "hold_s": 2.0, "points": first}, middle,
                               {"name": "c", "hold_s": 2.0, "points": first}]}

    subset = parse_show(doc({"name": "b", "hold_s": 2.0, "points": half, "drones": {"count": 200},
                             "others": others}))
    everyone = parse_show(doc({"name": "b", "hold_s": 2.0, "points": full}))
    t = time.perf_counter()
    plan = plan_show(subset)
    subset_s = time.perf_counter() - t
    t = time.perf_counter()
    plan_show(everyone)
    everyone_s = time.perf_counter() - t
    report = check_plan(plan)
    record_result({"drones": n, "flying": 200, "others": others, "ok": report.ok,
                   "min_distance_m": report.min_distance_m, "duration_s": plan.duration_s,
                   "resolutions": [t.resolution for t in plan.transitions],
                   "subset_over_all_plan_time": subset_s / everyone_s})
    assert report.ok, report.violations[:3]


def _check(doc: dict, path: Path) -> dict:
    """``swarmshow check --json`` on ``doc`` (written to ``path``): its report."""
    path.write_text(json.dumps(doc))
    clear_plan_cache()
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert cli_main(["check", "--json", str(path)]) in (0, 1)
    return dict(json.loads(out.getvalue()))


@pytest.mark.parametrize("others", ["park", "land", "swap", "sphere-swap", "sphere-park"])
def test_bench_random_groups_staged(others: str, record_result, tmp_path, monkeypatch) -> None:
    seeds = range(24)
    # The swap: the prepare-swap transition; "sphere-swap": 60 drones, a sphere, a random group on a tilted ring
    # (others land), a second random group on sphere points (the swap, from the tilted ring).
    into = {"swap": "again", "sphere-swap": "ring2", "sphere-park": "ring"}.get(others, "line")
    docs = {"sphere-swap": _ring_sphere_swap_doc, "sphere-park": sphere_park_doc}.get(
        others, lambda seed: random_group_doc(others, seed))
    safe = {"show": 0, "into": 0, "into_one_window": 0}
    staged_s: list[float] = []
    single_s: list[float] = []
    unsafe_seeds = []
    for seed in seeds:
        doc = docs(seed)
        report = _check(doc, tmp_path / "show.json")
        with monkeypatch.context() as m:  # the one-window plan: staging never kept
            m.setattr(_plan, "staged_subset", lambda *a, **k: (SimpleNamespace(unresolved=range(10**9)), None))
            single = _check(doc, tmp_path / "show.json")
        (ours,) = [b for b in report["by_transition"] if b["kind"] == "transition" and b["to"] == into]
        (theirs,) = [b for b in single["by_transition"] if b["kind"] == "transition" and b["to"] == into]
        safe["show"] += bool(report["ok"])
        safe["into"] += bool(ours["ok"] and not ours["unresolved"])
        safe["into_one_window"] += bool(theirs["ok"] and not theirs["unresolved"])
        if not report["ok"]:
            unsafe_seeds.append(seed)
        staged_s.append(ours["duration_s"])
        single_s.append(theirs["duration_s"])
    ratio = np.asarray(staged_s) / np.asarray(single_s)
    record_result({"others": others, "drones": len(doc["formations"][0]["points"]),
                   "group": "10-25 random" if others.startswith("sphere") else "10-40 random", "seeds": len(seeds),
                   "transition": into,
                   "safe_shows": safe["show"], "safe_transitions": safe["into"],
                   "safe_transitions_one_window": safe["into_one_window"], "unsafe_seeds": unsafe_seeds,
                   "transition_s_mean": float(np.mean(staged_s)),
                   "transition_s_one_window_mean": float(np.mean(single_s)),
                   "over_one_window_median": float(np.median(ratio)), "over_one_window_max": float(ratio.max())})
    assert safe["show"] == len(seeds)
