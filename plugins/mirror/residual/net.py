"""The residual network Δo_θ (Eq. 7): attention over the LOS points of the anchored wall, and the
losses it is trained with (Eq. 9 plus a Laplace likelihood for its uncertainty).

Architecture ``residual_mirror`` (:class:`ResidualAttention`, ~5 k parameters with the defaults):
the query (features of o' and ô in the wall frame, :mod:`.features`) and each neighbouring LOS
point are embedded by two-layer MLPs; multi-head scaled dot-product attention of the query over
the neighbours plus a learned "no neighbour" token aggregates the wall's local shape; an MLP on
[query embedding, aggregate] outputs the residual (Δu, Δn) and the log Laplace scales (log s_u,
log s_n), all in the local frame (u_q, n_q) in units of SCALE. The last layer starts at zero, so
an untrained network is the analytic mirror with scale SCALE·e^{log_scale_init}.
"""
from __future__ import annotations

import math

import torch
from pydantic import BaseModel, ConfigDict, Field
from torch import nn

from .features import SCALE

ARCHITECTURE = "residual_mirror"
N_QUERY, N_POINT = 12, 5  # input features per query / neighbour (:mod:`.features`)


class HParams(BaseModel):
    """Hyper-parameters of :class:`ResidualAttention` (stored in the checkpoint metadata)."""

    model_config = ConfigDict(extra="forbid")
    dim: int = Field(24, ge=4, le=256, description="embedding width")
    heads: int = Field(2, ge=1, le=16, description="attention heads (must divide dim)")
    log_scale_init: float = Field(-3.0, ge=-10, le=3, description="initial log Laplace scale (units of SCALE)")


def _mlp(n_in: int, dim: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(n_in, dim), nn.GELU(), nn.Linear(dim, dim))


class ResidualAttention(nn.Module):
    """query (B, 12), neigh (B, K, 5), mask (B, K) bool → (Δ local (B, 2), log scale local (B, 2)),
    both in units of SCALE (see the module doc)."""

    def __init__(self, hp: HParams):
        super().__init__()
        if hp.dim % hp.heads:
            raise ValueError(f"dim={hp.dim} is not divisible by heads={hp.heads}")
        self.hp = hp
        d = hp.dim
        self.query_mlp, self.point_mlp = _mlp(N_QUERY, d), _mlp(N_POINT, d)
        self.to_q, self.to_kv = nn.Linear(d, d), nn.Linear(d, 2 * d)
        self.null_kv = nn.Parameter(torch.zeros(2, d))
        self.out = nn.Sequential(nn.Linear(2 * d, d), nn.GELU(), nn.Linear(d, 4))
        nn.init.zeros_(self.out[-1].weight)
        with torch.no_grad():
            self.out[-1].bias.copy_(torch.tensor([0.0, 0.0, hp.log_scale_init, hp.log_scale_init]))

    def forward(self, query: torch.Tensor, neigh: torch.Tensor, mask: torch.Tensor):
        b, k = neigh.shape[:2]
        h, dh = self.hp.heads, self.hp.dim // self.hp.heads
        e = self.query_mlp(query)
        kv = self.to_kv(self.point_mlp(neigh))  # (B, K, 2d)
        kv = torch.cat([self.null_kv.reshape(1, 1, -1).expand(b, 1, -1), kv], 1)  # (B, K+1, 2d)
        keys, vals = kv.split(self.hp.dim, -1)
        qh = self.to_q(e).reshape(b, h, 1, dh)
        kh = keys.reshape(b, k + 1, h, dh).transpose(1, 2)
        vh = vals.reshape(b, k + 1, h, dh).transpose(1, 2)
        valid = torch.cat([torch.ones(b, 1, dtype=torch.bool, device=mask.device), mask], 1)
        score = (qh @ kh.transpose(-1, -2)) / math.sqrt(dh)  # (B, h, 1, K+1)
        score = score.masked_fill(~valid[:, None, None, :], float("-inf"))
        agg = (score.softmax(-1) @ vh).reshape(b, self.hp.dim)
        o = self.out(torch.cat([e, agg], -1))
        return o[:, :2], o[:, 2:].clamp(-12.0, 6.0)


def local_to_global(v_local: torch.Tensor, normal: torch.Tensor) -> torch.Tensor:
    """Ego-frame vectors (B, 2) [m] of local vectors (B, 2) [units of SCALE] in the frame (u_q, n_q)."""
    u = torch.stack([-normal[:, 1], normal[:, 0]], -1)
    return SCALE * (v_local[:, :1] * u + v_local[:, 1:] * normal)


def geo_loss(delta: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Eq. 9: L_geo = (1/K) Σ_j ‖Δo_θ^(j) − (o^(j) − ô_geom^(j))‖₁ over K points, in [m]; delta and
    target (K, 2) [m] in the ego frame (target = o − ô_geom)."""
    return (delta - target).abs().sum(-1).mean()


def laplace_nll(delta_local: torch.Tensor, log_scale: torch.Tensor, target: torch.Tensor,
                normal: torch.Tensor) -> torch.Tensor:
    """Mean negative log-likelihood (per point, both axes) of the residual error under independent
    Laplace laws in the local frame with scales s = SCALE·exp(log_scale) [m]; the predicted
    residual is detached, so this term only trains the scales (Eq. 9 alone trains Δo_θ)."""
    u = torch.stack([-normal[:, 1], normal[:, 0]], -1)
    err = target - local_to_global(delta_local.detach(), normal)  # [m]
    err_local = torch.stack([(err * u).sum(-1), (err * normal).sum(-1)], -1)
    s = SCALE * log_scale.exp()
    return (err_local.abs() / s + torch.log(2 * s)).sum(-1).mean()


def residual_cov(log_scale: torch.Tensor, normal: torch.Tensor) -> torch.Tensor:
    """(B, 2, 2) [m²] ego-frame covariance of the residual: Laplace variance 2s² per local axis,
    rotated by [u_q, n_q]."""
    u = torch.stack([-normal[:, 1], normal[:, 0]], -1)
    var = 2 * (SCALE * log_scale.exp()) ** 2
    r = torch.stack([u, normal], -1)  # columns u, n
    return r @ torch.diag_embed(var) @ r.transpose(-1, -2)
