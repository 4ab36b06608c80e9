"""Antenna model: 3-D patch element pattern, planar TX/RX arrays, steering, coupling, beam metrics.

These are B_t and B_r of Eq. 1–6; every forward model takes its gains from here.

Geometry (DESIGN.md ego frame): the arrays lie in the y–z plane facing +x. Azimuth
θ = atan2(y, x) [rad], positive to the left; elevation ε [rad] above the horizontal plane.
A plane wave from (θ, ε) has direction u = (cos ε cos θ, cos ε sin θ, sin ε).

* RX element j sits at (y, z) = (j·d_rx, 0); TX element i at (i·d_tx, h_tx) with
  d_rx = rx_spacing·λ, d_tx = tx_spacing·λ (default n_rx·d_rx: a filled virtual array) and
  h_tx = tx_elevation_offset·λ — or, for any layout, where ``radar.tx_positions`` /
  ``radar.rx_positions`` put them ([[y, z], …] in wavelengths; ``radar.tx_layout``). Each element is a broadside column of ``n_elevation`` patches
  (vertical spacing elevation_spacing·λ): a planar n_elevation × (n_tx + n_rx) patch layout.
* MIMO (``radar.mimo``): TX elements take turns, so channel (i, j) is a virtual element at
  p_tx,i + p_rx,j (tx-major order), n_tx·n_rx channels. Without MIMO the TX elements radiate
  together as one beam steered to θ_t = ``radar.tx_steering`` and the n_rx RX elements are the
  channels; :func:`transmit_gain` carries the TX array factor into the path power.
* Steering: a path from (θ, ε) is shorter at channel k by p_k·u, so its phase there is
  advanced: a_k(θ, ε) = exp(−j 2π (y_k sin θ cos ε + z_k sin ε) / λ). This is the same sign that
  :func:`xnlos_core.signal.chain.dechirp` uses for the synthetic cube.
* Mutual coupling (optional): the recorded channel vector is x = C·x₀ with a coupling matrix C
  (n_channels × n_channels), measured (``radar.coupling_file``) or modelled
  (:func:`coupling_matrix`).
"""
from __future__ import annotations

import functools
import io
import zipfile
from pathlib import Path

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig


def _wrap(angle) -> np.ndarray:
    return np.angle(np.exp(1j * np.asarray(angle, dtype=np.float64)))  # (−π, π]


def column_factor(radar: RadarConfig, elevation) -> np.ndarray:
    """Power array factor of one broadside patch column, normalised to 1 at ε = 0, shape like ``elevation``.

    |Σ_m exp(j 2π m d_el sin ε / λ)|² / n_el² = (sin(n ψ/2) / (n sin(ψ/2)))², ψ = 2π d_el sin ε / λ.
    """
    n = radar.n_elevation
    el = np.asarray(elevation, dtype=np.float64)
    if n == 1:
        return np.ones_like(el)
    psi = 2 * np.pi * radar.elevation_spacing * np.sin(el)
    num, den = np.sin(n * psi / 2), n * np.sin(psi / 2)
    small = np.abs(den) < 1e-12
    return np.where(small, 1.0, (num / np.where(small, 1.0, den)) ** 2)


def element_pattern(radar: RadarConfig, azimuth, elevation=0.0) -> np.ndarray:
    """Normalised power pattern of one element (patch column), 1 at boresight, broadcast over θ, ε [rad]:

        P(θ, ε) = cos(θ)^q · cos(ε)^q_el · AF_col(ε)

    q = element_pattern_exponent (azimuth plane), q_el = element_pattern_exponent_el, AF_col
    from :func:`column_factor`. Zero behind the ground plane (|θ| ≥ 90° or |ε| ≥ 90°).
    """
    th, el = np.broadcast_arrays(_wrap(azimuth), _wrap(elevation))
    front = (np.abs(th) < np.pi / 2) & (np.abs(el) < np.pi / 2)
    # clip before the power: cos^q of a negative number is NaN for non-integer q
    ca = np.clip(np.cos(th), 0.0, None) ** radar.element_pattern_exponent
    ce = np.clip(np.cos(el), 0.0, None) ** radar.element_pattern_exponent_el
    return np.where(front, ca * ce * column_factor(radar, el), 0.0)


