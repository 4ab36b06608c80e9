"""A third-party detector: local maxima a fixed margin above the median power, all LOS-or-mNLOS
by a range split. Written only against the public xnlos_core API."""
import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.ndimage import maximum_filter

from xnlos_core import LOS, MNLOS, Detections, Detector, hookimpl


class PeakThresholdDetector(Detector):
    """Local maxima ``margin_db`` above the median power; mNLOS beyond ``split_range`` [m]."""

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")
        margin_db: float = Field(20.0, gt=0, le=100, description="threshold above the median [dB]")
        split_range: float = Field(35.0, gt=0, description="detections beyond this range are mNLOS [m]")

    def detect(self, frame):
        ra = frame.ra_map
        p = ra.power
        thr = np.median(p) * 10 ** (self.params.margin_db / 10)
        peaks = (p == maximum_filter(p, size=3)) & (p > thr) & (p > 0)
        i, j = np.nonzero(peaks)
        if not len(i):
            return Detections.empty()
        r, a = ra.range_axis[i], ra.azimuth_axis[j]
        label = np.where(r > self.params.split_range, MNLOS, LOS).astype(np.int8)
        conf = 1.0 - thr / p[i, j]
        return Detections(r, a, label, conf)


@hookimpl
def xnlos_register_components(registry):
    registry.add("detector", "peak_threshold", PeakThresholdDetector)
