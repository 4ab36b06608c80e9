"""Learned and classical detectors and mirror reconstructors (plugin implementations)."""
