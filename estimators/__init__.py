"""Relay-wall estimators (one module each) and motion trackers (:mod:`estimators.trackers`)."""
