"""Empty: see :mod:`plugins.dataset_backend.plugin` (delete after reinstalling the project)."""
