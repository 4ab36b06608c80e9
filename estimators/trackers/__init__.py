"""Trackers: hidden points of successive frames → tracks (α–β ``nearest``, Kalman ``kalman``) and
motion identification (``sindy``): over a manoeuvre library, batched over tracks (``motion_library``),
or with ensemble SINDy (``sindy_model``)."""
