"""Searches over a scenario's settings by running the engines: the gait's phase timing
(:mod:`frogsim.optimize.gait`)."""
