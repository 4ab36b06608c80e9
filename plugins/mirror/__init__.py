"""Reconstructor plugins: hidden points from mNLOS detections and relay walls (Eq. 7)."""
