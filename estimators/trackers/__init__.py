"""Trackers: hidden points of successive frames → tracks (α–β ``nearest``, Kalman ``kalman``) and
motion identification (``sindy``): over a manoeuvre library, batched over tracks (the ``library``
package; ``motion_library`` re-exports its names), or with ensemble SINDy (``sindy_model``)."""
