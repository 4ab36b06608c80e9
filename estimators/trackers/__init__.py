"""Trackers: hidden points of successive frames → tracks (α–β ``nearest``, Kalman ``kalman``) and
motion identification with ensemble SINDy (``sindy_model``)."""
