"""Learned detectors (Sec. 4.1): a network maps RA-map features to LOS / mNLOS confidences, and
peaks of those become Detections. Swin-UNet (the paper's), UNet (its ablation), "See Further
Than CFAR" and RTN (the learned baselines of Table 2) share this plugin base and differ only in
the network and output head stored in their checkpoint.

Pipeline per frame: features (:mod:`.features`: log power over the map's median in 10 dB
units, cos/sin of the phase) → zero-padded to the network's multiple → network → cropped back →
peaks with sub-bin refinement (:mod:`.decode`) → range / azimuth by interpolating the fractional
cells on the map's axes. ``tta = "flip"`` trades time for accuracy: the logits are the mean of the
network's on the map and, mirrored back, on the map mirrored in azimuth (a left–right mirrored
scene is as plausible as the scene, and no feature depends on the sign of the azimuth).
Standard deviations: the refinement residuals measured on the validation
split when the model was trained (checkpoint metadata ``decode.calibration``, in cells; 1/√12
cell without one), times the local bin spacing.

The network is built from the checkpoint on the first ``detect`` — or before the first frame by
:meth:`LearnedDetector.warm_up`, which the pipeline calls, with one forward on an empty map of the
radar's grid — and cached (``__init__`` only stores parameters). Inference runs through
:class:`~plugins.detectors.inference.InferenceRunner`: ``torch.inference_mode`` and channels-last
(float32 outputs equal to the plain network's within 1e-5), with opt-in ``precision = "bf16"``
and ``compile = true`` and the torch thread count ``threads`` (see that module). ``checkpoint = "default"`` loads the model shipped in
``plugins/detectors/models/<name>.pt``; ``"none"`` builds an untrained network with default
hyper-parameters from ``seed`` (deterministic, but it detects nothing meaningful: for tests of the
plumbing only).

Self-describing models: a checkpoint records the radar and RA grid it was trained on (metadata
``trained_on``, or for older checkpoints the sidecar ``NAME.trained_on.json``, see
:mod:`plugins.training.trained_on`): carrier, bandwidth, the virtual array's element positions and
the grid. :meth:`LearnedDetector.check_model` compares them with the radar whose maps the detector
will see when the pipeline is checked (``xnlos check``) and warmed up, before any frame: a
difference is a :class:`~xnlos_core.errors.ConfigError` naming each item (trained value, value
here), unless ``allow_mismatch = true``, which runs anyway with one
:class:`~xnlos_core.errors.GridMismatchWarning` and lists the differences in the run's provenance
(``accepted_mismatch``). A frame whose radar was not checked before (e.g. saved frames of another
radar) is compared too: a GridMismatchWarning once per detector instance, or with ``strict = true``
(and without ``allow_mismatch``) an InputError. A checkpoint without a record (and
``checkpoint = "none"``) is not checked.
"""
from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import warnings

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, StrictBool, field_validator, model_validator

from plugins.detectors.detection_doppler import nearest_cells, strongest_cells, with_cell_velocity
from xnlos_core.core_share import limited
from xnlos_core.errors import ConfigError, GridMismatchWarning, InputError
from xnlos_core.interfaces import Detector, FrameState
from xnlos_core.radar import RadarConfig
from xnlos_core.types import Detections, Frame, RAMap
from xnlos_core.param_paths import config_path

from .inference import InferenceRunner

MODELS_DIR = Path(__file__).with_name("models")
UNIFORM_STD = 1.0 / np.sqrt(12.0)  # cells: the error of a position uniform within one cell


