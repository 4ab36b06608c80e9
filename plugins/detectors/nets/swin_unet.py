"""Swin-UNet (Cao et al. 2022) for dense LOS / mNLOS confidence maps (Sec. 4.1).

Encoder: patch embedding (p_r × p_a patches → C channels), then per stage ``depth`` Swin blocks
(window multi-head self-attention, every second block on windows shifted by half a window, with
a learned relative-position bias) followed by patch merging (2×2 → 2C). Decoder: patch expanding
(C → 2×2 × C/2), concatenation with the encoder skip of the same scale, a linear fusion and
Swin blocks. Our addition (a hybrid, as in TransUNet): the patch embedding sits on a small
convolutional stem — ``stem_levels`` levels of conv-BN-ReLU at full, 1/2, 1/4, … resolution, each
level after the first halving it — whose feature maps are skips for the last decoder steps (patch
expanding to the stem's lowest resolution, fusion, then per level transposed-conv up-sampling by
2 and fusion; each fusion ``decoder_convs`` 3×3 conv-BN-ReLU). A pure ×4 patch embedding loses
the sub-cell peak shape that the Gaussian targets and the refinement rely on (Sec. 4, angular
upsampling); with the stem the transformer still sees every cell's context at 1/p resolution.
The shipped model has three stem levels (full, 1/2, 1/4) under 8 × 8 patches: convolutions where
echoes are dense, attention from 1/8 on, where an 8 × 8-token window spans 64 × 64 cells. A 3×3
projection to two channels is the head (the paper's linear layer with a 3×3 support); the
Sigmoid is applied by the loss / detector. With ``mlp_conv`` each block's MLP carries a 3×3
depthwise convolution (Mix-FFN, :class:`MixMLP`): attention stays windowed and shifted, and every
token also sees its neighbours (+1 % parameters; after the 24 crop epochs of stage 1 on the
default dataset, val loss 0.250 against 0.267 without).

Inputs (B, 4, H, W) with H, W multiples of ``multiple`` = patch · 2^(stages−1); windows that do
not tile a stage are zero-padded inside the block and cropped back (as in Swin).
"""
from __future__ import annotations

import torch
import torch.nn.functional as F
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field
from torch import nn

from ..features import N_FEATURES
from .blocks import conv_bn, head_bias_init


class SwinUNetParams(BaseModel):
    """Hyper-parameters of :class:`SwinUNet`."""

    model_config = ConfigDict(extra="forbid")
    in_channels: int = Field(N_FEATURES, ge=1, le=64, description="input feature channels (plugins.detectors.features: 4 power-map channels, 7 with Doppler)")
    embed_dim: int = Field(32, ge=4, le=256, description="channels C of the first stage")
    depths: tuple[Annotated[int, Field(ge=1, le=32)], ...] = Field((2, 2, 2), min_length=1, max_length=5,
                                                                   description="Swin blocks per stage")
    heads: tuple[Annotated[int, Field(ge=1, le=64)], ...] = Field((2, 4, 8), min_length=1, max_length=5,
                                                                  description="attention heads per stage")
    window: tuple[Annotated[int, Field(ge=1, le=256)], Annotated[int, Field(ge=1, le=256)]] = Field(
        (8, 8), description="attention window (range, azimuth) [tokens]")
    patch: tuple[Annotated[int, Field(ge=1, le=256)], Annotated[int, Field(ge=1, le=256)]] = Field(
        (4, 4), description="patch size (range, azimuth) [bins], even")
    mlp_ratio: float = Field(2.0, gt=0, le=8, description="MLP hidden width / channels")
    stem_channels: int = Field(8, ge=1, le=128, description="conv stem channels at full resolution")
    head_channels: int = Field(16, ge=1, le=128, description="conv stem / decoder channels at half resolution "
                                                              "(doubled per further stem level)")
    decoder_convs: int = Field(1, ge=1, le=4, description="3×3 conv-BN-ReLU per full- and half-resolution "
                                                           "decoder step (2: the UNet unit)")
    mlp_conv: bool = Field(False, description="a 3×3 depthwise convolution between the two linear layers of "
                                              "every block's MLP (Mix-FFN)")
    stem_levels: int = Field(2, ge=2, le=4, description="conv stem levels before the patch embedding (full, "
                                                         "1/2, 1/4, … resolution); level k ≥ 1 has "
                                                         "head_channels · 2^(k−1) channels")

    def model_post_init(self, _ctx) -> None:
        if len(self.depths) != len(self.heads):
            raise ValueError(f"depths {self.depths} and heads {self.heads} must have one entry per stage")
        for i, h in enumerate(self.heads):
            if (self.embed_dim * 2**i) % h:
                raise ValueError(f"stage {i}: {self.embed_dim * 2**i} channels not divisible by {h} heads")
        step = 2 ** (self.stem_levels - 1)
        if min(self.window) < 1 or min(self.patch) < step or any(p % step for p in self.patch):
            raise ValueError(f"window {self.window} must be ≥ 1 and patch {self.patch} a multiple of {step}: "
                             f"the {self.stem_levels}-level conv stem divides the resolution by {step} before "
                             "the patch embedding")


