"""Forward models: scenes rendered into RA maps with ground truth."""
