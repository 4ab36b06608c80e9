"""Focal losses: the penalty-reduced heatmap focal loss of Eq. 8 and the binary focal loss.

Both take logits z (the network output before the Sigmoid) so that log c = log σ(z) and
log(1 − c) = log σ(−z) stay finite for any z (no log 0 at saturated confidences).
"""
from __future__ import annotations

import torch
import torch.nn.functional as F


def heatmap_focal_loss(logits: torch.Tensor, target: torch.Tensor, alpha: float = 2.0,
                       beta: float = 4.0) -> torch.Tensor:
    """Eq. 8:  L = −(1/N) Σ_{x,y,k} { (1 − c)^α log c                 if Y = 1,
                                      (1 − Y)^β c^α log(1 − c)       otherwise },

    c = σ(logits), Y = ``target`` ∈ [0, 1] of the same shape (any, e.g. (B, 2, H, W)); N = the
    number of cells with Y = 1 exactly (the ground-truth peaks, summed over the batch). With
    no positive at all N is taken as 1, so the loss is the plain sum of the negative terms
    (defined, finite, and still pushing false confidences down). Returns a scalar.
    """
    z = logits.float()
    y = target.float()
    pos = y.eq(1.0)
    c = torch.sigmoid(z)
    log_c, log_1mc = F.logsigmoid(z), F.logsigmoid(-z)
    pos_term = (1.0 - c).pow(alpha) * log_c
    neg_term = (1.0 - y).pow(beta) * c.pow(alpha) * log_1mc
    total = torch.where(pos, pos_term, neg_term).sum()
    n = pos.sum().clamp(min=1).to(total.dtype)
    return -total / n


def binary_focal_loss(logits: torch.Tensor, target: torch.Tensor, alpha: float = 0.25,
                      gamma: float = 2.0) -> torch.Tensor:
    """Binary focal loss (Lin et al. 2017) per cell, summed and divided by the number of positive
    cells (≥ 1):  FL = −α_t (1 − p_t)^γ log p_t,  p_t = c if Y = 1 else 1 − c,
    α_t = α if Y = 1 else 1 − α. ``target`` is 0/1 (cells ≥ 0.5 count as positive)."""
    z = logits.float()
    y = (target.float() >= 0.5).float()
    ce = F.binary_cross_entropy_with_logits(z, y, reduction="none")  # = −log p_t
    p_t = torch.exp(-ce)
    a_t = alpha * y + (1.0 - alpha) * (1.0 - y)
    total = (a_t * (1.0 - p_t).pow(gamma) * ce).sum()
    return total / y.sum().clamp(min=1.0)