@functools.lru_cache(maxsize=64)
def _directivity(radar: RadarConfig, n: int = 721) -> float:
    th = np.linspace(-np.pi / 2, np.pi / 2, n)
    el = np.linspace(-np.pi / 2, np.pi / 2, n)
    g = element_pattern(radar, th[None, :], el[:, None])
    # dΩ = cos ε dθ dε on the front hemisphere (the pattern is zero behind)
    integral = np.trapezoid(np.trapezoid(g, th, axis=1) * np.cos(el), el)
    return float(4 * np.pi * g.max() / integral)


def element_directivity(radar: RadarConfig) -> float:
    """Directivity D = 4π·max P / ∮ P dΩ of :func:`element_pattern` (linear), by quadrature."""
    return _directivity(radar)


def radiation_efficiency(radar: RadarConfig) -> float:
    """η = G0 / D₁: stated single-patch gain (element_gain_dbi) over the single patch's directivity."""
    single = radar if radar.n_elevation == 1 else radar.model_copy(update={"n_elevation": 1})
    return 10.0 ** (radar.element_gain_dbi / 10.0) / _directivity(single)


def element_gain(radar: RadarConfig, azimuth, elevation=0.0) -> np.ndarray:
    """Power gain of one element (patch column), linear (not dB): G_e(θ, ε) = η·D·P(θ, ε).

    This is B_t = B_r of Eq. 1/3/5. P: :func:`element_pattern`; D its directivity; η the patch's
    radiation efficiency (:func:`radiation_efficiency`), so a single patch has boresight gain
    exactly G0 = 10^(element_gain_dbi/10) and a column of n_el patches gains what its narrower
    elevation beam gives (less than n_el·G0 when the patches are already directive).
    """
    scale = radiation_efficiency(radar) * _directivity(radar) if radar.n_elevation > 1 else \
        10.0 ** (radar.element_gain_dbi / 10.0)
    return scale * element_pattern(radar, azimuth, elevation)


def tx_positions(radar: RadarConfig) -> np.ndarray:
    """(n_tx, 2) TX element (y, z) positions [m] (module doc): ``radar.tx_layout``·λ, y centred on its mean.

    Centring each array on its own y shifts the virtual array as a whole, which no consumer sees
    (array gains are relative; :func:`channel_positions` re-centres the virtual array).
    """
    p = radar.tx_layout * radar.wavelength
    return np.stack([p[:, 0] - p[:, 0].mean(), p[:, 1]], axis=1)


def rx_positions(radar: RadarConfig) -> np.ndarray:
    """(n_rx, 2) RX element (y, z) positions [m]: ``radar.rx_layout``·λ, y centred on 0, z as configured."""
    p = radar.rx_layout * radar.wavelength
    return np.stack([p[:, 0] - p[:, 0].mean(), p[:, 1]], axis=1)


def channel_positions(radar: RadarConfig) -> np.ndarray:
    """(n_channels, 2) phase-centre (y, z) [m] of each recorded channel.

    MIMO: the virtual array p_tx,i + p_rx,j, tx-major (y equals ``radar.virtual_positions``),
    coinciding virtual elements kept (their channels add coherently); else the RX elements.
    """
    rx = rx_positions(radar)
    if not radar.mimo:
        return rx
    v = (tx_positions(radar)[:, None, :] + rx[None, :, :]).reshape(-1, 2)
    return v - np.array([v[:, 0].mean(), 0.0])


def virtual_layout(radar: RadarConfig) -> np.ndarray:
    """(n_channels, 2) virtual element (y, z) [wavelengths], uncentred: tx_i + rx_j tx-major with MIMO,
    else the RX elements. The positions p_k of the array factor Σ_k exp(j k·p_k)."""
    rx = radar.rx_layout
    return (radar.tx_layout[:, None, :] + rx[None, :, :]).reshape(-1, 2) if radar.mimo else rx


def has_elevation_aperture(radar: RadarConfig) -> bool:
    """True when the channels sit at more than one height z (elevation can be beamformed)."""
    z = channel_positions(radar)[:, 1] / radar.wavelength
    return bool(np.ptp(z) > 1e-9)


def array_response(positions, wavelength: float, azimuth, elevation=0.0) -> np.ndarray:
    """Steering vectors exp(−j 2π (y sin θ cos ε + z sin ε)/λ), shape (K, P) for positions (K, 2)
    [m] and P directions (θ, ε broadcast to 1-D), complex128, float64 phases."""
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    th, el = np.broadcast_arrays(np.atleast_1d(np.asarray(azimuth, dtype=np.float64)),
                                 np.atleast_1d(np.asarray(elevation, dtype=np.float64)))
    th, el = th.ravel(), el.ravel()
    path = np.outer(pos[:, 0], np.sin(th) * np.cos(el)) + np.outer(pos[:, 1], np.sin(el))
    # cycles reduced mod 1 before ×2π keeps the phase exact for apertures of many wavelengths
    return np.exp(-2j * np.pi * np.mod(path / wavelength, 1.0))


