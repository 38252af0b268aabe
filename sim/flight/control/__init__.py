"""Controllers: the paper's position and attitude ISMC, attitude resolution and the PD baseline."""
