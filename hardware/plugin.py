"""Entry point ``xnlos-hardware``: registers the hardware backends.

* ``npz``: frames saved with :func:`xnlos_core.io.save_frame`;
* ``can``: a radar on any python-can interface (CAN FD, DBC + ISO-TP), with an in-process
  device emulator for hardware-in-the-loop runs on the ``virtual`` interface;
* ``replay``: a recorded CAN log (BLF, ASC, …) played back as frames;
* ``adc``: a raw ADC recording (DCA1000 ``.bin``, ``.npy``/``.npz``/HDF5 cubes) described by a TOML.
"""
from xnlos_core import hookimpl

from .commands import xnlos_add_commands  # noqa: F401  (hook implementation)


@hookimpl
def xnlos_register_components(registry):
    from .adc_backend import ADCBackend
    from .can_backend import CANBackend
    from .npz import NPZBackend
    from .replay import ReplayBackend

    registry.add("backend", "npz", NPZBackend)
    registry.add("backend", "can", CANBackend)
    registry.add("backend", "replay", ReplayBackend)
    registry.add("backend", "adc", ADCBackend)

