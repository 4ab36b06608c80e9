"""One palette for every figure and benchmark plot: a colour per detector plugin, per detection
class and per drawn role (truth, estimate, walls), and the drawing order (zorder) that puts the
ground truth above the reconstructions.

A detector keeps its colour in every plot (benchmarks/detectors.py curves, figure titles), the
built-in ones from :data:`DETECTOR_COLOURS`; any other name gets a stable colour from
:data:`EXTRA_COLOURS` chosen by a hash of the name (not Python's salted ``hash``), so a third-party
detector is coloured the same in every run. Colours are matplotlib colour names.
"""
from __future__ import annotations

import zlib

from xnlos_core.types import LOS, MNLOS, UNCLASSIFIED

#: Built-in detector plugins (registry name → colour): distinct from each other and from the
#: class and role colours below, so a curve never reads as a class of detection.
DETECTOR_COLOURS: dict[str, str] = {
    "cfar": "tab:blue",
    "nlos_cfar": "navy",
    "further_than_cfar": "tab:brown",
    "swin_unet": "tab:pink",
    "unet": "darkgoldenrod",
    "rtn": "teal",
    "oracle": "black",
    "peak_threshold": "slategray",
}
#: Colours for detectors not listed above, picked by a stable hash of the name.
EXTRA_COLOURS = ("indigo", "sienna", "olivedrab", "crimson", "dodgerblue", "darkslategray", "orchid", "peru")

#: Detection class → (legend name, colour, marker), the same in every RA-map and bird's-eye panel.
CLASS_STYLE: dict[int, tuple[str, str, str]] = {LOS: ("LOS", "tab:cyan", "o"), MNLOS: ("mNLOS", "tab:red", "x"),
                                                UNCLASSIFIED: ("unclassified", "gold", "s")}

TRUTH = "tab:green"          # true hidden points and the hidden objects' outlines
TRUE_WALL = "0.45"           # centre line of a true wall (over its wide light band)
TRUE_WALL_BAND = "0.8"
ESTIMATE = "tab:purple"      # reconstructed hidden points and their credible ellipses
WALL_ESTIMATE = "tab:orange"
UNOBSERVABLE = "0.35"

#: Drawing order, bottom to top: reconstructions under the ground truth, the radar on top.
Z_BAND = 1          # wide background bands (true walls), field-of-view lines
Z_ESTIMATE = 3      # fitted walls, posterior draws, reconstructed points, credible ellipses, detections
Z_TRUTH = 6         # true hidden points, object outlines, true-wall centre lines
Z_RADAR = 8


def detector_colour(name: str) -> str:
    """Colour of detector plugin ``name`` in every plot: its entry in :data:`DETECTOR_COLOURS`, else
    a stable pick from :data:`EXTRA_COLOURS` (CRC-32 of the name)."""
    if name in DETECTOR_COLOURS:
        return DETECTOR_COLOURS[name]
    return EXTRA_COLOURS[zlib.crc32(name.encode()) % len(EXTRA_COLOURS)]
