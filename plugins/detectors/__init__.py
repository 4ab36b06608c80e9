"""Detector plugins: peaks in RA maps classified LOS / mNLOS."""
