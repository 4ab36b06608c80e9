"""Reproduce the paper's Fig. 2: (a) path loss versus frequency, (b) specular ratio versus frequency.

    python benchmarks/fig2.py [--out figures]

(a) free-space path loss 20·log10(4πdf/c) at d = 10, 100, 1000 m from 1 GHz to the optical band
    (LiDAR at 905 nm), with the ITU-R P.676 gaseous loss added where it is defined (1–1000 GHz).
(b) coherent specular power ratio ρ_s = exp(−(4πσ_h cosθ/λ)²) for rms roughness σ_h = 0.1 µm,
    50 µm and 5 mm, at grazing incidence θ = 80° (solid; a relay facade seen along a street,
    ``--incidence``) and at normal incidence (thin dashed). At θ = 80° a 5 mm wall is a mirror at
    10 GHz (ρ_s ≈ 0.88) and diffuse at 77 GHz (ρ_s ≈ 4e-4), as the paper shows; at normal
    incidence the same wall is already diffuse at 10 GHz (ρ_s ≈ 0.012).
Writes ``fig2a_path_loss.png``, ``fig2b_specular_ratio.png`` and ``fig2.png`` (both panels) and
prints the values at 10 GHz, 77 GHz and 905 nm.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sims.atmosphere import attenuation_db  # noqa: E402
from sims.propagation import free_space_path_loss_db  # noqa: E402
from sims.roughness import specular_factor  # noqa: E402
from xnlos_core.io import atomic_write_bytes  # noqa: E402
from xnlos_core.radar import SPEED_OF_LIGHT  # noqa: E402

DISTANCES = (10.0, 100.0, 1000.0)
ROUGHNESS = ((0.1e-6, "0.1 µm"), (50e-6, "50 µm"), (5e-3, "5 mm"))
MARKS = ((10e9, "10 GHz"), (77e9, "77 GHz"), (SPEED_OF_LIGHT / 905e-9, "905 nm"))


def panel_a(ax):
    f = np.logspace(9, 15, 600)
    fa = f[f <= 1e12]
    for d, c in zip(DISTANCES, ("C0", "C1", "C2")):
        ax.plot(f, free_space_path_loss_db(f, d), c, label=f"{d:g} m")
        ax.plot(fa, free_space_path_loss_db(fa, d) + attenuation_db(fa, d), c + ":", lw=1)
    for fm, name in MARKS:
        ax.axvline(fm, color="0.6", lw=0.8, ls="--")
        ax.text(fm, 60, name, rotation=90, va="bottom", ha="right", fontsize=8)
    ax.set(xscale="log", xlabel="frequency [Hz]", ylabel="path loss [dB]", ylim=(50, 260),
           title="(a) free-space path loss (dotted: + P.676 gaseous loss)")
    ax.legend(title="distance")
    ax.grid(True, which="both", alpha=0.3)


def panel_b(ax, incidence_deg: float):
    f = np.logspace(9, 15, 600)
    lam = SPEED_OF_LIGHT / f
    th = np.radians(incidence_deg)
    for (s, name), c in zip(ROUGHNESS, ("C0", "C1", "C2")):
        ax.plot(f, specular_factor(s, th, lam), c, label=f"σ = {name}")
        ax.plot(f, specular_factor(s, 0.0, lam), c + "--", lw=0.8)
    for fm, name in MARKS:
        ax.axvline(fm, color="0.6", lw=0.8, ls="--")
        ax.text(fm, 0.02, name, rotation=90, va="bottom", ha="right", fontsize=8)
    ax.set(xscale="log", xlabel="frequency [Hz]", ylabel="specular ratio ρ_s", ylim=(-0.02, 1.05),
           title=f"(b) specular ratio exp(−(4πσ cosθ/λ)²), θ = {incidence_deg:g}° (dashed: 0°)")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)


def _save(fig, path: Path):
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=130, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="figures", help="output folder (default: figures)")
    ap.add_argument("--incidence", type=float, default=80.0,
                    help="incidence angle from the wall normal for panel (b) [deg] (default 80)")
    args = ap.parse_args(argv)
    if not 0.0 <= args.incidence < 90.0:
        ap.error(f"--incidence must be in [0, 90) degrees, got {args.incidence}")
    th = np.radians(args.incidence)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name, fn in (("fig2a_path_loss.png", panel_a),
                     ("fig2b_specular_ratio.png", lambda ax: panel_b(ax, args.incidence))):
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        fn(ax)
        _save(fig, out / name)
    fig, axes = plt.subplots(1, 2, figsize=(12.5, 4.2))
    panel_a(axes[0])
    panel_b(axes[1], args.incidence)
    _save(fig, out / "fig2.png")

    print(f"{'':>10} " + " ".join(f"{'FSPL ' + f'{d:g} m':>14}" for d in DISTANCES)
          + " " + " ".join(f"{'ρ_s ' + n:>12}" for _, n in ROUGHNESS) + f"  (ρ_s at θ = {args.incidence:g}°)")
    for fm, name in MARKS:
        row = [free_space_path_loss_db(fm, d) for d in DISTANCES]
        rho = [specular_factor(s, th, SPEED_OF_LIGHT / fm) for s, _ in ROUGHNESS]
        print(f"{name:>10} " + " ".join(f"{v:>11.1f} dB" for v in row) + " " + " ".join(f"{v:>12.3g}" for v in rho))
    d77 = free_space_path_loss_db(77e9, 100.0) - free_space_path_loss_db(10e9, 100.0)
    print(f"FSPL(77 GHz) − FSPL(10 GHz) = {d77:.2f} dB (20·log10 7.7 = {20 * np.log10(7.7):.2f} dB)")
    print(f"wrote {out / 'fig2a_path_loss.png'}, {out / 'fig2b_specular_ratio.png'}, {out / 'fig2.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
