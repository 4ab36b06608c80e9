"""Residual mirror reconstruction (Eq. 7 with the learned residual), with covariance.

For each mNLOS detection o' anchored to a wall (:mod:`plugins.mirror.association`, as ``mirror``):

    o = R_Π(o') + Δo_θ                                             (Eq. 7)
    Σ_o = Σ_mirror + Σ_Δ

R_Π(o') and Σ_mirror are exactly the ``mirror`` reconstructor's (first-order propagation of the
detection and wall covariances; wall posterior samples and arcs through
:func:`xnlos_core.wall_propagation.propagate`), so a point-estimate wall (zero covariance) works and a
wider wall posterior gives a wider Σ_o. Δo_θ comes from :class:`.net.ResidualAttention` over the K
supporting LOS detections of the anchored wall nearest to the reflection point (the wall's mean
pose defines the local frame, :mod:`.features`). Σ_Δ is the residual's own uncertainty: the
network predicts a Laplace scale s per local axis (trained with a Laplace NLL next to the Eq. 9
ℓ1 loss, :mod:`.train`), and Σ_Δ = R diag(2s_u², 2s_n²) Rᵀ (Laplace variance, R = [u_q n_q]).
Σ_Δ is learned from residual errors that already include wall-fit noise, so the sum is
conservative (it counts the wall uncertainty partly twice); ``residual_cov = false`` leaves it out.

The shipped checkpoint ``models/residual_mirror.pt`` is loaded by default (``model`` overrides).
``mirror`` is the ablation without Δo_θ.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
from pydantic import Field

from xnlos_core.errors import InputError
from xnlos_core.types import LOS, Detections, HiddenPoints, WallPosterior
from xnlos_core.param_paths import ConfigPath

from plugins.mirror.association import wall_support
from plugins.mirror.mirror import MirrorParams, MirrorReconstructor

from .features import build_inputs

DEFAULT_MODEL = Path(__file__).parent / "models" / "residual_mirror.pt"


class ResidualMirrorParams(MirrorParams):
    model: ConfigPath | None = Field(None, description="checkpoint of the residual network, relative to the "
                                                       "config file's folder (default: the shipped "
                                                       "plugins/mirror/residual/models/residual_mirror.pt)")
    neighbours: int | None = Field(None, ge=1, le=1024, description="supporting LOS points the attention sees "
                                                                   "(default: the checkpoint's)")
    support_distance: float | None = Field(None, gt=0, le=100, description="LOS points within this distance "
                                           "[m] of a wall support it (default: the checkpoint's)")
    residual_cov: bool = Field(True, description="add the residual's predicted covariance Σ_Δ to Σ_o")
    wedge_margin: float | None = Field(None, ge=0, le=1e3, description="with gate: how far [m] beyond each wall's "
                                       "observed extent its bounce point may lie; None (here the default): "
                                       "extent_margin, since the residual corrects walls whose fitted line and "
                                       "extent are off (a bent facade fitted as one line), as its training data had")
    one_relay: bool = Field(False, description="with gate: refuse a hidden point whose ray crosses two walls within "
                            "the wedge margin; off here, where that margin is extent_margin and two crossings "
                            "within it are common (a corner's two facades)")


@lru_cache(maxsize=8)
def _load(path: str, mtime_ns: int):
    from .net import ARCHITECTURE, HParams, ResidualAttention
    from plugins.training.checkpoint import load_checkpoint

    sd, meta, _ = load_checkpoint(path)
    if meta.get("architecture") != ARCHITECTURE:
        raise InputError(f"checkpoint {path!r}: holds a {meta.get('architecture')!r} model, but reconstructor "
                         f"residual_mirror needs a {ARCHITECTURE!r} checkpoint (train one with xnlos train "
                         "configs/training/residual_mirror.toml)")
    try:
        hp = HParams.model_validate(meta.get("hparams", {}))
        net = ResidualAttention(hp)
        net.load_state_dict(sd, strict=True)
    except (ValueError, RuntimeError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"checkpoint {path!r}: weights do not fit a {ARCHITECTURE!r} network "
                         f"(wrong architecture or hyper-parameters: {first})") from None
    net.eval()
    return net, meta


def load_model(path: str | Path | None = None):
    """(network in eval mode, metadata) of a residual_mirror checkpoint (default: the shipped one).
    Raises InputError naming the file when it is missing, corrupt or of another architecture."""
    p = Path(path) if path is not None else DEFAULT_MODEL
    if not p.is_file():
        raise InputError(f"checkpoint {str(p)!r}: no such file (residual_mirror.model); train one with "
                         "xnlos train configs/training/residual_mirror.toml")
    return _load(str(p.resolve()), p.stat().st_mtime_ns)


class ResidualMirrorReconstructor(MirrorReconstructor):
    """Eq. 7 with a learned residual: analytic mirror + attention over the wall's LOS points, with
    the propagated mirror covariance plus the residual's predicted covariance."""

    Params = ResidualMirrorParams

    def _model(self):
        return load_model(self.params.model)

    def state_sha256(self) -> str | None:
        """The residual checkpoint's ``weights_sha256``."""
        return self._model()[1]["weights_sha256"]

    def settings(self, meta: dict) -> tuple[int, float]:
        """(neighbours K, support distance [m]): the parameters', else the checkpoint's."""
        k = self.params.neighbours or int(meta.get("neighbours", 16))
        dist = self.params.support_distance or float(meta.get("support_distance", 3.0))
        return k, dist

    def prepare(self, detections: Detections, walls: list[WallPosterior], neighbours: int, support_distance: float
                ) -> tuple[HiddenPoints, dict[str, np.ndarray]]:
        """(analytic-mirror HiddenPoints, network inputs of its rows (:func:`.features.build_inputs`))."""
        geom, pts = self.mirror_detections(detections, walls)
        los = detections.position[detections.of_class(LOS)]
        support = wall_support(los, list(walls), support_distance, self.params.extent_margin)
        return geom, build_inputs(pts, list(walls), geom.wall_index, los, support, neighbours)

    def reconstruct(self, detections: Detections, walls: list[WallPosterior]) -> HiddenPoints:
        """Hidden points for the mNLOS rows of ``detections`` (source_index into ``detections``,
        wall_index into ``walls``), in detection order; mean (M, 2) [m], cov (M, 2, 2) [m²]. Raises
        InsufficientDataError when there are mNLOS detections but no walls, InputError for bad
        inputs or an unusable checkpoint. ``last_unanchored_`` and ``last_residual_`` (M, 2) [m]
        are set."""
        import torch

        from .net import local_to_global, residual_cov

        net, meta = self._model()
        geom, x = self.prepare(detections, walls, *self.settings(meta))
        self.last_residual_ = np.zeros((len(geom), 2))
        if len(geom) == 0:
            return geom
        normal = torch.from_numpy(x["normal"].astype(np.float32))
        with torch.inference_mode():
            d_local, log_s = net(torch.from_numpy(x["query"]), torch.from_numpy(x["neigh"]),
                                 torch.from_numpy(x["mask"]))
            delta = local_to_global(d_local, normal).double().numpy()
            extra = residual_cov(log_s, normal).double().numpy()
        cov = geom.cov + extra if self.params.residual_cov else geom.cov
        mean = geom.mean + delta
        # the residual moves a point: the gate applies to where it ends up, too
        keep = self.visible(mean, detections.position[geom.source_index], list(walls), geom.wall_index,
                            geom.source_index, detections)
        self.last_residual_ = delta[keep]
        cov = 0.5 * (cov + np.swapaxes(cov, -1, -2))
        view = None if geom.view is None else geom.view[keep]
        return HiddenPoints(mean[keep], cov[keep], geom.source_index[keep], geom.wall_index[keep], view=view,
                            gated=np.concatenate([geom.gated, geom.source_index[~keep]]))
