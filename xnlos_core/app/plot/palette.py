"""One palette for every figure and benchmark plot: a colour per detector plugin, per detection
class and per drawn role (truth, estimate, walls), and the drawing order (zorder) that puts the
ground truth above the reconstructions.

A detector keeps its colour in every plot (benchmarks/detectors.py curves, figure titles), the
built-in ones from :data:`DETECTOR_COLOURS`; any other name gets a stable colour from
:data:`EXTRA_COLOURS` chosen by a hash of the name (not Python's salted ``hash``), so a third-party
detector is coloured the same in every run. Colours are matplotlib colour names.

Distinct means distinct to the eye: every two detector colours (built-in and extra) and every
detector colour and class or role colour differ by at least :data:`MIN_DELTA_E` in CIELAB
(ΔE*ab, CIE 1976, :func:`delta_e`); a plot that shows several series at once takes its colours
from :func:`distinct_colours`, which keeps that distance even when two names hash to one colour.
"""
from __future__ import annotations

import zlib
from collections.abc import Mapping

import numpy as np

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
EXTRA_COLOURS = ("darkorchid", "dodgerblue", "olivedrab", "deeppink", "darkslateblue", "sienna", "lightcoral",
                 "darkmagenta")
#: Least CIELAB distance ΔE*ab between two colours that must read as different series (≈ 2.3 is a
#: just-noticeable difference; 20 tells two thin lines apart at a glance).
MIN_DELTA_E = 20.0

#: Detection class → (legend name, colour, marker), the same in every RA-map and bird's-eye panel.
CLASS_STYLE: dict[int, tuple[str, str, str]] = {LOS: ("LOS", "tab:cyan", "o"), MNLOS: ("mNLOS", "tab:red", "x"),
                                                UNCLASSIFIED: ("unclassified", "gold", "s")}

TRUTH = "tab:green"          # true hidden points and the hidden objects' outlines
TRUE_WALL = "0.45"           # centre line of a true wall (over its wide light band)
TRUE_WALL_BAND = "0.8"
WALL_DRAWS = "saddlebrown"  # posterior draws of a sampled wall, over its (orange) mean
ESTIMATE = "tab:purple"      # reconstructed hidden points and their credible ellipses
WALL_ESTIMATE = "tab:orange"
UNOBSERVABLE = "0.35"

#: Drawing order, bottom to top: reconstructions under the ground truth, the radar on top.
Z_BAND = 1          # wide background bands (true walls), field-of-view lines
Z_DETECTION = 2     # detections in the bird's-eye view: under the walls fitted through them
Z_ESTIMATE = 3      # fitted walls, posterior draws, reconstructed points, credible ellipses
Z_TRUTH = 6         # true hidden points, object outlines, true-wall centre lines
Z_RADAR = 8


def detector_colour(name: str) -> str:
    """Colour of detector plugin ``name`` in every plot: its entry in :data:`DETECTOR_COLOURS`, else
    a stable pick from :data:`EXTRA_COLOURS` (CRC-32 of the name)."""
    if name in DETECTOR_COLOURS:
        return DETECTOR_COLOURS[name]
    return EXTRA_COLOURS[zlib.crc32(name.encode()) % len(EXTRA_COLOURS)]


#: sRGB (D65) linear RGB → CIE XYZ, IEC 61966-2-1.
_RGB_TO_XYZ = np.array([[0.4124564, 0.3575761, 0.1804375],
                        [0.2126729, 0.7151522, 0.0721750],
                        [0.0193339, 0.1191920, 0.9503041]])
_WHITE_D65 = np.array([0.95047, 1.0, 1.08883])


def cielab(colour) -> np.ndarray:
    """CIE 1976 L*a*b* (3,) of a matplotlib colour, sRGB with the D65 white (L* in [0, 100]).

    Written out because matplotlib converts only to RGB/HSV and scikit-image is not a dependency:
    sRGB decoding (IEC 61966-2-1), the linear map to XYZ, then L* = 116 f(Y/Yₙ) − 16,
    a* = 500 (f(X/Xₙ) − f(Y/Yₙ)), b* = 200 (f(Y/Yₙ) − f(Z/Zₙ)) with f(t) = t^(1/3) above (6/29)³
    and t/(3·(6/29)²) + 4/29 below."""
    from matplotlib.colors import to_rgb

    rgb = np.asarray(to_rgb(colour), float)
    lin = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    t = _RGB_TO_XYZ @ lin / _WHITE_D65
    d = 6.0 / 29.0
    f = np.where(t > d ** 3, np.cbrt(t), t / (3 * d * d) + 4.0 / 29.0)
    return np.array([116.0 * f[1] - 16.0, 500.0 * (f[0] - f[1]), 200.0 * (f[1] - f[2])])


def delta_e(a, b) -> float:
    """CIE 1976 colour difference ΔE*ab: the Euclidean distance of two colours in CIELAB."""
    return float(np.linalg.norm(cielab(a) - cielab(b)))


def distinct_colours(preferred: Mapping[str, str], min_delta_e: float = MIN_DELTA_E) -> dict[str, str]:
    """Key → colour for series drawn together, in the order given: each key keeps its ``preferred``
    colour (e.g. :func:`detector_colour` of its detector) when that is at least ``min_delta_e`` from
    every colour already given, else takes the first colour of :data:`DETECTOR_COLOURS` then
    :data:`EXTRA_COLOURS` that is; once none is left, the candidate farthest from those given."""
    pool = list(dict.fromkeys([*DETECTOR_COLOURS.values(), *EXTRA_COLOURS]))
    out: dict[str, str] = {}
    for key, want in preferred.items():
        def gap(c):
            return min((delta_e(c, t) for t in out.values()), default=np.inf)
        if gap(want) < min_delta_e:
            want = next((c for c in pool if gap(c) >= min_delta_e), None) or max(pool, key=gap)
        out[key] = want
    return out
