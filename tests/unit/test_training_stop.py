"""A training run that stops before its epochs says why, in its summary and on the command line."""
from pathlib import Path

from plugins.training.run import Run


def test_early_stop_is_explained():
    run = Run(Path("out"), epochs=8, patience=2, minimise=False)
    assert run.stop_reason() is None  # not ended
    run.epoch, run.bad_epochs, run.best_epoch = 4, 2, 2
    assert run.stop_reason() == ("stopped early after epoch 4 of 8: 2 validation(s) without a better score "
                                 "(optim.patience = 2); the best model is epoch 2's")
    run.epoch = 8  # all epochs run: no early stop, whatever the patience count
    assert run.stop_reason() is None
