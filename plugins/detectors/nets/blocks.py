"""Convolutional building blocks shared by the convolutional detectors (UNet, FTC, RTN)."""
from __future__ import annotations

import math

from torch import nn

PRIOR = 0.01  # initial foreground probability of a head (focal-loss initialisation, Lin et al. 2017)


def head_bias_init(conv: nn.Conv2d, channels: int | None = None, prior: float = PRIOR) -> None:
    """Set the bias of the first ``channels`` outputs (all by default) to logit(prior) so training
    starts from 'almost everything is background' instead of p = 0.5 (stabilises focal losses)."""
    n = conv.out_channels if channels is None else channels
    nn.init.constant_(conv.bias[:n], -math.log((1 - prior) / prior))


def conv_bn(cin: int, cout: int, stride: int | tuple[int, int] = 1) -> nn.Sequential:
    """3×3 convolution → BatchNorm → ReLU."""
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride=stride, padding=1, bias=False), nn.BatchNorm2d(cout),
                         nn.ReLU(inplace=True))


def double_conv(cin: int, cout: int) -> nn.Sequential:
    """Two 3×3 conv → BN → ReLU (the UNet unit)."""
    return nn.Sequential(conv_bn(cin, cout), conv_bn(cout, cout))


class ResBlock(nn.Module):
    """Basic residual block (ResNet): two 3×3 convs with an identity or 1×1 strided shortcut."""

    def __init__(self, cin: int, cout: int, stride: int | tuple[int, int] = 1):
        super().__init__()
        self.body = nn.Sequential(conv_bn(cin, cout, stride), nn.Conv2d(cout, cout, 3, padding=1, bias=False),
                                  nn.BatchNorm2d(cout))
        self.short = nn.Identity() if cin == cout and stride == 1 else nn.Sequential(
            nn.Conv2d(cin, cout, 1, stride=stride, bias=False), nn.BatchNorm2d(cout))
        self.act = nn.ReLU(inplace=True)

    def forward(self, x):
        return self.act(self.body(x) + self.short(x))
