"""Mesh import benchmark (issue 21): ``pytest -m slow benchmarks/bench_mesh.py``.

2,000 drones sampled evenly over the surface of a 100,000-face mesh (a torus of 500 x 100 quads,
written to GLB, read back and sampled at the size that fits 2,000 at 3 m). Target: <= 5 s.
Baseline in the same run, on the same mesh: trimesh's own ``sample_surface_even`` (random
samples thinned by a radius; it returns *about* N points, not exactly N, with no size search).
CPU time (``time.process_time``) is quoted besides wall time because the machine is shared.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from formations.sources import mesh_points

pytestmark = pytest.mark.slow

DRONES = 2000
SPACING_M = 3.0
TARGET_S = 5.0


def test_surface_2000_of_100k_faces(record_result):
    mesh = trimesh.creation.torus(major_radius=2.0, minor_radius=0.7, major_sections=500, minor_sections=100)
    assert len(mesh.faces) == 100_000
    data = mesh.export(file_type="glb")

    wall0, cpu0 = time.perf_counter(), time.process_time()
    points, size_m = mesh_points(data, DRONES, file_type="glb", mode="surface", size_m=None,
                                 min_spacing_m=SPACING_M)
    ours_wall, ours_cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    d, _ = cKDTree(points.points_m).query(points.points_m, k=2)
    assert len(points) == DRONES and d[:, 1].min() >= SPACING_M

    # Baseline: trimesh's even sampling of the same mesh (parsed once more, as ours does) at the
    # radius ours reached, scaled into the same units.
    wall0, cpu0 = time.perf_counter(), time.process_time()
    again = trimesh.load(trimesh.util.wrap_as_stream(data), file_type="glb", force="mesh", process=False)
    scale = size_m / float(np.ptp(again.vertices, axis=0).max())
    base, _ = trimesh.sample.sample_surface_even(again, DRONES, radius=SPACING_M / scale, seed=0)
    base_wall, base_cpu = time.perf_counter() - wall0, time.process_time() - cpu0

    nn = d[:, 1]
    figures = {
        "drones": DRONES, "faces": len(mesh.faces), "min_spacing_m": SPACING_M, "size_m": round(size_m, 3),
        "wall_s": round(ours_wall, 3), "cpu_s": round(ours_cpu, 3), "target_s": TARGET_S,
        "nearest_neighbour_mean_over_min": round(float(nn.mean() / SPACING_M), 3),
        "baseline": "trimesh.sample.sample_surface_even at the same radius (about N points, not exactly N)",
        "baseline_points": len(base), "baseline_wall_s": round(base_wall, 3), "baseline_cpu_s": round(base_cpu, 3),
        "cpu_ratio_ours_over_baseline": round(ours_cpu / max(base_cpu, 1e-9), 2),
    }
    record_result(figures)
    assert ours_cpu <= TARGET_S, figures
