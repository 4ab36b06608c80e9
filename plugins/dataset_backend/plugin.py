"""Registers nothing: the ``dataset`` backend moved to :mod:`sims.dataset.backend` (registered by
:mod:`sims.plugin`). Kept only while an installed environment still lists the entry point
``xnlos-dataset-backend``; delete this package once the project is reinstalled."""