class WindowAttention(nn.Module):
    """Multi-head self-attention within windows of wh × ww tokens with relative-position bias."""

    def __init__(self, dim: int, heads: int, window: tuple[int, int]):
        super().__init__()
        self.heads, self.window = heads, window
        wh, ww = window
        self.bias_table = nn.Parameter(torch.zeros((2 * wh - 1) * (2 * ww - 1), heads))
        nn.init.trunc_normal_(self.bias_table, std=0.02)
        coords = torch.stack(torch.meshgrid(torch.arange(wh), torch.arange(ww), indexing="ij")).flatten(1)
        rel = coords[:, :, None] - coords[:, None, :]
        index = (rel[0] + wh - 1) * (2 * ww - 1) + (rel[1] + ww - 1)
        self.register_buffer("bias_index", index, persistent=False)
        self.qkv = nn.Linear(dim, 3 * dim)
        self.proj = nn.Linear(dim, dim)

    def forward(self, x: torch.Tensor, mask: torch.Tensor | None) -> torch.Tensor:
        """x (B·nW, N, C); mask (nW, N, N) additive (0 / −inf-like) or None."""
        bw, n, c = x.shape
        qkv = self.qkv(x).reshape(bw, n, 3, self.heads, c // self.heads).permute(2, 0, 3, 1, 4)
        bias = self.bias_table[self.bias_index.reshape(-1)].reshape(n, n, -1).permute(2, 0, 1)
        bias = bias.unsqueeze(0)
        if mask is not None:
            nw = mask.shape[0]
            bias = (bias.unsqueeze(0) + mask[None, :, None]).expand(bw // nw, -1, -1, -1, -1).reshape(bw, -1, n, n)
        out = F.scaled_dot_product_attention(qkv[0], qkv[1], qkv[2], attn_mask=bias.to(x.dtype))
        return self.proj(out.transpose(1, 2).reshape(bw, n, c))


def _partition(x: torch.Tensor, wh: int, ww: int) -> torch.Tensor:
    b, h, w, c = x.shape
    x = x.view(b, h // wh, wh, w // ww, ww, c).permute(0, 1, 3, 2, 4, 5)
    return x.reshape(-1, wh * ww, c)


def _merge(win: torch.Tensor, wh: int, ww: int, b: int, h: int, w: int) -> torch.Tensor:
    x = win.view(b, h // wh, w // ww, wh, ww, -1).permute(0, 1, 3, 2, 4, 5)
    return x.reshape(b, h, w, -1)


def _shift_mask(h: int, w: int, window: tuple[int, int], shift: tuple[int, int], device) -> torch.Tensor:
    """Additive mask (nW, N, N) keeping attention inside the regions a cyclic shift brought together."""
    wh, ww = window

    def bands(win: int, s: int) -> tuple[slice, ...]:
        return (slice(0, -win), slice(-win, -s), slice(-s, None)) if s else (slice(None),)

    region = torch.zeros(1, h, w, 1, device=device)
    k = 0
    for hs in bands(wh, shift[0]):
        for ws in bands(ww, shift[1]):
            region[:, hs, ws] = k
            k += 1
    ids = _partition(region, wh, ww).squeeze(-1)
    diff = ids[:, None, :] - ids[:, :, None]
    return torch.zeros_like(diff).masked_fill(diff != 0, -1e4)


class MixMLP(nn.Module):
    """Linear → 3×3 depthwise conv → GELU → Linear on channels-last tokens (B, H, W, C).

    The Mix-FFN of SegFormer (Xie et al. 2021; the LeFF of Uformer): each token's MLP also sees its
    eight neighbours, a locality prior that windowed attention lacks and that zero padding turns
    into an implicit position cue (Islam et al. 2020).
    """

    def __init__(self, dim: int, hidden: int):
        super().__init__()
        self.fc1 = nn.Linear(dim, hidden)
        self.dw = nn.Conv2d(hidden, hidden, 3, padding=1, groups=hidden)
        self.fc2 = nn.Linear(hidden, dim)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.dw(self.fc1(x).permute(0, 3, 1, 2)).permute(0, 2, 3, 1)
        return self.fc2(F.gelu(y))


class SwinBlock(nn.Module):
    """LN → (shifted) window attention → residual; LN → MLP → residual (channels-last input)."""

    def __init__(self, dim: int, heads: int, window: tuple[int, int], shifted: bool, mlp_ratio: float,
                 mlp_conv: bool = False):
        super().__init__()
        self.window, self.shifted = window, shifted
        self.norm1 = nn.LayerNorm(dim)
        self.attn = WindowAttention(dim, heads, window)
        self.norm2 = nn.LayerNorm(dim)
        hidden = max(1, int(dim * mlp_ratio))
        self.mlp = MixMLP(dim, hidden) if mlp_conv else nn.Sequential(nn.Linear(dim, hidden), nn.GELU(), nn.Linear(hidden, dim))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, h, w, c = x.shape
        wh, ww = self.window
        y = self.norm1(x)
        ph, pw = (-h) % wh, (-w) % ww
        if ph or pw:
            y = F.pad(y, (0, 0, 0, pw, 0, ph))
        hp, wp = h + ph, w + pw
        # No shift along an axis that one window already covers (nothing to connect across).
        shift = (wh // 2 if self.shifted and hp > wh else 0, ww // 2 if self.shifted and wp > ww else 0)
        mask = None
        if any(shift):
            y = torch.roll(y, (-shift[0], -shift[1]), dims=(1, 2))
            mask = _shift_mask(hp, wp, self.window, shift, y.device)
        y = _merge(self.attn(_partition(y, wh, ww), mask), wh, ww, b, hp, wp)
        if any(shift):
            y = torch.roll(y, shift, dims=(1, 2))
        x = x + y[:, :h, :w]
        return x + self.mlp(self.norm2(x))


class PatchMerging(nn.Module):
    """2×2 neighbouring tokens → one token: (B, H, W, C) → (B, H/2, W/2, 2C)."""

    def __init__(self, dim: int):
        super().__init__()
        self.norm = nn.LayerNorm(4 * dim)
        self.reduce = nn.Linear(4 * dim, 2 * dim, bias=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = torch.cat([x[:, 0::2, 0::2], x[:, 1::2, 0::2], x[:, 0::2, 1::2], x[:, 1::2, 1::2]], -1)
        return self.reduce(self.norm(x))


class PatchExpand(nn.Module):
    """One token → an fh × fw block of tokens with ``out_dim`` channels each (channels-last)."""

    def __init__(self, dim: int, out_dim: int, factor: tuple[int, int]):
        super().__init__()
        self.factor, self.out_dim = factor, out_dim
        self.expand = nn.Linear(dim, factor[0] * factor[1] * out_dim, bias=False)
        self.norm = nn.LayerNorm(out_dim)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, h, w, _ = x.shape
        fh, fw = self.factor
        x = self.expand(x).view(b, h, w, fh, fw, self.out_dim).permute(0, 1, 3, 2, 4, 5)
        return self.norm(x.reshape(b, h * fh, w * fw, self.out_dim))


def _stage(dim: int, depth: int, heads: int, window: tuple[int, int], mlp_ratio: float, mlp_conv: bool) -> nn.Sequential:
    return nn.Sequential(*(SwinBlock(dim, heads, window, i % 2 == 1, mlp_ratio, mlp_conv) for i in range(depth)))


class SwinUNet(nn.Module):
    """Swin-UNet: features (B, 4, H, W) → logits (B, 2, H, W) (module doc)."""

    def __init__(self, hp: SwinUNetParams | None = None):
        super().__init__()
        hp = hp or SwinUNetParams()
        self.hp = hp
        n = len(hp.depths)
        c = hp.embed_dim
        self.multiple = (hp.patch[0] * 2 ** (n - 1), hp.patch[1] * 2 ** (n - 1))
        levels = hp.stem_levels
        ch = [hp.stem_channels] + [hp.head_channels * 2 ** (k - 1) for k in range(1, levels)]
        self.stem0 = nn.Sequential(conv_bn(hp.in_channels, ch[0]), conv_bn(ch[0], ch[0]))
        for k in range(1, levels):
            self.add_module(f"stem{k}", nn.Sequential(conv_bn(ch[k - 1], ch[k], stride=2), conv_bn(ch[k], ch[k])))
        step = 2 ** (levels - 1)
        rest = (hp.patch[0] // step, hp.patch[1] // step)
        self.embed = nn.Conv2d(ch[-1], c, kernel_size=rest, stride=rest)
        self.embed_norm = nn.LayerNorm(c)
        win = tuple(hp.window)
        self.encoder = nn.ModuleList(_stage(c * 2**i, hp.depths[i], hp.heads[i], win, hp.mlp_ratio, hp.mlp_conv)
                                     for i in range(n))
        self.merge = nn.ModuleList(PatchMerging(c * 2**i) for i in range(n - 1))
        self.expand = nn.ModuleList(PatchExpand(c * 2 ** (i + 1), c * 2**i, (2, 2)) for i in range(n - 1))
        self.fuse = nn.ModuleList(nn.Linear(2 * c * 2**i, c * 2**i) for i in range(n - 1))
        self.decoder = nn.ModuleList(_stage(c * 2**i, hp.depths[i], hp.heads[i], win, hp.mlp_ratio, hp.mlp_conv)
                                     for i in range(n - 1))
        self.final_expand = PatchExpand(c, ch[-1], rest)
        # Attribute names fuse{k} / up{k} keep the two-level checkpoints' state_dict keys.
        for k in reversed(range(levels)):
            self.add_module(f"fuse{k}", _fuse(2 * ch[k], ch[k], hp.decoder_convs))
            if k:
                self.add_module(f"up{k - 1}", nn.ConvTranspose2d(ch[k], ch[k - 1], 2, stride=2))
        self.head = nn.Conv2d(ch[0], 2, 3, padding=1)
        head_bias_init(self.head)
        self.apply(_init)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h, w = x.shape[-2:]
        if h % self.multiple[0] or w % self.multiple[1]:
            raise ValueError(f"SwinUNet: input {h}×{w} must be a multiple of {self.multiple}; pad it first")
        levels = self.hp.stem_levels
        feats = [self.stem0(x)]
        for k in range(1, levels):
            feats.append(getattr(self, f"stem{k}")(feats[-1]))
        t = self.embed_norm(self.embed(feats[-1]).permute(0, 2, 3, 1))
        skips = []
        for i, stage in enumerate(self.encoder):
            t = stage(t)
            if i < len(self.merge):
                skips.append(t)
                t = self.merge[i](t)
        for i in reversed(range(len(self.decoder))):
            t = self.expand[i](t)
            t = self.decoder[i](self.fuse[i](torch.cat([t, skips[i]], -1)))
        y = torch.cat([self.final_expand(t).permute(0, 3, 1, 2), feats[-1]], 1)
        y = getattr(self, f"fuse{levels - 1}")(y)
        for k in reversed(range(levels - 1)):
            y = getattr(self, f"fuse{k}")(torch.cat([getattr(self, f"up{k}")(y), feats[k]], 1))
        return self.head(y)


def _fuse(cin: int, cout: int, n: int) -> nn.Sequential:
    """n 3×3 conv-BN-ReLU (n = 1 keeps the layout of the checkpoints made before ``decoder_convs``)."""
    return conv_bn(cin, cout) if n == 1 else nn.Sequential(conv_bn(cin, cout), *(conv_bn(cout, cout) for _ in range(n - 1)))


def _init(m: nn.Module) -> None:
    if isinstance(m, nn.Linear):
        nn.init.trunc_normal_(m.weight, std=0.02)
        if m.bias is not None:
            nn.init.zeros_(m.bias)
    elif isinstance(m, nn.LayerNorm):
        nn.init.ones_(m.weight)
        nn.init.zeros_(m.bias)


def count_parameters(module: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in module.parameters() if p.requires_grad)

