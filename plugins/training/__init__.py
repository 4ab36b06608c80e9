"""The training core, beside inference: what every learned component's training shares.

- :mod:`.checkpoint`: checkpoint files (state_dict + JSON metadata, ``weights_only`` loads, the
  sealed ``last.pt``)
- :mod:`.resume`: ``last.pt`` as the single commit point of an epoch, and resuming from it
- :mod:`.optim`: the ``[optim]`` table, AdamW and the cosine schedule
- :mod:`.run`: the run directory (claim, resume, extend), the epoch loop, the final model and export
- :mod:`.trained_on`: the radar and RA grid a model was trained on (checkpoint record, sidecar
  for older checkpoints) and what differs on the maps it is used on
- :mod:`.trainers`: the trainer chosen by a config's ``[model] name``
- :mod:`.commands`: ``xnlos train`` and ``xnlos check`` of a training config

A learned component (``plugins/detectors``, ``plugins/mirror/residual``) supplies its model, data,
loss and validation metric, and registers its trainer from its plugin module.
"""
