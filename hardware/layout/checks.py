"""Checks of a DCA1000 recording's declared layout against its data, each a RecordingWarning that
names the setting, what the data says and the likely fix (statistics of :mod:`.scores`, candidates
of :mod:`.candidates`; ``xnlos recording inspect`` prints the same scores for every layout)."""
from __future__ import annotations

import warnings

import numpy as np

from xnlos_core.errors import XnlosWarning

from ..raw_formats import signed_words
from .candidates import MAX_WORDS, Layout, loop_lags, score_layouts
from .scores import encoding_evidence, periodicity

ENCODING_DB = 6.0  # one reading of the codes this much smaller [dB] in RMS (half): the encoding is that one
COHERENCE_DROP = 0.3  # periodicity this much lower at the declared loop than at the data's own: misframed
LAYOUT_DB = 3.0  # another layout scoring this much higher [dB]: the declared one is wrong
IQ_ORDER_DB = 25.0  # far half over near half [dB] beyond which Q + jI is named (R⁻⁴ alone gives ≤ ~16 dB in a scene)

_KEY = {"n_samples": "chirp.n_samples"}


def _warn(message: str, category: type[Warning]) -> None:
    warnings.warn(message, category, stacklevel=4)


def check_layout(words, declared: Layout, n_rx: int, n_tdm: int, source: str,
                 category: type[XnlosWarning]) -> list[str]:
    """Warn (``category``) where the int16 stream ``words`` (1-D, the file's first words) contradicts the
    declared layout with ``n_rx`` receivers per chirp and ``n_tdm`` TX slots per loop: its encoding, its
    chirp-loop length (n_samples · n_rx · n_tx · words per sample) and its lanes / sampling / I/Q
    order and interleave. Returns the settings named (empty when the data agrees or cannot tell)."""
    raw = np.asarray(words)[:MAX_WORDS]
    named: list[str] = []
    ev = encoding_evidence(raw)
    if declared.encoding == "twos_complement" and ev > ENCODING_DB or \
            declared.encoding == "offset_binary" and ev < -ENCODING_DB:
        other = "offset_binary" if declared.encoding == "twos_complement" else "twos_complement"
        _warn(f"{source}: recording.encoding = '{declared.encoding}', but the 16-bit codes read as {other} have "
              f"an RMS {abs(ev):.0f} dB smaller (a radar's samples sit around 0; the other reading adds 32768 to "
              f"half of them): set recording.encoding = '{other}' (adc_offset = 32768 does not convert "
              "offset-binary words read as signed: it is wrong by 65536 for every non-negative sample)", category)
        named.append("recording.encoding")
        declared = Layout(**{**declared.__dict__, "encoding": other})
    x = signed_words(raw, declared.encoding).astype(np.float64)
    loop = declared.chirp_words(n_rx) * n_tdm
    r = periodicity(x, 4 * loop + 64)
    lags = loop_lags(r)
    if lags and loop < r.size:
        lag = lags[0]
        if r[lag] - r[loop] > COHERENCE_DROP and loop % lag:  # the declared loop is no multiple of the period
            per_sample = 2 if declared.sampling == "complex" else 1
            width = 4 if declared.lanes == 4 else n_rx
            hints = []
            if lag % (width * n_tdm * per_sample) == 0:
                hints.append(f"n_samples = {lag // (width * n_tdm * per_sample)} with these receivers and TX")
            if declared.lanes == 2 and lag % (declared.n_samples * per_sample) == 0:
                k = lag // (declared.n_samples * per_sample)
                hints.append(f"n_rx·n_tx = {k} chirps of {declared.n_samples} samples per loop "
                             f"(now n_rx = {n_rx}, n_tx = {n_tdm})")
            _warn(f"{source}: a static scene repeats every chirp loop, and these samples repeat every {lag} int16 "
                  f"words (correlation {r[lag]:.2f}), not every n_samples·receivers·TX slots·"
                  f"{per_sample} = {loop} words as described (correlation {r[loop]:.2f}): chirp.n_samples, "
                  f"radar.n_rx / n_tx or recording.sampling is wrong; the data fits "
                  f"{' or '.join(hints) or 'a loop of ' + str(lag) + ' words'}", category)
            named.append("chirp.n_samples / radar.n_rx / radar.n_tx")
    scored = score_layouts(raw, n_rx, n_tdm, declared)
    best = scored[0]
    mine = next(s for s in scored if s.layout == declared)
    if best.layout != declared and best.score - mine.score > LAYOUT_DB:
        diff = best.layout.differences(declared)
        # I/Q order alone shows only as energy in the spectrum's far half, which far echoes give too (a
        # corner 60 m away at 100 m range): named only when the imbalance is beyond any scene's
        if set(diff) == {"iq_order"} and mine.stats.near_far_db > -IQ_ORDER_DB:
            diff = {}
        if set(diff) - {"encoding"}:
            settings = ", ".join(f"{_KEY.get(k, 'recording.' + k)} = {v[0]!r}" for k, v in diff.items())
            why = []
            if "iq_order" in diff and set(diff) == {"iq_order"}:
                why.append(f"the range spectrum holds {-mine.stats.near_far_db:.0f} dB more energy in its far "
                           "half than its near half, as when Q + jI mirrors every range")
            else:
                why.append(f"the decoded samples' range spectrum peaks {mine.stats.peak_db:.0f} dB over its floor "
                           f"(mirror images {100 * mine.stats.symmetry:.0f} %) as described, "
                           f"{best.stats.peak_db:.0f} dB (images {100 * best.stats.symmetry:.0f} %) with these")
            _warn(f"{source}: the data fits another layout better ({best.score - mine.score:.0f} dB by the layout "
                  f"score): {'; '.join(why)}: set {settings} (`xnlos recording inspect` scores every layout)",
                  category)
            named += [_KEY.get(k, "recording." + k) for k in diff]
    return named
