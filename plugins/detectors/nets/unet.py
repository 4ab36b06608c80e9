"""UNet (Ronneberger et al. 2015): the paper's "Proposed + UNet" ablation (Table 2).

The Swin-UNet backbone replaced by a convolutional UNet; the same two-channel head, Gaussian
targets and Eq. 8 focal loss. Levels of two 3×3 conv-BN-ReLU, 2×2 max-pool down, transposed
convolution up, concatenated skips. Input (B, 4, H, W), H and W multiples of 2^levels; output
logits (B, 2, H, W).
"""
from __future__ import annotations

import torch
from pydantic import BaseModel, ConfigDict, Field
from torch import nn

from ..features import N_FEATURES
from .blocks import double_conv, head_bias_init


class UNetParams(BaseModel):
    """Hyper-parameters of :class:`UNet`."""

    model_config = ConfigDict(extra="forbid")
    in_channels: int = Field(N_FEATURES, ge=1, le=64, description="input feature channels (plugins.detectors.features: 4 power-map channels, 7 with Doppler)")
    base_channels: int = Field(12, ge=2, le=128, description="channels of the first level (doubled per level)")
    levels: int = Field(3, ge=1, le=5, description="down-sampling steps")


class UNet(nn.Module):
    """Features (B, 4, H, W) → logits (B, 2, H, W)."""

    def __init__(self, hp: UNetParams | None = None):
        super().__init__()
        hp = hp or UNetParams()
        self.hp = hp
        c = [hp.base_channels * 2**i for i in range(hp.levels + 1)]
        self.multiple = (2**hp.levels, 2**hp.levels)
        self.down = nn.ModuleList([double_conv(hp.in_channels, c[0])] + [double_conv(c[i], c[i + 1]) for i in range(hp.levels)])
        self.pool = nn.MaxPool2d(2)
        self.up = nn.ModuleList(nn.ConvTranspose2d(c[i + 1], c[i], 2, stride=2) for i in range(hp.levels))
        self.dec = nn.ModuleList(double_conv(2 * c[i], c[i]) for i in range(hp.levels))
        self.head = nn.Conv2d(c[0], 2, 1)
        head_bias_init(self.head)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        skips = []
        for i, block in enumerate(self.down):
            x = block(x if i == 0 else self.pool(x))
            skips.append(x)
        x = skips.pop()
        for i in reversed(range(len(self.up))):
            x = self.dec[i](torch.cat([self.up[i](x), skips[i]], 1))
        return self.head(x)
