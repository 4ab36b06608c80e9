"""Running a detector network for inference, fast.

:class:`InferenceRunner` wraps an ``nn.Module`` (B, C, H, W) → (B, C, H', W') once it is built:

- eval mode under ``torch.inference_mode()`` (no autograd records, no version counters);
- channels-last memory format for weights and input: oneDNN's convolutions run NHWC natively, so
  the (N, C, H, W) ↔ NHWC reorders around every convolution go away. The arithmetic is the same
  up to summation order: float32 logits agree with the contiguous network's within 1e-5
  (``tests/unit/test_detector_inference.py``; measured ≤ 6e-6 on the shipped models);
- ``precision = "bf16"``: CPU (or CUDA) autocast to bfloat16 — matrix products and convolutions in
  bfloat16 with float32 accumulation, outputs returned as float32. Opt-in: logits move by ~0.1, so
  detections change near the thresholds; ``benchmarks/detector_speed.md`` prices it (F1 against the
  float32 detections and Macro-F1 against ground truth);
- ``compile = True``: ``torch.compile`` (inductor). Compilation is lazy (the first forward of each
  input shape), so a failure — no C++ compiler, an unsupported platform or Python — shows on the
  first call; the runner then warns (:class:`CompileFallbackWarning`) and runs the eager network
  from then on: same outputs, no crash. Warm the runner up (:meth:`InferenceRunner.warm_up`) so that
  compilation is not paid on the first frame;
- ``threads``: torch intra-op threads during the call, restored afterwards (None leaves torch's
  setting: with the process thread policy of :mod:`xnlos_core.threads`, one thread per available
  core, waiting passively so that other processes on the same cores do not stall them). BLAS runs
  one thread while the stages run, so torch owns the cores during the detector.

Hand-written rather than a library: the pieces are three torch calls; what this module adds is
the fallback and the counters the pipeline's warm-up test reads (:attr:`InferenceRunner.forwards`).
"""
from __future__ import annotations

import warnings
from typing import Literal

import numpy as np

from xnlos_core.core_share import limited
from xnlos_core.errors import ConfigError, XnlosWarning

Precision = Literal["fp32", "bf16"]


class CompileFallbackWarning(XnlosWarning):
    """``compile = true`` was asked for, but ``torch.compile`` is unavailable or failed on this
    machine; the detector runs the eager network instead (same outputs, without the speed-up)."""


def to_channels_last(x):
    """A 4-D tensor in channels-last memory format (same values); other ranks unchanged."""
    import torch

    return x.contiguous(memory_format=torch.channels_last) if x.dim() == 4 else x


class InferenceRunner:
    """Callable: features (C, H, W) float32 numpy (C the network's ``in_channels``) → raw network output (C, H', W') float32 numpy,
    C-contiguous (module doc). ``net`` is moved to ``device``, set to eval mode and converted to
    channels-last in place (the caller's module is the one used)."""

    def __init__(self, net, device, precision: Precision = "fp32", compile: bool = False,
                 threads: int | None = None, name: str = "detector"):
        import torch

        if precision not in ("fp32", "bf16"):
            raise ConfigError(f"{name}: precision {precision!r}: expected 'fp32' or 'bf16'")
        if precision == "bf16" and device.type not in ("cpu", "cuda"):
            raise ConfigError(f"{name}: precision 'bf16' needs device cpu or cuda, got {device.type!r}; "
                              "use precision = 'fp32'")
        self.name = name
        self.device = device
        self.precision = precision
        self.threads = threads
        self.net = net.to(device).eval().to(memory_format=torch.channels_last)
        self.multiple = net.multiple
        self.forwards = 0  # network calls made (warm-up included): the pipeline's warm-up test counts them
        self._compiled = None
        self._compiled_ok = False
        if compile:
            try:
                self._compiled = torch.compile(self.net)
            except Exception as exc:  # noqa: BLE001 - any failure means: run eager
                self._fallback(exc)

    @property
    def compiled(self) -> bool:
        """True while the compiled network is in use (False without ``compile`` or after a fallback)."""
        return self._compiled is not None

    def _fallback(self, exc: BaseException) -> None:
        self._compiled = None
        warnings.warn(f"{self.name}: compile = true, but torch.compile is not available here "
                      f"({type(exc).__name__}: {str(exc).strip().splitlines()[0] if str(exc).strip() else ''}); "
                      "running the eager network (same outputs, without the compile speed-up)",
                      CompileFallbackWarning, stacklevel=3)

    def _forward(self, x):
        if self._compiled is not None:
            try:
                out = self._compiled(x)
                self._compiled_ok = True
                return out
            except Exception as exc:  # noqa: BLE001 - compilation is lazy: it fails on a first call
                if self._compiled_ok:
                    raise
                self._fallback(exc)
        return self.net(x)

    def __call__(self, features: np.ndarray) -> np.ndarray:
        """Raw output (C, H', W') float32 of features (C, H, W), zero-padded to the network's multiple
        (not cropped back: the head decides)."""
        import torch

        from .features import pad_to_multiple

        x = torch.from_numpy(np.ascontiguousarray(features, dtype=np.float32))[None].to(self.device)
        x, _ = pad_to_multiple(x, self.multiple)
        x = to_channels_last(x)
        before = torch.get_num_threads()
        threads = limited(self.threads) if self.threads else 0  # kept to the cores left free (core_share)
        if threads and threads != before:
            torch.set_num_threads(threads)
        try:
            with torch.inference_mode():
                if self.precision == "bf16":
                    with torch.autocast(device_type=self.device.type, dtype=torch.bfloat16):
                        out = self._forward(x)
                else:
                    out = self._forward(x)
                out = out[0].float().contiguous().cpu().numpy()
        finally:
            if threads and threads != before:
                torch.set_num_threads(before)
        self.forwards += 1
        return out

    def warm_up(self, shape: tuple[int, int]) -> int:
        """One forward on all-zero features of a map of ``shape`` (n_range, n_azimuth): builds oneDNN's
        kernels, autocast's weight casts and, with ``compile``, the compiled graph for that size, so
        the first frame runs at the steady-state speed. Returns the number of forwards made (1)."""
        h, w = (int(s) for s in shape)
        if h < 1 or w < 1:
            raise ConfigError(f"{self.name}: warm-up map shape {shape}: expected positive (n_range, n_azimuth)")
        channels = int(getattr(getattr(self.net, "hp", None), "in_channels", 4))
        self(np.zeros((channels, h, w), np.float32))
        return 1
