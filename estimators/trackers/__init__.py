"""Trackers: hidden points of successive frames → tracks (α–β ``nearest``; more models to come)."""
