"""pluggy hook specifications of xnlos (project name ``xnlos``).

Plugins implement these with ``@xnlos_core.hookimpl`` in a module exposed through the
``xnlos.plugins`` entry-point group; built-in plugins do exactly the same.
"""
from __future__ import annotations

import pluggy

hookspec = pluggy.HookspecMarker("xnlos")
hookimpl = pluggy.HookimplMarker("xnlos")


@hookspec(historic=True)
def xnlos_register_components(registry) -> None:
    """Register components with ``registry.add(kind, name, factory)``.

    Called once for every plugin when it is registered (historic: plugins registered later are
    called too). ``kind`` is one of :data:`xnlos_core.interfaces.KINDS` (the six pipeline stages
    and ``scene_generator``); ``factory`` is a
    class with a pydantic ``Params`` model that subclasses the kind's interface. Returns nothing;
    all implementations are called.
    """