def steering_vector(radar: RadarConfig, theta, elevation=0.0) -> np.ndarray:
    """Channel response a_k(θ, ε), shape (n_channels, n_dirs), complex128, unit modulus per channel.

    θ, ε [rad]: scalars or 1-D (broadcast). No element pattern and no coupling included.
    """
    return array_response(channel_positions(radar), radar.wavelength, theta, elevation)


def array_gain(positions, wavelength: float, azimuth, steer: float, elevation=0.0, weights=None) -> np.ndarray:
    """Power gain |Σ w_k a_k(θ, ε) a_k*(θ₀, 0)|² / Σ|w_k|² of an array steered to θ₀ = ``steer`` [rad].

    Equals the number of elements at θ = θ₀ for uniform weights (the coherent array gain).
    Returns the shape of the broadcast (azimuth, elevation).
    """
    th, el = np.broadcast_arrays(np.asarray(azimuth, dtype=np.float64), np.asarray(elevation, dtype=np.float64))
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    w = np.ones(len(pos)) if weights is None else np.asarray(weights, dtype=np.float64)
    a = array_response(pos, wavelength, th.ravel(), el.ravel())
    a0 = array_response(pos, wavelength, steer)[:, 0]
    af = (w * a0.conj()) @ a
    return (np.abs(af) ** 2 / np.sum(w**2)).reshape(th.shape)


def beam_pattern(radar: RadarConfig, which: str, azimuth, steer: float = 0.0, elevation=0.0) -> np.ndarray:
    """B_t(θ; θ_t) or B_r(θ; θ_r): element gain × array gain of the TX or RX array steered to ``steer``.

    which: "tx" or "rx". Linear power gain; at the steering angle it is G_e·n (n elements).
    """
    if which not in ("tx", "rx"):
        raise InputError(f"beam_pattern: which must be 'tx' or 'rx', got {which!r}")
    pos = tx_positions(radar) if which == "tx" else rx_positions(radar)
    return element_gain(radar, azimuth, elevation) * array_gain(pos, radar.wavelength, azimuth, steer, elevation)


def transmit_gain(radar: RadarConfig, azimuth, elevation=0.0) -> np.ndarray:
    """Factor on a path's per-channel received power from transmitting with several elements at once.

    MIMO: 1 (one TX per chirp; the TX phase lives in the virtual channel). Otherwise the n_tx
    elements radiate coherently towards θ_t: |Σ_i a_i(θ, ε) a_i*(θ_t)|² (n_tx² at θ_t: n_tx times
    the power, n_tx times the directivity).
    """
    th, el = np.broadcast_arrays(np.asarray(azimuth, dtype=np.float64), np.asarray(elevation, dtype=np.float64))
    if radar.mimo:
        return np.ones(th.shape)
    return radar.n_tx * array_gain(tx_positions(radar), radar.wavelength, th, radar.tx_steering, el)


def azimuth_weights(radar: RadarConfig, window: str | None = None) -> np.ndarray:
    """Real taper over the channels (n_channels,), symmetric; default radar.azimuth_window.

    Uniform rows (no ``tx_positions`` / ``rx_positions``): the window over the channel index, as
    the tx-major channels of a filled ULA are in aperture order. Explicit layouts: the taper
    follows each channel's y (:func:`aperture_taper`), so a raised or interleaved transmitter
    does not scramble it. ``radar.azimuth_channels = "row"`` on a layout with channels at several
    heights: the taper over the channels of :func:`azimuth_row` by their y, 0 on the others.
    """
    name = radar.azimuth_window if window is None else window
    try:
        return _azimuth_weights(radar, name).copy()
    except TypeError:  # an unhashable window spec (e.g. a list): computed without the cache
        return _azimuth_weights_uncached(radar, name)


@functools.lru_cache(maxsize=64)
def _azimuth_weights(radar: RadarConfig, name: str) -> np.ndarray:
    """:func:`azimuth_weights`, computed once per (frozen, hashable) radar and window, read-only."""
    w = _azimuth_weights_uncached(radar, name)
    w.flags.writeable = False
    return w


