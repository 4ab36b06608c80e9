"""RTN: a radar-tensor detection network (RTNH of the K-Radar benchmark, Paek et al. 2022)
adapted, as the paper did, from object detection to LOS / mNLOS point detection.

An object detector on a grid: a ResNet backbone down to stride (s_r, s_a), a context stage that
fuses a coarser scale, and a detection head per grid cell — two class logits ("a LOS / an mNLOS
point lies in this cell") and per class a 2-D position regression (logits of the point's
position inside the cell, in [0, 1) of a cell after a sigmoid). Each cell holds at most one point
per class, which is why closely spaced peaks merge (the failure mode the paper reports). Trained
with the binary focal loss on the class logits and an L1 loss on the offsets of occupied cells.

The default stride (1, 2) keeps the grid no coarser than the radar's resolution cell (one range
bin δr = c/2B; two 1° azimuth bins against a 4° beamwidth), the density at which ground truth
is defined. A coarser grid caps recall whatever the network learns: keeping one ground-truth
point per grid cell scores F1 0.82 / 0.81 (LOS / mNLOS, 96 val maps of the default dataset) at
stride (2, 2), 0.94 / 0.94 at (1, 2).
Input (B, 4, H, W), H and W multiples of the stride; output (B, 6, H/s_r, W/s_a).
"""
from __future__ import annotations

import torch
import torch.nn.functional as F
from pydantic import BaseModel, ConfigDict, Field
from torch import nn

from ..features import N_FEATURES
from .blocks import ResBlock, conv_bn, head_bias_init


class RTNParams(BaseModel):
    """Hyper-parameters of :class:`RTN`."""

    model_config = ConfigDict(extra="forbid")
    in_channels: int = Field(N_FEATURES, ge=1, le=64, description="input feature channels (plugins.detectors.features: 4 power-map channels, 7 with Doppler)")
    base_channels: int = Field(16, ge=2, le=128, description="channels of the first stage (doubled per stage)")
    stride: tuple[int, int] = Field((1, 2), description="output grid stride (range, azimuth) [bins]; "
                                                       "powers of two (module doc: keep it within a "
                                                       "resolution cell)")

    def model_post_init(self, _ctx) -> None:
        for s in self.stride:
            if s < 1 or s & (s - 1) or s > 16:
                raise ValueError(f"stride {self.stride}: each entry must be a power of two in 1…16")


def _strides(stride: tuple[int, int]) -> list[tuple[int, int]]:
    """Per-stage (range, azimuth) strides: halve each axis until it reaches its target stride."""
    out, (r, a) = [], stride
    while r > 1 or a > 1:
        out.append((2 if r > 1 else 1, 2 if a > 1 else 1))
        r, a = max(r // 2, 1), max(a // 2, 1)
    return out


class RTN(nn.Module):
    """Features (B, 4, H, W) → (B, 6, H/s_r, W/s_a): logits LOS, mNLOS; position logits (range,
    azimuth) of the LOS and of the mNLOS point in each cell."""

    def __init__(self, hp: RTNParams | None = None):
        super().__init__()
        hp = hp or RTNParams()
        self.hp = hp
        self.stride = tuple(hp.stride)
        self.multiple = self.stride
        c = hp.base_channels
        self.stem = conv_bn(hp.in_channels, c)
        stages, cin = [], c
        for i, s in enumerate(_strides(self.stride)):
            stages.append(ResBlock(cin, c * 2 ** (i + 1), s))
            cin = c * 2 ** (i + 1)
        self.stages = nn.ModuleList(stages)
        self.context = nn.Sequential(ResBlock(cin, 2 * cin, 2), ResBlock(2 * cin, 2 * cin, 2))  # receptive field
        self.neck = nn.Conv2d(2 * cin, cin, 1)
        self.head = nn.Sequential(conv_bn(cin, cin), nn.Conv2d(cin, 6, 1))
        head_bias_init(self.head[-1], channels=2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.stem(x)
        for stage in self.stages:
            y = stage(y)
        ctx = self.neck(self.context(y))
        y = y + F.interpolate(ctx, size=y.shape[-2:], mode="bilinear", align_corners=False)
        return self.head(y)
