"""``xnlos recording inspect``: the layout of a DCA1000 ``.bin`` told from its data.

:func:`inspect_words` scores every candidate layout (:func:`.candidates.score_layouts`) and returns
the best and the runner-up, or says the data cannot tell them apart (scores within
:data:`.candidates.TIE_DB`); :func:`report_text` prints them with a ready-to-paste
``[recording]``/``[chirp]`` table. The radar's receivers and TX slots come from a description TOML,
whole (``[recording]``, ``[chirp]``, ``[radar]``) or partial (``[radar]`` n_tx, n_rx; ``[chirp]``
n_samples; ``[radar]`` n_chirps for the frame count).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from xnlos_core.datafiles import file_size, open_regular
from xnlos_core.errors import ConfigError
from xnlos_core.files import load_toml

from .candidates import MAX_WORDS, TIE_DB, Layout, Scored, score_layouts

FIELDS = ("lanes", "sampling", "encoding", "iq_order", "iq_interleave")


@dataclass(frozen=True)
class Inspection:
    """Best and runner-up layouts of a file; ``told`` False when their scores are within TIE_DB [dB]."""

    best: Scored
    runner_up: Scored | None
    told: bool
    n_words: int
    n_rx: int
    n_tdm: int
    n_chirps: int | None

    @property
    def margin(self) -> float:
        """Best score − runner-up's [dB] (inf without a runner-up)."""
        return float("inf") if self.runner_up is None else self.best.score - self.runner_up.score


def inspect_words(words, n_rx: int, n_tdm: int, declared: Layout, n_words: int | None = None,
                  n_chirps: int | None = None) -> Inspection:
    """Score the layouts of the int16 stream ``words`` (the file's first words); ``n_words``: the file's
    total (for the frame count), ``n_chirps``: chirp loops per frame if known."""
    scored = score_layouts(words, n_rx, n_tdm, declared)
    best = scored[0]
    runner = scored[1] if len(scored) > 1 else None
    told = runner is None or best.score - runner.score >= TIE_DB
    return Inspection(best, runner, told, int(n_words if n_words is not None else np.asarray(words).size),
                      n_rx, n_tdm, n_chirps)


def _settings(layout: Layout) -> str:
    return ", ".join(f"{k} = {getattr(layout, k)!r}" for k in FIELDS + ("n_samples",))


def report_text(ins: Inspection, name: str) -> str:
    """The inspection as text: best, runner-up, scores, verdict and (when told) a table to paste."""
    b, r = ins.best, ins.runner_up
    lines = [f"{name}: {ins.n_words} int16 words; {ins.n_rx} receiver(s) per chirp, {ins.n_tdm} TX slot(s) per loop",
             f"best       score {b.score:7.1f} dB  (chirp-loop correlation {b.coherence:.2f}): {_settings(b.layout)}"]
    if r is not None:
        diff = ", ".join(r.layout.differences(b.layout))
        lines.append(f"runner-up  score {r.score:7.1f} dB  (chirp-loop correlation {r.coherence:.2f}): "
                     f"{_settings(r.layout)}  [differs in {diff}]")
    if not ins.told:
        lines.append(f"cannot tell: the best two layouts score within {TIE_DB} dB ({ins.margin:.1f} dB apart); "
                     "the data (noise, or a scene without strong static echoes) does not decide between them")
        return "\n".join(lines) + "\n"
    lines.append(f"layout told: the best scores {ins.margin:.1f} dB above the runner-up")
    per_frame = None
    if ins.n_chirps:
        per_frame = b.layout.chirp_words(ins.n_rx) * ins.n_tdm * ins.n_chirps
        n, rest = divmod(ins.n_words, per_frame)
        lines.append(f"frames: {ins.n_chirps} chirp loop(s) × {ins.n_tdm} TX slot(s) per frame → {n} frame(s)"
                     + (f", {rest} words left over (n_chirps may be wrong, or the capture is truncated)" if rest else ""))
    lay = b.layout
    lines += ["", "[recording]", 'format = "dca1000"', f"lanes = {lay.lanes}", f'sampling = "{lay.sampling}"',
              f'encoding = "{lay.encoding}"']
    if lay.sampling == "complex":
        lines += [f'iq_order = "{lay.iq_order}"', f'iq_interleave = "{lay.iq_interleave}"']
    lines += ["[chirp]", f"n_samples = {lay.n_samples}"]
    return "\n".join(lines) + "\n"


def inspect_file(path: str | Path, description: str | Path) -> Inspection:
    """Inspect the DCA1000 file ``path`` with the receivers and TX slots of the TOML ``description``."""
    table = load_toml(Path(description))
    radar, chirp, rec = table.get("radar", {}), table.get("chirp", {}), table.get("recording", {})
    n_tx = len(radar["tx_positions"]) if "tx_positions" in radar else int(radar.get("n_tx", 1))
    n_rx = len(radar["rx_positions"]) if "rx_positions" in radar else int(radar.get("n_rx", 4))
    mimo = bool(radar.get("mimo", True))
    n_samples = int(chirp.get("n_samples", radar.get("n_samples", 256)))
    if n_tx < 1 or n_rx < 1 or n_samples < 16:
        raise ConfigError(f"{description}: expected n_tx ≥ 1, n_rx ≥ 1 and n_samples ≥ 16; got n_tx={n_tx}, "
                          f"n_rx={n_rx}, n_samples={n_samples}")
    declared = Layout(int(rec.get("lanes", 2)), rec.get("sampling", "complex"), rec.get("iq_order", "iq"),
                      rec.get("iq_interleave", "lanes"), rec.get("encoding", "twos_complement"), n_samples)
    p = Path(path)
    with open_regular(p, what=f"recording {p}") as f:
        size = file_size(f)
        data = f.read(2 * min(MAX_WORDS, size // 2))
    words = np.frombuffer(data[:len(data) // 2 * 2], dtype="<i2")
    n_tdm = n_tx if mimo else 1
    return inspect_words(words, n_rx, n_tdm, declared, n_words=size // 2,
                         n_chirps=int(radar["n_chirps"]) if "n_chirps" in radar else None)
