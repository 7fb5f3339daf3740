"""Tools around the simulation: the `lander` command line, launcher, recorder, analysis, sweeps."""
