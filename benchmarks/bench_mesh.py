"""Mesh import benchmark (issue 21): ``pytest -m slow benchmarks/bench_mesh.py``.

2,000 drones sampled evenly over the surface of a 100,000-face mesh (a torus of 500 x 100 quads,
written to GLB, read back and sampled at the size that fits 2,000 at 3 m). Target: <= 5 s.
Baseline in the same run, on the same mesh: trimesh's own ``sample_surface_even`` (random
samples thinned by a radius; it returns *about* N points, not exactly N, with no size search).
CPU time (``time.process_time``) is quoted besides wall time because the machine is shared.
Packing density N (sqrt(3)/2) d_min^2 / area (1 = the hexagonal packing) is recorded for ours and
for the farthest-point picks alone (the method before the surface relaxation), same candidates.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from formations._mesh import _box_centre, load_mesh, pick_points, surface_candidates
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

    # Before: the farthest-point picks alone, on the same unit-sized candidates.
    cpu0 = time.process_time()
    loaded = load_mesh(data, "glb")
    extent = float(np.ptp(loaded.vertices, axis=0).max())
    unit = replace(loaded, vertices=loaded.vertices / extent)
    cand, cols = surface_candidates(unit, 100_000)
    fps, fps_size_m = pick_points(cand, cols, DRONES, min_spacing_m=SPACING_M, scale=None, extent=1.0,
                                  center_m=np.zeros(3), origin=_box_centre(unit.vertices), what="fps")
    fps_cpu = time.process_time() - cpu0
    area_m2 = {k: float(mesh.area) * (sz / extent) ** 2 for k, sz in (("ours", size_m), ("fps", fps_size_m))}

    def density(pts: np.ndarray, area: float) -> float:
        dd, _ = cKDTree(pts).query(pts, k=2)
        return float(len(pts) * np.sqrt(3) / 2 * dd[:, 1].min() ** 2 / area)

    nn = d[:, 1]
    figures = {
        "drones": DRONES, "faces": len(mesh.faces), "min_spacing_m": SPACING_M, "size_m": round(size_m, 3),
        "wall_s": round(ours_wall, 3), "cpu_s": round(ours_cpu, 3), "target_s": TARGET_S,
        "nearest_neighbour_mean_over_min": round(float(nn.mean() / SPACING_M), 3),
        "baseline": "trimesh.sample.sample_surface_even at the same radius (about N points, not exactly N)",
        "baseline_points": len(base), "baseline_wall_s": round(base_wall, 3), "baseline_cpu_s": round(base_cpu, 3),
        "cpu_ratio_ours_over_baseline": round(ours_cpu / max(base_cpu, 1e-9), 2),
        "density_ours": round(density(points.points_m, area_m2["ours"]), 3),
        "density_farthest_point_only": round(density(fps.points_m, area_m2["fps"]), 3),
        "size_ratio_farthest_point_over_ours": round(fps_size_m / size_m, 3),
        "cpu_ratio_ours_over_farthest_point_only": round(ours_cpu / max(fps_cpu, 1e-9), 2),
    }
    record_result(figures)
    assert ours_cpu <= TARGET_S, figures
