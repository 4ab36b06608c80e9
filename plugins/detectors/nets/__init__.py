"""Network architectures of the learned detectors: one file per architecture, a table to choose.

Each entry maps a detector name to (module class, hyper-parameter model, head kind). A module
takes features (B, 4, H, W) with H, W multiples of its ``multiple`` and returns raw outputs:
``"dense"`` heads give logits (B, 2, H, W) (LOS, mNLOS); the ``"grid"`` head gives
(B, 6, H/s_r, W/s_a): two class logits and per class a (range, azimuth) position logit pair.
"""
from __future__ import annotations

from typing import Any, NamedTuple

from pydantic import BaseModel

from xnlos_core.errors import InputError


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


def build_model(metadata: dict[str, Any], state_dict: dict | None = None, source: str = "checkpoint"):
    """The network described by ``metadata`` (architecture + hparams), with ``state_dict`` loaded."""
    archs = architectures()
    name = metadata.get("architecture")
    if name not in archs:
        raise InputError(f"{source}: unknown architecture {name!r}; known: {', '.join(archs)}")
    arch = archs[name]
    try:
        hp = arch.HParams.model_validate(metadata.get("hparams", {}))
    except ValueError as exc:
        raise InputError(f"{source}: invalid hyper-parameters for {name!r}: {exc}") from None
    model = arch.module(hp)
    if state_dict is not None:
        try:
            model.load_state_dict(state_dict, strict=True)
        except RuntimeError as exc:
            first = str(exc).splitlines()[0] if str(exc) else ""
            raise InputError(f"{source}: weights do not fit a {name!r} network with hparams "
                             f"{hp.model_dump()} ({first})") from None
    return model
