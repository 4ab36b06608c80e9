"""Output heads: how a network's raw output is supervised (targets + loss) and read (peaks).

* ``gaussian`` (Swin-UNet, UNet): dense logits (B, 2, H, W), Gaussian heatmap targets and the
  penalty-reduced focal loss of Eq. 8; peaks refined with the Gaussian log-ratio.
* ``binary`` ("See Further Than CFAR"): dense logits, one positive cell per point and the binary
  focal loss; peaks refined parabolically.
* ``grid`` (RTN): (B, 6, H/s_r, W/s_a) class logits and in-cell positions; binary focal loss on
  the occupancy plus L1 on the positions of occupied cells.

A head is described by a JSON-able dict (stored in checkpoints) and rebuilt by :func:`make_head`.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from . import decode
from .focal import binary_focal_loss, heatmap_focal_loss
from .heatmaps import binary_cells, gaussian_heatmap, grid_targets


class DenseHead:
    """Dense LOS / mNLOS logits at map resolution."""

    def __init__(self, target: str = "gaussian", sigma: tuple[float, float] = (1.0, 1.5)):
        if target not in ("gaussian", "binary"):
            raise ValueError(f"dense head target {target!r}: expected 'gaussian' or 'binary'")
        self.target, self.sigma = target, (float(sigma[0]), float(sigma[1]))
        # sub-bin refinement of peaks (decode.refine): exact for Gaussian targets, generic otherwise
        self.refine = "gaussian" if target == "gaussian" else "parabolic"

    def describe(self) -> dict[str, Any]:
        return {"kind": "dense", "target": self.target, "sigma": list(self.sigma)}

    def targets(self, peaks: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        """Targets (2, H, W) of peaks (P, 3) (see :mod:`.heatmaps`)."""
        if self.target == "gaussian":
            return gaussian_heatmap(peaks, shape, self.sigma)
        return binary_cells(peaks, shape)

    def loss(self, out: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        if self.target == "gaussian":
            return heatmap_focal_loss(out, target)
        return binary_focal_loss(out, target)

    def crop(self, out: torch.Tensor, shape: tuple[int, int]) -> torch.Tensor:
        return out[..., : shape[0], : shape[1]]

    def peaks(self, out: np.ndarray, threshold: float, window: tuple[int, int], class_nms: bool, max_peaks: int):
        """(fractional rows, fractional cols, class, confidence) of one output (2, H, W)."""
        return decode.dense_peaks(out, threshold, window, class_nms, max_peaks, self.refine, self.sigma)


class GridHead:
    """One object per grid cell and class at output stride (s_r, s_a)."""

    def __init__(self, stride: tuple[int, int] = (2, 2), offset_weight: float = 1.0):
        self.stride = (int(stride[0]), int(stride[1]))
        self.offset_weight = float(offset_weight)

    def describe(self) -> dict[str, Any]:
        return {"kind": "grid", "stride": list(self.stride), "offset_weight": self.offset_weight}

    def targets(self, peaks: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        return grid_targets(peaks, shape, self.stride)

    def loss(self, out: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        cls = binary_focal_loss(out[:, :2], target[:, :2])
        occ = target[:, :2] >= 0.5
        pos = torch.sigmoid(out[:, 2:]).view(out.shape[0], 2, 2, *out.shape[-2:])
        tgt = target[:, 2:].view_as(pos)
        mask = occ.unsqueeze(2).expand_as(pos)
        l1 = F.l1_loss(pos[mask], tgt[mask], reduction="sum") / occ.sum().clamp(min=1)
        return cls + self.offset_weight * l1

    def crop(self, out: torch.Tensor, shape: tuple[int, int]) -> torch.Tensor:
        return out  # grid cells beyond the map are dropped when peaks are mapped back

    def peaks(self, out: np.ndarray, threshold: float, window: tuple[int, int], class_nms: bool, max_peaks: int):
        return decode.grid_peaks(out, self.stride, threshold, class_nms, max_peaks)


def make_head(spec: dict[str, Any]):
    """A head from its ``describe()`` dict."""
    kind = spec.get("kind")
    if kind == "dense":
        return DenseHead(spec.get("target", "gaussian"), tuple(spec.get("sigma", (1.0, 1.5))))
    if kind == "grid":
        return GridHead(tuple(spec.get("stride", (2, 2))), spec.get("offset_weight", 1.0))
    raise ValueError(f"head kind {kind!r}: expected 'dense' or 'grid'")


def default_head(architecture: str, hparams, sigma: tuple[float, float] = (1.0, 1.5)):
    """The head each architecture is trained with (the paper's setup for each baseline)."""
    if architecture in ("swin_unet", "unet"):
        return DenseHead("gaussian", sigma)
    if architecture == "further_than_cfar":
        return DenseHead("binary", sigma)
    if architecture == "rtn":
        return GridHead(tuple(hparams.stride))
    raise ValueError(f"no head for architecture {architecture!r}")
