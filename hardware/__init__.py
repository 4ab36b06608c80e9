"""Hardware backends: sources of measured frames."""
