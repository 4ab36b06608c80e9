"""Network architectures of the learned detectors: one file per architecture, a table to choose.

Each entry maps a detector name to (module class, hyper-parameter model, head kind). A module
takes features (B, 4, H, W) with H, W multiples of its ``multiple`` and returns raw outputs:
``"dense"`` heads give logits (B, 2, H, W) (LOS, mNLOS); the ``"grid"`` head gives
(B, 6, H/s_r, W/s_a): two class logits and per class a (range, azimuth) position logit pair.
"""
from __future__ import annotations

from typing import NamedTuple

from pydantic import BaseModel


class Architecture(NamedTuple):
    """A network family: its module class, hyper-parameter model and output head kind."""

    module: type
    HParams: type[BaseModel]
    head: str  # "dense" | "grid"


def architectures() -> dict[str, Architecture]:
    """name → Architecture for every learned detector (imported lazily: torch is heavy)."""
    from .ftc import FurtherThanCFAR, FTCParams
    from .rtn import RTN, RTNParams
    from .swin_unet import SwinUNet, SwinUNetParams
    from .unet import UNet, UNetParams

    return {
        "swin_unet": Architecture(SwinUNet, SwinUNetParams, "dense"),
        "unet": Architecture(UNet, UNetParams, "dense"),
        "further_than_cfar": Architecture(FurtherThanCFAR, FTCParams, "dense"),
        "rtn": Architecture(RTN, RTNParams, "grid"),
    }
