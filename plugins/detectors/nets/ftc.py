""""See Further Than CFAR" (Roldan et al. 2022) adapted to LOS / mNLOS: a data-driven detector.

A fully convolutional encoder–decoder trained with *per-cell binary* labels (a cell is positive
only where a ground-truth point falls) and the binary focal loss of Lin et al. (α = 0.25,
γ = 2), as in the original, which learned radar detections from lidar-labelled cells. Encoder:
strided residual blocks; decoder: bilinear up-sampling with additive skips (FPN-like).
Input (B, 4, H, W), H and W multiples of 2^levels; output logits (B, 2, H, W).
"""
from __future__ import annotations

import torch
import torch.nn.functional as F
from pydantic import BaseModel, ConfigDict, Field
from torch import nn

from ..features import N_FEATURES
from .blocks import ResBlock, conv_bn, head_bias_init


class FTCParams(BaseModel):
    """Hyper-parameters of :class:`FurtherThanCFAR`."""

    model_config = ConfigDict(extra="forbid")
    in_channels: int = Field(N_FEATURES, ge=1, le=64, description="input feature channels (plugins.detectors.features: 4 power-map channels, 7 with Doppler)")
    base_channels: int = Field(16, ge=2, le=128, description="channels at full resolution (doubled per level)")
    levels: int = Field(2, ge=1, le=4, description="stride-2 encoder stages")


class FurtherThanCFAR(nn.Module):
    """Features (B, 4, H, W) → per-cell logits (B, 2, H, W)."""

    def __init__(self, hp: FTCParams | None = None):
        super().__init__()
        hp = hp or FTCParams()
        self.hp = hp
        c = [hp.base_channels * 2**i for i in range(hp.levels + 1)]
        self.multiple = (2**hp.levels, 2**hp.levels)
        self.stem = conv_bn(hp.in_channels, c[0])
        self.enc = nn.ModuleList(ResBlock(c[i], c[i + 1], stride=2) for i in range(hp.levels))
        self.lateral = nn.ModuleList(nn.Conv2d(c[i], c[0], 1) for i in range(hp.levels + 1))
        self.out = conv_bn(c[0], c[0])
        self.head = nn.Conv2d(c[0], 2, 1)
        head_bias_init(self.head)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        feats = [self.stem(x)]
        for block in self.enc:
            feats.append(block(feats[-1]))
        y = self.lateral[-1](feats[-1])
        for i in reversed(range(len(feats) - 1)):
            y = F.interpolate(y, size=feats[i].shape[-2:], mode="bilinear", align_corners=False)
            y = y + self.lateral[i](feats[i])
        return self.head(self.out(y))
