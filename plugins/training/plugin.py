"""Entry point ``xnlos-training``: the training core adds ``xnlos train`` and the ``check`` of
training configs (:mod:`.commands`); the learned components register their trainers themselves
(:mod:`.trainers`)."""
from .commands import xnlos_add_commands, xnlos_check_config  # noqa: F401  (hook implementations)