def symmetric_window(name: str, n: int) -> np.ndarray:
    """The n-point symmetric (``fftbins=False``) scipy.signal window ``name``, (n,) float64: the
    taper of every window in xnlos (range, Doppler, azimuth), so a beam or spectrum is symmetric
    about its centre. scipy.signal is imported here, not at module level: it loads scipy.stats
    (~0.2 s), which an ``xnlos`` start need not pay."""
    from scipy.signal import get_window

    return np.asarray(get_window(name, n, fftbins=False), dtype=np.float64)


def _azimuth_weights_uncached(radar: RadarConfig, name: str) -> np.ndarray:
    if radar.azimuth_channels == "row" and has_elevation_aperture(radar):
        keep = azimuth_row(radar)
        w = np.zeros(radar.n_channels)
        w[keep] = aperture_taper(name, channel_positions(radar)[keep, 0] / radar.wavelength)
        return w
    if radar.has_custom_layout:
        return aperture_taper(name, channel_positions(radar)[:, 0] / radar.wavelength)
    return symmetric_window(name, radar.n_channels)


def azimuth_row(radar: RadarConfig) -> np.ndarray:
    """(n_channels,) bool: the channels at the height z that most channels share (ties: the height
    whose channels span the widest y, then the lowest). With ``radar.azimuth_channels = "row"`` the RA
    map is beamformed from these alone (:func:`azimuth_weights` gives the others weight 0).

    Why: at ε = 0 a channel's height adds no phase, so a raised transmitter's channels beamform as if
    they sat in the row; a target at elevation ε ≠ 0 gives them an extra phase 2π·Δz·sin ε/λ (π/2 at
    ε = 30° for Δz = λ/2), and the sub-array they form then adds its own sidelobes to the map
    (xWR1843-style 3 × 4 board, target at −2°, ε = 30°: −19 dB at −50° with all channels, −41 dB with the
    row of 8)."""
    p = channel_positions(radar) / radar.wavelength
    z = np.round(p[:, 1] / 1e-9) * 1e-9
    levels = np.unique(z)
    best = max(levels, key=lambda h: (int(np.sum(z == h)), float(np.ptp(p[z == h, 0])), -float(h)))
    return z == best


def aperture_taper(window: str, y) -> np.ndarray:
    """Window weights (K,) for elements at along-array positions y (K,) [any unit], any order.

    A filled uniform line (distinct, equally spaced y) gets the K-point window by rank in y, which
    is the index taper when y ascends. Otherwise (gaps, coinciding virtual elements) the window is
    sampled finely over [min y, max y] and read at each y, so coinciding elements weigh the same.
    All elements at one y: uniform weights (no azimuth aperture to taper).
    """
    y = np.asarray(y, dtype=np.float64)
    k = len(y)
    order = np.argsort(y, kind="stable")
    ys = y[order]
    span = ys[-1] - ys[0] if k else 0.0
    if k < 2 or span <= 0:
        return np.ones(k)
    gaps = np.diff(ys)
    w = np.empty(k)
    if np.all(gaps > 1e-9 * span) and np.allclose(gaps, gaps[0], rtol=1e-6, atol=0.0):
        w[order] = symmetric_window(window, k)
        return w
    fine = 4096 + 1
    return np.interp(y, np.linspace(ys[0], ys[-1], fine), symmetric_window(window, fine))


def array_factor(radar: RadarConfig, theta, steer_to: float = 0.0, window: str = "boxcar",
                 elevation=0.0) -> np.ndarray:
    """Normalised power array factor |Σ w_k a_k(θ, ε) a_k*(θ₀, 0)|² / (Σ w_k)² of the channels
    (the virtual array with MIMO), shape of the broadcast (θ, ε).

    Equals 1 at θ = θ₀ = ``steer_to`` [rad], ε = 0; ``window`` is a scipy.signal window name
    (:func:`azimuth_weights`); ``elevation`` ε [rad] of the arriving wave: channels at different
    heights (a raised transmitter) dephase there. Element pattern not included (multiply by
    :func:`element_gain` for the full two-way beam).
    """
    th = np.asarray(theta, dtype=np.float64)
    w = azimuth_weights(radar, window)
    return array_gain(channel_positions(radar), radar.wavelength, th, steer_to, elevation,
                      weights=w) * np.sum(w**2) / w.sum() ** 2


