"""Relay-wall estimators and motion trackers."""
