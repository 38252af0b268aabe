"""Robustness of the controller under the realistic error models (issue 20).

The Monte-Carlo runs of a 12-drone ring-to-sphere show with the "gusty-rtk" preset once lost
a drone (a runaway near the end of the 81 s show): at 65 m the mean wind is ~10 m/s, the
tilt limiter engaged for tens of seconds, and while it did the attitude loop's disturbance
estimate u_d was frozen too (the limiter counted as a rotor saturation), its sliding
variable wound up, and after the release the attitude loop ran away (seed 3, drone 7 at
t = 81 s on main at the time). Every seed of that show must fly without a divergence.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim.flight import FlightOptions, error_preset, fly_show


@pytest.mark.parametrize("seeds", [range(0, 10), range(10, 20)])
def test_gusty_rtk_flies_every_seed(plan12, seeds) -> None:
    worst = []
    for seed in seeds:
        flight = fly_show(plan12, FlightOptions(errors=error_preset("gusty-rtk"), seed=seed, flown_distance=False))
        assert flight.diverged == [], f"seed {seed}: {flight.diverged}"
        worst.append(float(np.max(flight.tracking_max_m)))
    # Gusts of up to ~15 m/s at 45-70 m need more than the 34° tilt limit (drag 7.7 m/s² at
    # 15 m/s): a drone is blown off by metres there (seed 3: 7.3 m) and comes back; it must
    # not run away (the old anti-windup lost drone 7 of seed 3 at 25 m).
    assert max(worst) < 10.0, worst
