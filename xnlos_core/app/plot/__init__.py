"""Figures of runs and evaluations (matplotlib): frame panels, tracks, animations, the detector palette."""
