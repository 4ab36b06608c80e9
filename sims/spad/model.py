"""The SPAD simulator as a registered ``transient_model`` ("spad"): :func:`.scene.simulate` with the
seed given per call, and the hidden surfaces in the scan's wall coordinates as ground truth, so
that the cross-modality study (:mod:`xnlos_core.app.crossmodal.study`) composes it through the registry."""
from __future__ import annotations

import numpy as np

from xnlos_core.interfaces import TransientModel
from xnlos_core.scene import Scene
from xnlos_core.transient import TransientVolume

from .scene import SpadParams, simulate, visible_patches


class SpadTransientModel(TransientModel):
    """Confocal SPAD scan of a Scene's relay wall (850 nm, 1.6 mW by default; :class:`SpadParams`,
    whose ``seed`` is replaced by the ``seed`` of each :meth:`simulate` call)."""

    Params = SpadParams

    def simulate(self, scene: Scene, seed: int) -> TransientVolume:
        """Photon counts (T, H, W) from ``numpy.random.default_rng(seed)``."""
        return simulate(scene, self.params.model_copy(update={"seed": int(seed)}))

    def truth(self, scene: Scene) -> np.ndarray:
        """Centres (P, 3) [m] of the hidden-surface patches the scan sees (:func:`.scene.visible_patches`:
        not occluded, facing the grid) in wall coordinates (x, y, z)."""
        return np.asarray(visible_patches(scene, self.params).centers, float).reshape(-1, 3)

    def facing_params(self, scene: Scene, target, exclude: str | None = None) -> tuple[dict, dict]:
        """Parameters with ``grid_offset`` at the wall position facing ``target`` most nearly head-on
        among those the sensor sees (:func:`.placement.facing_offset`), and the placement record."""
        from .placement import facing_offset

        params = self.params.model_dump()
        pl = facing_offset(scene, self.params, target, exclude=exclude)
        if pl.offset is not None:
            params["grid_offset"] = pl.offset
        return params, {"placement": "facing", "grid_offset": pl.offset, "facing_offset": pl.facing,
                        "clipped": pl.clipped}
