"""The OpenBLAS kernels (``OPENBLAS_CORETYPE``) this processor can run, for the kernel matrix.

OpenBLAS built with DYNAMIC_ARCH (numpy's and scipy's wheels) picks a kernel per processor; the
variable forces another. A kernel needs its instruction set: forcing SkylakeX (AVX-512) on a
processor without it dies of an illegal instruction, so those are reported as not runnable here.
"""
from __future__ import annotations

import platform

# kernel → the /proc/cpuinfo flags it needs
KERNELS = {
    "Prescott": ("pni",),  # SSE3 (Linux calls it pni)
    "Nehalem": ("ssse3", "sse4_2"),
    "Haswell": ("avx2", "fma"),
    "SkylakeX": ("avx512f", "avx512bw", "avx512vl", "avx512dq", "avx512cd"),
}
REQUIRED = ("Prescott", "Haswell", "SkylakeX")  # the matrix the project promises; Nehalem added


def cpu_flags() -> set[str]:
    """The processor's feature flags (empty off Linux)."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def runnable() -> tuple[list[str], dict[str, str]]:
    """(kernels runnable here, {kernel: why not} for the others)."""
    if platform.machine() not in ("x86_64", "AMD64"):
        return [], {k: f"not an x86-64 processor ({platform.machine()})" for k in KERNELS}
    flags = cpu_flags()
    ok, why = [], {}
    for k, need in KERNELS.items():
        missing = [f for f in need if f not in flags]
        if missing:
            why[k] = "the processor lacks " + ", ".join(missing)
        else:
            ok.append(k)
    return ok, why
