"""Backend plugin: the maps of an `xnlos simulate` dataset split, with ground truth, as frames."""
