"""The simulated linear-motor axis: plant, controller, trajectories, scenarios."""