class LearnedParams(BaseModel):
    """Parameters shared by the learned detectors."""

    model_config = ConfigDict(extra="forbid")
    checkpoint: Annotated[str, config_path("default", "none")] = Field(
        "default", description="checkpoint file from `xnlos train`, relative to the config file's folder; "
                               "'default': the model shipped with xnlos; 'none': untrained (tests only)")
    model: str | None = Field(None, pattern=r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}$",
                              description="a model shipped with xnlos, by name (plugins/detectors/models/NAME.pt, "
                                          "e.g. 'swin_unet_doppler', which also reads the Doppler channels); "
                                          "None: checkpoint decides")
    device: str = Field("auto", pattern=r"^(auto|cpu|cuda(:\d+)?|mps)$",
                        description="torch device: auto (cuda when available, else cpu), cpu, cuda[:N], mps")
    threshold: float | tuple[float, float] | None = Field(
        None, description="confidence threshold in (0, 1), or (LOS, mNLOS) thresholds; None: the per-class "
                          "values tuned on the validation split (checkpoint)")
    window: tuple[int, int] | None = Field(None, description="peak neighbourhood (range, azimuth) [cells], odd; "
                                                            "None: the checkpoint's")
    cells: bool | None = Field(None, description="keep only the most confident peak per radar resolution cell "
                                                 "(decode module doc); None: the checkpoint's choice")
    class_nms: bool = Field(True, description="suppress a weaker peak of the other class within the window")
    max_detections: int = Field(1000, ge=1, le=100_000, description="keep at most this many peaks")
    velocity_radius: int = Field(1, ge=0, le=3, description="with Doppler maps, each detection's radial velocity "
                                 "is read at the strongest cell within ± this many cells of its peak cell (0: the "
                                 "peak cell; plugins.detectors.detection_doppler.strongest_cells)")
    seed: int = Field(0, ge=0, lt=2**63, description="weights of an untrained network (checkpoint='none')")
    threads: int | None = Field(None, ge=1, le=1024, description="torch intra-op CPU threads during inference, "
                                "restored afterwards; None: torch's setting, which the process thread policy "
                                "makes one per available core (OMP_NUM_THREADS, with passive OpenMP waiting, so "
                                "that several threads stay fast when other processes share the cores; BLAS runs "
                                "1 thread during the stages; xnlos_core.threads)")
    precision: Literal["fp32", "bf16"] = Field(
        "fp32", description="'fp32': float32 inference (default); 'bf16': autocast to bfloat16 on cpu / cuda, "
                            "~2× faster on CPUs with bf16 units, detections within the F1 stated in "
                            "benchmarks/detector_speed.md")
    compile: StrictBool = Field(False, description="torch.compile the network (compiled during warm-up); "
                                                   "where compile is unavailable: a CompileFallbackWarning "
                                                   "and the eager network")
    tta: Literal["none", "flip"] = Field("none", description="test-time augmentation: 'flip' averages the logits "
                                         "of the map and of its azimuth mirror (twice the network time; "
                                         "dense heads only)")
    strict: bool = Field(False, description="refuse (InputError) a frame whose radar was not checked before the "
                                            "run (check_model) and differs from the one the checkpoint was "
                                            "trained on; false: warn once (GridMismatchWarning)")
    allow_mismatch: StrictBool = Field(
        False, description="run the checkpoint on a radar other than the one it was trained on (carrier, "
                           "bandwidth, virtual array, grid): one GridMismatchWarning, and the run's provenance "
                           "lists each difference; false: refuse it (ConfigError) when the pipeline is checked "
                           "or warmed up")

    @field_validator("threshold")
    @classmethod
    def _unit(cls, v):
        vals = [v] if isinstance(v, float | int) else list(v or [])
        if any(not 0 < t < 1 for t in vals):
            raise ValueError(f"threshold {v}: must lie in (0, 1)")
        return v

    @model_validator(mode="after")
    def _one_model(self):
        if self.model is not None and self.checkpoint != "default":
            raise ValueError(f"give model = {self.model!r} (a shipped model) or checkpoint = {self.checkpoint!r} "
                             "(a file), not both")
        return self

    @field_validator("window")
    @classmethod
    def _odd(cls, v):
        if v is not None and any(s < 1 or s > 31 or s % 2 == 0 for s in v):
            raise ValueError(f"window {v}: each size must be odd and in 1…31 cells")
        return v


def shipped_models(architecture: str) -> list[str]:
    """Names of the models shipped for ``architecture`` (plugins/detectors/models/NAME.pt whose
    metadata sidecar NAME.json names that architecture)."""
    import json

    names = []
    for pt in sorted(MODELS_DIR.glob("*.pt")):
        side = pt.with_suffix(".json")
        try:
            arch = json.loads(side.read_text()).get("architecture") if side.is_file() else None
        except (OSError, ValueError):
            arch = None
        if arch == architecture:
            names.append(pt.stem)
    return names


