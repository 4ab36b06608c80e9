"""The optimiser every learned component trains with: AdamW, gradient-norm clipping, a cosine
learning-rate schedule (with optional linear warm-up) and early stopping on a validation metric.

:class:`OptimConfig` is the ``[optim]`` table of a training config. Each trainer subclasses it to
set its own defaults (``DEFAULTS``; the residual mirror trains on batches of 256 point pairs, a
detector on batches of 8 maps) and to add keys only it reads; the bounds are written once here.

Schedule: lr(step) = lr · f(step) with f = (step + 1)/warmup during the warm-up, then
f = 0.02 + 0.98 · ½ (1 + cos(π t)), t = (step − warmup)/(total − warmup) clipped to 1: a cosine
from lr down to 2 % of lr over the run's ``total`` optimizer steps (epochs × steps per epoch).
The schedule therefore depends on ``optim.epochs``: a run extended with a larger ``--epochs``
resumes at its step count on the cosine of the new total (:mod:`.run`).
"""
from __future__ import annotations

import math
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, Field, model_validator


class OptimConfig(BaseModel):
    """``[optim]``: AdamW with a cosine learning-rate schedule and early stopping."""

    model_config = ConfigDict(extra="forbid")
    DEFAULTS: ClassVar[dict[str, Any]] = {}  # a trainer's own defaults for the fields below

    epochs: int = Field(30, ge=1, le=100_000, description="epochs of the run (a rerun with more extends it)")
    batch_size: int = Field(8, ge=1, le=1_000_000)
    lr: float = Field(2e-3, gt=0, le=1, description="peak learning rate")
    weight_decay: float = Field(1e-4, ge=0, le=1, description="AdamW weight decay")
    grad_clip: float = Field(5.0, gt=0, le=1e6, description="gradient-norm clip")
    patience: int = Field(6, ge=1, le=100_000, description="early stopping: validations without a better metric")

    @model_validator(mode="before")
    @classmethod
    def _trainer_defaults(cls, data: Any) -> Any:
        return {**cls.DEFAULTS, **data} if isinstance(data, dict) else data


def lr_factor(warmup: int, total: int):
    """f(step) of the module doc (plain floats, so the scheduler's state loads with weights_only)."""
    def f(step: int) -> float:
        if step < warmup:
            return (step + 1) / warmup
        t = min(1.0, (step - warmup) / max(1, total - warmup))
        return 0.02 + 0.98 * 0.5 * (1.0 + math.cos(math.pi * t))
    return f


def make_optimizer(net, optim: OptimConfig, total_steps: int, warmup_steps: int = 0):
    """(AdamW over ``net``'s parameters, its cosine LambdaLR over ``total_steps``)."""
    import torch

    opt = torch.optim.AdamW(net.parameters(), lr=optim.lr, weight_decay=optim.weight_decay)
    return opt, torch.optim.lr_scheduler.LambdaLR(opt, lr_factor(warmup_steps, total_steps))


def step(loss, net, opt, sched, grad_clip: float) -> None:
    """One optimizer step on ``loss``: backward, clip the gradient norm, AdamW, schedule. Then torch's
    threads follow the cores other processes leave free for the next step
    (:func:`xnlos_core.core_share.adapt_torch_threads`)."""
    import torch

    from xnlos_core.core_share import adapt_torch_threads

    opt.zero_grad(set_to_none=True)
    loss.backward()
    torch.nn.utils.clip_grad_norm_(net.parameters(), grad_clip)
    opt.step()
    sched.step()
    adapt_torch_threads()
