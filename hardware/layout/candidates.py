"""Candidate DCA1000 layouts of a word stream, each scored by the statistics of :mod:`.scores`.

A :class:`Layout` is what ``[recording]`` and ``[chirp]`` say about the words: lanes, sampling,
I/Q order and interleave, encoding and samples per chirp (the receivers and TX slots come from
``[radar]``). :func:`score_layouts` decodes the first chirps of a stream in every candidate layout
and ranks them by one score [dB]:

    score = peak_db − 10·symmetry + ½·clip(near_far_db, −20, 0) + 10·(r − r_max) − encoding penalty

peak_db, symmetry and near_far_db from :func:`.scores.spectrum_stats`; r the stream's periodicity
at the candidate's chirp-loop length (:func:`.scores.periodicity`), r_max the best over candidates;
the encoding penalty is how much larger [dB] the candidate's reading of the codes is than the other
(a spectrum whose far half holds more energy than its near half loses up to 10 dB: I and Q exchanged)
(:func:`.scores.encoding_evidence`). Two layouts within :data:`TIE_DB` cannot be told apart.
"""
from __future__ import annotations

import itertools
from dataclasses import asdict, dataclass

import numpy as np

from ..raw_formats import decode_dca1000, signed_words
from .scores import SpectrumStats, encoding_evidence, periodicity, spectrum_stats

TIE_DB = 1.5       # scores closer than this [dB] cannot be told apart
MAX_WORDS = 1 << 21  # words of the stream looked at (4 MiB): enough loops for the statistics
MAX_CHIRPS = 32    # chirps decoded per candidate for its spectrum


@dataclass(frozen=True)
class Layout:
    """One way to read DCA1000 words (the ``[recording]`` fields of the same names, and n_samples)."""

    lanes: int
    sampling: str
    iq_order: str
    iq_interleave: str
    encoding: str
    n_samples: int

    def chirp_words(self, n_rx: int) -> int:
        """int16 words per chirp: n_samples × lanes carried (4 with lanes = 4) × (2 if complex)."""
        return self.n_samples * (4 if self.lanes == 4 else n_rx) * (2 if self.sampling == "complex" else 1)

    def differences(self, other: "Layout") -> dict[str, tuple]:
        """{field: (this value, other's value)} where the two differ."""
        a, b = asdict(self), asdict(other)
        return {k: (a[k], b[k]) for k in a if a[k] != b[k]}


@dataclass(frozen=True)
class Scored:
    """A layout's score [dB] (module doc), the periodicity r at its loop length and its spectrum."""

    layout: Layout
    score: float
    coherence: float
    stats: SpectrumStats


def layouts_for(chirp_words: int, n_rx: int, encodings: tuple[str, ...]) -> list[Layout]:
    """Every layout whose chirps are ``chirp_words`` words long with ``n_rx`` receivers (n_samples ≥ 16)."""
    out = []
    for lanes, sampling, enc in itertools.product((2, 4), ("complex", "real"), encodings):
        if lanes == 4 and n_rx > 4:
            continue
        per = (4 if lanes == 4 else n_rx) * (2 if sampling == "complex" else 1)
        if chirp_words % per or chirp_words // per < 16:
            continue
        n = chirp_words // per
        if sampling == "complex" and (lanes == 2 and n % 2):
            continue
        variants = itertools.product(("iq", "qi"), ("lanes", "samples")) if sampling == "complex" else [("iq", "lanes")]
        out += [Layout(lanes, sampling, o, il, enc, n) for o, il in variants]
    return out


def loop_lags(r: np.ndarray, min_lag: int = 16, good: float = 0.5) -> list[int]:
    """Lags at which the stream repeats: the smallest lag ≥ ``min_lag`` whose r is within 0.9 of the
    best (when the best exceeds ``good``), else none (noise, a moving scene)."""
    if r.size <= min_lag:
        return []
    tail = r[min_lag:]
    best = float(tail.max())
    if best < good:
        return []
    return [int(min_lag + np.argmax(tail >= 0.9 * best))]


def decode_chirps(words: np.ndarray, layout: Layout, n_rx: int, max_chirps: int = MAX_CHIRPS) -> np.ndarray | None:
    """The first whole chirps (≤ ``max_chirps``) of signed ``words`` in ``layout`` →
    (n_samples, chirps, n_rx) counts; None when not one chirp fits."""
    per = layout.chirp_words(n_rx)
    k = min(max_chirps, words.size // per)
    if k < 1:
        return None
    return decode_dca1000(words[:k * per], layout.n_samples, k, n_rx, layout.sampling, layout.lanes,
                          layout.iq_order, layout.iq_interleave)


def score_layouts(words, n_rx: int, n_tdm: int, declared: Layout) -> list[Scored]:
    """Score ``declared`` and the candidate layouts of the int16 stream ``words`` (1-D, a recording's
    first frames) for ``n_rx`` receivers per chirp and ``n_tdm`` TX slots per loop; best first.

    Candidates: every lanes × sampling × I/Q order × interleave × plausible encoding whose chirp length
    is the declared one, the stream's repetition length over n_tdm, or that length itself (one TX slot)."""
    raw = np.asarray(words)[:MAX_WORDS]
    ev = encoding_evidence(raw)
    encodings = ("twos_complement", "offset_binary")
    penalty = {"twos_complement": max(0.0, ev), "offset_binary": max(0.0, -ev)}
    signed = {e: signed_words(raw, e).astype(np.float64) for e in encodings}
    for e in encodings:
        signed[e] -= signed[e].mean()
    best_enc = min(encodings, key=penalty.get)
    w_decl = declared.chirp_words(n_rx)
    r = periodicity(signed[best_enc], 4 * w_decl * n_tdm + 64)
    lags = loop_lags(r)
    chirp_lengths = {w_decl} | {lag // n_tdm for lag in lags if lag % n_tdm == 0} | set(lags)
    cands = {declared}
    for w in sorted(chirp_lengths):
        cands.update(layouts_for(w, n_rx, encodings))
    coh = {c: float(r[c.chirp_words(n_rx) * n_tdm]) if c.chirp_words(n_rx) * n_tdm < r.size else 0.0 for c in cands}
    r_max = max(coh.values())
    out = []
    for c in cands:
        z = decode_chirps(signed[c.encoding], c, n_rx)
        if z is None:
            continue
        st = spectrum_stats(z, c.sampling == "complex")
        score = (st.peak_db - 10 * st.symmetry + 0.5 * float(np.clip(st.near_far_db, -20, 0))
                 + 10 * (coh[c] - r_max) - penalty[c.encoding])
        out.append(Scored(c, float(score), coh[c], st))
    out.sort(key=lambda s: (-s.score, s.layout != declared))
    return out