@functools.lru_cache(maxsize=32)
def coupling_matrix(radar: RadarConfig) -> np.ndarray | None:
    """Mutual-coupling matrix C (n_channels, n_channels) complex128, or None when none is configured.

    Measured (``radar.coupling_file``): .npy / .npz (array ``coupling``) / .csv of complex numbers,
    loaded without pickle. Modelled (``radar.coupling_db``): between two elements of one array a
    distance d apart, c(d) = (10^(c_dB/20)·e^{jφ})^(d/d_rx) with d_rx the RX spacing (geometric
    decay with separation, so neighbours couple at c_dB and the 2λ-spaced TX elements barely do),
    c(0) = 1; the MIMO matrix is C_tx ⊗ C_rx (tx-major like the channels). Cached per radar.
    """
    if radar.coupling_file is not None:
        return _load_coupling(radar)
    if radar.coupling_db is None:
        return None
    d0 = radar.rx_spacing * radar.wavelength
    base_mag, base_phase = 10 ** (radar.coupling_db / 20), radar.coupling_phase

    def toeplitz(pos):
        # element distance in the y–z plane (hypot(dy, 0) = |dy| exactly: rows as before)
        d = np.hypot(pos[:, None, 0] - pos[None, :, 0], pos[:, None, 1] - pos[None, :, 1]) / d0
        return np.where(d == 0, 1.0 + 0j, base_mag**d * np.exp(1j * base_phase * d))

    c = toeplitz(rx_positions(radar))
    return np.kron(toeplitz(tx_positions(radar)), c) if radar.mimo else c


def _load_coupling(radar: RadarConfig) -> np.ndarray:
    """The measured matrix; the file is read whole through :func:`xnlos_core.files.read_file_bytes`
    (regular files only, never blocking on a FIFO), then parsed from memory without pickle."""
    from xnlos_core.errors import ConfigError
    from xnlos_core.files import decode_utf8, read_file_bytes

    path = Path(radar.coupling_file)
    m = radar.n_channels
    try:
        data = read_file_bytes(path, what=f"coupling_file {str(path)!r}")
        if path.suffix == ".csv":
            c = np.loadtxt(io.StringIO(decode_utf8(data, f"coupling_file {str(path)!r}")), delimiter=",",
                           dtype=np.complex128, ndmin=2)
        elif path.suffix == ".npz":
            with np.load(io.BytesIO(data), allow_pickle=False) as z:
                c = np.asarray(z["coupling"])
        else:
            c = np.load(io.BytesIO(data), allow_pickle=False)
    except (ConfigError, OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise InputError(f"coupling_file {str(path)!r}: cannot read a coupling matrix "
                         f"(.npy, .npz with 'coupling', or .csv of complex): {exc}") from None
    c = np.asarray(c, dtype=np.complex128)
    if c.shape != (m, m) or not np.all(np.isfinite(c)):
        raise InputError(f"coupling_file {str(path)!r}: expected a finite ({m}, {m}) matrix "
                         f"(n_channels × n_channels), got shape {c.shape}")
    return c


def beam_metrics(radar: RadarConfig, window: str | None = None, step: float = 2e-5) -> dict[str, float]:
    """Numerical beam metrics of the delay-and-sum beam steered to boresight.

    window: scipy window name, default ``radar.azimuth_window`` (what the RA map uses).
    Returns a dict:
      ``beamwidth_3db`` [rad]: full width between the −3 dB points (the azimuth resolution);
      ``first_null`` [rad]: angle of the first minimum of the main lobe (from boresight);
      ``peak_sidelobe_db`` [dB]: highest array-factor level beyond the first null, ≤ 0;
      ``*_deg`` copies in degrees. Grid: ``step`` [rad] over [0, π/2] (the beam is symmetric).
    """
    th = np.arange(0.0, np.pi / 2, step)
    af = array_factor(radar, th, 0.0, radar.azimuth_window if window is None else window)
    # −3 dB crossing: linear interpolation between the bracketing grid points
    i = int(np.argmax(af < 0.5))
    half = th[i - 1] + (0.5 - af[i - 1]) * (th[i] - th[i - 1]) / (af[i] - af[i - 1])
    # first null: first point where the main lobe stops falling
    rising = np.flatnonzero(np.diff(af) > 0)
    j = int(rising[0]) if len(rising) else len(af) - 1
    sidelobe = float(af[j:].max()) if j < len(af) - 1 else 0.0
    out = {
        "beamwidth_3db": float(2 * half),
        "first_null": float(th[j]),
        "peak_sidelobe_db": float(10 * np.log10(max(sidelobe, 1e-30))),
    }
    out["beamwidth_3db_deg"] = float(np.degrees(out["beamwidth_3db"]))
    out["first_null_deg"] = float(np.degrees(out["first_null"]))
    return out