def shipped_model(architecture: str, name: str) -> Path:
    """The file of the shipped model ``name`` for ``architecture``; ConfigError naming the choices."""
    names = shipped_models(architecture)
    if name not in names:
        import difflib

        close = difflib.get_close_matches(name, names, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ConfigError(f"params.model = {name!r}: no such {architecture} model shipped with xnlos{hint}; "
                          f"shipped: {', '.join(names) or 'none'}")
    return MODELS_DIR / f"{name}.pt"


def resolve_device(name: str):
    """torch.device for 'auto' | 'cpu' | 'cuda[:N]' | 'mps'; a missing accelerator is an InputError."""
    import torch

    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise InputError(f"device {name!r}: CUDA is not available here; use device = 'cpu' or 'auto'")
    if name == "mps" and not (hasattr(torch.backends, "mps") and torch.backends.mps.is_available()):
        raise InputError("device 'mps': not available here; use device = 'cpu' or 'auto'")
    return torch.device(name)


def run_network(net, features: np.ndarray, device, threads: int | None = None) -> np.ndarray:
    """Raw network output for features (4, H, W) (padded, not cropped back: see the head) as float32,
    the plain way: contiguous (NCHW) tensors in float32. The detectors run the faster
    :class:`~plugins.detectors.inference.InferenceRunner` (channels-last, optional bf16 / compile);
    this is its float32 reference (equal within 1e-5).

    threads: torch CPU threads for this call (restored afterwards; None: torch's setting, the process
    thread policy's count, :mod:`xnlos_core.threads`)."""
    import torch

    from .features import pad_to_multiple

    x = torch.from_numpy(np.ascontiguousarray(features))[None].to(device)
    x, _ = pad_to_multiple(x, net.multiple)
    before = torch.get_num_threads()
    if threads:
        threads = limited(threads)  # kept to the cores other processes leave free (xnlos_core.core_share)
        torch.set_num_threads(threads)
    try:
        with torch.inference_mode():
            out = net(x)[0]
    finally:
        if threads:
            torch.set_num_threads(before)
    return out.float().cpu().numpy()


def detections_from_output(out: np.ndarray, head, ra_map: RAMap, threshold, window: tuple[int, int],
                           class_nms: bool, max_detections: int, calibration: dict[str, float] | None = None,
                           cells: bool = False, velocity_radius: int = 1) -> Detections:
    """Detections of one raw network output (see :mod:`.tasks`) on the grid of ``ra_map``.

    threshold: one confidence threshold, or (LOS, mNLOS) thresholds (peaks are found at the lower
    one, then each class keeps those reaching its own). cells: keep the most confident peak per
    radar resolution cell (and class; of both classes with ``class_nms``), see :mod:`.decode`.
    Ordered by descending confidence, at most ``max_detections``. With Doppler maps on ``ra_map``
    each detection carries the radial velocity of the strongest cell (|κ|²) within ±``velocity_radius``
    cells of the cell nearest its refined position (0: that cell itself; refinement is ≤ ½ cell;
    :func:`plugins.detectors.detection_doppler.strongest_cells`), else velocity is None."""
    thr = (float(threshold),) * 2 if np.ndim(threshold) == 0 else (float(threshold[0]), float(threshold[1]))
    h, w = ra_map.shape
    if out.ndim != 3:
        raise InputError(f"network output: expected (channels, H, W), got shape {out.shape}")
    if head.describe()["kind"] == "dense":
        out = out[:, :h, :w]
    fr, fc, k, conf = head.peaks(out, min(thr), tuple(window), class_nms, h * w * 2 if cells else max_detections)
    inside = (fr > -0.5) & (fr < h - 0.5) & (fc > -0.5) & (fc < w - 0.5) & (conf > np.asarray(thr)[k])
    fr, fc, k, conf = np.clip(fr[inside], 0, h - 1), np.clip(fc[inside], 0, w - 1), k[inside], conf[inside]
    ir, ia = np.arange(h), np.arange(w)
    rng = np.interp(fr, ir, ra_map.range_axis)
    az = np.interp(fc, ia, ra_map.azimuth_axis)
    cal = calibration or {}
    dr = np.interp(fr, ir, np.gradient(ra_map.range_axis))
    da = np.interp(fc, ia, np.gradient(ra_map.azimuth_axis))
    rs = cal.get("range_cells", UNIFORM_STD) * dr
    azs = cal.get("azimuth_cells", UNIFORM_STD) * da
    det = Detections(rng, az, k.astype(np.int8), np.clip(conf, 0.0, 1.0), rs, azs)
    det = with_cell_velocity(det, ra_map, *strongest_cells(ra_map, *nearest_cells(fr, fc, (h, w)), velocity_radius))
    if cells and len(rng):
        from xnlos_core.metrics import resolution_groups

        from .decode import one_per_cell

        keep = one_per_cell(resolution_groups(det.position, ra_map.radar, None if class_nms else k), conf)
        keep = keep[np.argsort(-conf[keep], kind="stable")][:max_detections]
        det = det.select(keep)
    return det


class LearnedDetector(Detector, FrameState):
    """Base of the learned detectors: network from a checkpoint, peaks of its confidence maps.

    A model that reads previous frames (input channels ``log_power_prev*``,
    :func:`plugins.detectors.features.map_features`) keeps the last frames' log power of the running
    sequence and carries state (:class:`~xnlos_core.interfaces.FrameState`): the pipeline resets it at
    each sequence start and replays a resumed run from frame 0. Other models carry none."""

    Params = LearnedParams
    architecture: ClassVar[str] = ""

    def _load(self) -> None:
        if getattr(self, "_net", None) is not None:
            return
        from plugins.training.checkpoint import load_checkpoint

        from .nets import build_model
        from .tasks import default_head, make_head

        p = self.params
        device = resolve_device(p.device)
        if p.checkpoint == "none":
            import torch

            from .nets import architectures

            arch = architectures()[self.architecture]
            with torch.random.fork_rng(devices=[]):
                torch.manual_seed(p.seed)
                net = arch.module(arch.HParams())
            meta: dict[str, Any] = {"architecture": self.architecture, "hparams": net.hp.model_dump(),
                                    "head": default_head(self.architecture, net.hp).describe()}
        else:
            path = shipped_model(self.architecture, p.model) if p.model else (
                MODELS_DIR / f"{self.architecture}.pt" if p.checkpoint == "default" else Path(p.checkpoint))
            if p.checkpoint == "default" and not path.is_file():
                raise InputError(f"{type(self).__name__}: no shipped checkpoint {path}; train one with "
                                 f"`xnlos train configs/training/{self.architecture}.toml` and set "
                                 "params.checkpoint to its path")
            sd, meta, _ = load_checkpoint(path, self.architecture)
            net = build_model(meta, sd, source=f"checkpoint {str(path)!r}")
            if "trained_on" not in meta:
                from plugins.training.trained_on import read_sidecar

                rec = read_sidecar(path, meta.get("weights_sha256"))
                if rec is not None:
                    meta = {**meta, "trained_on": rec}
        self._meta = meta
        self._grid_warned = False
        self._checked: dict[RadarConfig, list[str]] = {}  # radar → differences accepted (check_model)
        self._head = make_head(meta["head"])
        self._device = device
        self._runner = InferenceRunner(net, device, p.precision, p.compile, p.threads, name=type(self).__name__)
        self._net = self._runner.net  # eval mode, channels-last
        self._warm_shapes: set[tuple[int, int]] = set()
        from collections import deque

        from .features import parse_layout

        self._history: deque = deque(maxlen=parse_layout(self.input_channels_of(meta))[1])  # last frames' ℓ

    def warm_up(self, radar: RadarConfig | None = None) -> int:
        """Load the network and run it once on an all-zero map of ``radar``'s grid (n_range_bins ×
        n_azimuth_bins), so that loading, kernel set-up and (``compile = true``) compilation are not
        paid by the first frame; the pipeline calls it before its first frame
        (:meth:`xnlos_core.pipeline.Pipeline.warm_up`). Once per grid shape: returns the number of
        network forwards made now (1, or 0 when already warm for that shape or ``radar`` is None).
        The pipeline compares the checkpoint with the maps' radar first (:meth:`check_model`)."""
        self._load()
        if radar is None:
            return 0
        shape = (radar.n_range_bins, radar.n_azimuth_bins)
        if shape in self._warm_shapes:
            return 0
        n = self._runner.warm_up(shape)
        self._warm_shapes.add(shape)
        return n

    @property
    def forwards(self) -> int:
        """Network forwards made so far (warm-up included; 0 before the network is loaded)."""
        runner = getattr(self, "_runner", None)
        return runner.forwards if runner is not None else 0

    @property
    def metadata(self) -> dict[str, Any]:
        """The checkpoint's metadata record (loads the network if needed)."""
        self._load()
        return self._meta

    @staticmethod
    def input_channels_of(meta: dict[str, Any]) -> tuple[str, ...]:
        """The input channels a checkpoint's metadata records (the four power-map channels without a
        record)."""
        from .features import RA_CHANNELS

        return tuple(meta.get("features", {}).get("channels", RA_CHANNELS))

    @property
    def input_channels(self) -> tuple[str, ...]:
        """The names of the network's input channels (checkpoint metadata ``features.channels``; the
        four power-map channels for checkpoints without a record), :mod:`.features`."""
        self._load()
        return self.input_channels_of(self._meta)

    @property
    def needs_doppler(self) -> bool:
        """Whether the model's inputs include Doppler channels (it refuses maps without them)."""
        from .features import parse_layout

        return parse_layout(self.input_channels)[0]

    @property
    def previous_frames(self) -> int:
        """How many earlier frames' log power the model reads (0 for most)."""
        from .features import parse_layout

        return parse_layout(self.input_channels)[1]

    @property
    def carries_state(self) -> bool:
        """True for a model that reads previous frames (:class:`~xnlos_core.interfaces.FrameState`)."""
        return self.previous_frames > 0

    def reset(self) -> None:
        """Forget the previous frames (the start of a run or a sequence)."""
        history = getattr(self, "_history", None)
        if history is not None:
            history.clear()

    def _model_name(self) -> str:
        p = self.params
        return f"model {p.model!r}" if p.model else f"checkpoint {p.checkpoint!r}"

    def state_sha256(self) -> str | None:
        """The checkpoint's ``weights_sha256`` (None for ``checkpoint = "none"``: the seed decides)."""
        return None if self.params.checkpoint == "none" else self.metadata["weights_sha256"]

    def _decode_defaults(self) -> tuple[tuple[float, float], tuple[int, int], dict, bool]:
        """(thresholds, window, calibration, cells): the parameters', else the checkpoint's."""
        dec = self._meta.get("decode", {})
        thr = self.params.threshold if self.params.threshold is not None else dec.get("threshold", 0.3)
        thr = (float(thr),) * 2 if np.ndim(thr) == 0 else (float(thr[0]), float(thr[1]))
        win = self.params.window if self.params.window is not None else tuple(dec.get("window", (1, 3)))
        cells = self.params.cells if self.params.cells is not None else bool(dec.get("cells", False))
        return thr, tuple(win), dec.get("calibration", {}), cells

    def check_model(self, radar: RadarConfig) -> list[str]:
        """Compare the radar the checkpoint was trained on with ``radar``, whose maps the detector will
        see (:func:`plugins.training.trained_on.radar_mismatches`: carrier, bandwidth, virtual array,
        range and azimuth grid). A difference is a ConfigError naming each item (trained value, value
        here), unless ``allow_mismatch``: then one GridMismatchWarning per instance. Returns the
        differences accepted ([] when they agree, the checkpoint has no record or is ``"none"``), which
        :meth:`xnlos_core.pipeline.Pipeline.provenance` records; frames of ``radar`` are not compared
        again (:meth:`check_grid`)."""
        from plugins.training.trained_on import radar_mismatches

        self._load()
        rec = self._meta.get("trained_on")
        if rec is None:
            return []
        if radar in self._checked:
            return list(self._checked[radar])
        problems = radar_mismatches(rec, radar)
        if problems:
            what = f"{type(self).__name__} ({self._model_name()})"
            text = "; ".join(problems)
            if not self.params.allow_mismatch:
                raise ConfigError(f"{what} was trained on another radar than the one whose maps it would see: "
                                  f"{text}. Its outputs there are not what its validation figures describe: retrain "
                                  "it on maps of this radar (xnlos train), or set allow_mismatch = true in the "
                                  "detector's params to run anyway (the run's provenance records it)")
            if not self._grid_warned:
                self._grid_warned = True
                warnings.warn(f"{what} runs on another radar than it was trained on (allow_mismatch = true): "
                              f"{text}; its outputs are not what its validation figures describe (retrain on "
                              "maps of this radar)", GridMismatchWarning, stacklevel=3)
        self._checked[radar] = problems
        return list(problems)

    def check_grid(self, ra_map: RAMap, where: str = "frame") -> list[str]:
        """What differs between ``ra_map`` and the radar / grid the checkpoint was trained on (module
        doc; :func:`plugins.training.trained_on.map_mismatches`); warns (GridMismatchWarning, once per
        instance) or, with ``strict`` and without ``allow_mismatch``, raises InputError. A map on the
        grid of a radar :meth:`check_model` accepted is not compared again. [] when they agree or the
        checkpoint has no record."""
        from plugins.training.trained_on import axis_summary, map_mismatches, mismatch_message

        self._load()
        rec = self._meta.get("trained_on")
        if rec is None:
            return []
        radar = ra_map.radar
        if radar in self._checked and axis_summary(ra_map.range_axis) == axis_summary(radar.range_axis) and \
                axis_summary(ra_map.azimuth_axis) == axis_summary(radar.azimuth_axis):
            return []  # decided before the run (check_model)
        problems = map_mismatches(rec, ra_map)
        if problems:
            what = f"{type(self).__name__} ({self._model_name()}) on {where}"
            msg = mismatch_message(what, rec, ra_map, problems)
            if self.params.strict and not self.params.allow_mismatch:
                raise InputError(f"{msg}; strict = true refuses it (set strict = false to only warn, or "
                                 "allow_mismatch = true)")
            if not self._grid_warned:
                self._grid_warned = True
                warnings.warn(msg, GridMismatchWarning, stacklevel=3)
        return problems

    def output(self, frame: Frame) -> np.ndarray:
        """Raw network output of ``frame`` (float32): dense logits (2, H', W') of the zero-padded map
        (H' ≥ H, W' ≥ W; rows and columns beyond the map are padding), or a grid head's (6, H'/s_r, W'/s_a);
        with ``tta = "flip"`` the flip-averaged logits. :meth:`decode` turns it into detections."""
        from .features import map_features

        self.check_frame(frame)
        self._load()
        self.check_grid(frame.ra_map, f"frame {frame.index}")
        feats = map_features(frame.ra_map, self.input_channels,
                             self._meta.get("features", {}).get("dynamic_range_db", 200.0),
                             name=f"{type(self).__name__} ({self._model_name()}) on frame {frame.index}: RAMap",
                             previous=self._history)
        if self._history.maxlen:
            self._history.appendleft(feats[0])
        out = self._runner(feats)
        if self.params.tta == "flip":
            kind = self._head.describe()["kind"]
            if kind != "dense":
                raise ConfigError(f"{type(self).__name__}: tta = 'flip' needs a dense head; this checkpoint's "
                                  f"head is {kind!r}")
            w = feats.shape[-1]
            back = self._runner(feats[..., ::-1])[..., :w][..., ::-1]
            out[..., :w] = 0.5 * (out[..., :w] + back)
        if not np.all(np.isfinite(out)):
            raise InputError(f"{type(self).__name__}: the network produced non-finite outputs on frame "
                             f"{frame.index} (the checkpoint's weights are broken)")
        return out

    def heatmap(self, frame: Frame) -> np.ndarray:
        """Confidence maps (2, H', W') in [0, 1] (LOS, mNLOS); map resolution for dense heads, the
        head's grid for a grid head."""
        out = self.output(frame)
        h, w = frame.ra_map.shape
        z = out[:2, :h, :w] if self._head.describe()["kind"] == "dense" else out[:2]
        return (1.0 / (1.0 + np.exp(-z.astype(np.float64)))).astype(np.float32)

    def decode(self, out: np.ndarray, ra_map: RAMap) -> Detections:
        """Detections of a network output ``out`` of this detector's head (:meth:`output`; dense logits
        may also come cropped to the map, (2, H, W)) on the grid of ``ra_map``, decoded as :meth:`detect`
        decodes: the parameters' thresholds, window and cell suppression, else the checkpoint's. Outputs
        of several networks with the same head kind, combined (e.g. logits averaged), decode here too."""
        self._load()
        thr, win, cal, cells = self._decode_defaults()
        return detections_from_output(out, self._head, ra_map, thr, win, self.params.class_nms,
                                      self.params.max_detections, cal, cells, self.params.velocity_radius)

    def detect(self, frame: Frame) -> Detections:
        """Detections of ``frame``, ordered by descending confidence (an empty map may give none)."""
        return self.decode(self.output(frame), frame.ra_map)


class SwinUNetDetector(LearnedDetector):
    """Swin-UNet dense LOS/mNLOS confidence maps + sub-bin peaks (the paper's detector, Sec. 4.1)."""

    architecture = "swin_unet"


class UNetDetector(LearnedDetector):
    """Convolutional UNet with the Swin-UNet's head and Eq. 8 loss (the paper's UNet ablation)."""

    architecture = "unet"


class FurtherThanCFARDetector(LearnedDetector):
    """Conv encoder–decoder with per-cell binary focal loss ("See Further Than CFAR" baseline)."""

    architecture = "further_than_cfar"


class RTNDetector(LearnedDetector):
    """Radar-tensor detection network on a grid, adapted to LOS/mNLOS points (RTN baseline)."""

    architecture = "rtn"


LEARNED = {c.architecture: c for c in (SwinUNetDetector, UNetDetector, FurtherThanCFARDetector, RTNDetector)}
