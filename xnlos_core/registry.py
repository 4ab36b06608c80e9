"""Registry of components keyed by (kind, name), filled through the pluggy registration hook.

Loading follows pytest's conventions: every entry point of the ``xnlos.plugins`` group is
loaded unless ``XNLOS_DISABLE_PLUGIN_AUTOLOAD`` is set; ``XNLOS_PLUGINS`` (comma-separated
entry-point or distribution names) is an allow-list, and with autoload disabled it names the
plugins to load explicitly. A config file can only name installed entry points
(:meth:`PluginManager.load_named`); importing a module by name (:meth:`PluginManager.load_module`)
is reserved for the user's own command line, ``xnlos -p MODULE``.
"""
from __future__ import annotations

import difflib
import importlib
import inspect
import os
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any, Callable

import pluggy

from . import hookspecs
from .errors import ConfigError, PluginError
from .interfaces import BASES, KINDS

HOOK_NAMES = tuple(n for n in dir(hookspecs) if n.startswith("xnlos_") and callable(getattr(hookspecs, n)))

ENTRY_POINT_GROUP = "xnlos.plugins"
ENV_DISABLE = "XNLOS_DISABLE_PLUGIN_AUTOLOAD"
ENV_ALLOW = "XNLOS_PLUGINS"


@dataclass(frozen=True)
class Component:
    """One registered component: kind, name, factory, and the distribution that provided it."""

    kind: str
    name: str
    factory: Callable
    provider: str

    @property
    def params_model(self):
        return getattr(self.factory, "Params", None)

    @property
    def description(self) -> str:
        doc = inspect.getdoc(self.factory) or ""
        return doc.splitlines()[0] if doc else ""

    def parameters(self) -> dict[str, dict[str, Any]]:
        """{name: {type, default, description, constraints}} from the Params model."""
        model = self.params_model
        if model is None:
            return {}
        out = {}
        for pname, f in model.model_fields.items():
            info: dict[str, Any] = {
                "type": getattr(f.annotation, "__name__", str(f.annotation)),
                "default": None if f.is_required() else _jsonable(f.get_default(call_default_factory=True)),
                "required": f.is_required(),
            }
            if f.description:
                info["description"] = f.description
            for m in f.metadata:
                for attr in ("gt", "ge", "lt", "le", "min_length", "max_length"):
                    if getattr(m, attr, None) is not None:
                        info[attr] = getattr(m, attr)
            out[pname] = info
        return out


def _jsonable(v):
    if isinstance(v, (int, float, str, bool)) or v is None:
        return v
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    return repr(v)


class Registry:
    """Components keyed by (kind, name). Filled by plugins through ``xnlos_register_components``."""

    def __init__(self):
        self._components: dict[tuple[str, str], Component] = {}
        self._provider = "<unknown>"

    def add(self, kind: str, name: str, factory: Callable) -> None:
        """Register ``factory`` (a subclass of the kind's interface) as ``name`` of ``kind``."""
        if kind not in KINDS:
            raise PluginError(f"registry.add: unknown kind {kind!r}; known kinds: {', '.join(KINDS)}")
        if not isinstance(name, str) or not name.isidentifier():
            raise PluginError(f"registry.add: name must be an identifier (letters, digits, _), got {name!r}")
        if (kind, name) in self._components:
            prev = self._components[(kind, name)]
            raise PluginError(
                f"{kind} {name!r} is already registered by {prev.provider}; {self._provider} tried again. "
                f"Registered {kind}s: {', '.join(self.names(kind))}"
            )
        base = BASES[kind]
        if not (inspect.isclass(factory) and issubclass(factory, base)):
            raise PluginError(f"{kind} {name!r} from {self._provider}: factory must subclass "
                              f"{base.__module__}.{base.__name__}, got {factory!r}")
        self._components[(kind, name)] = Component(kind, name, factory, self._provider)

    def get(self, kind: str, name: str) -> Component:
        """The component, or a PluginError listing the registered names of that kind."""
        if kind not in KINDS:
            raise PluginError(f"unknown plugin kind {kind!r}; known kinds: {', '.join(KINDS)}")
        try:
            return self._components[(kind, name)]
        except KeyError:
            known = ", ".join(self.names(kind)) or "(none)"
            close = difflib.get_close_matches(str(name), self.names(kind), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise PluginError(f"unknown {kind} {name!r}{hint}; registered {kind}s: {known}") from None

    def create(self, kind: str, name: str, params: dict[str, Any] | None = None, *, source: str = "<config>",
               base_dir: str | Path | None = None, prefix: str | None = None):
        """Instantiate ``name`` with validated ``params`` (errors name ``source`` and the key ``prefix``,
        default ``<kind>.params``). ``base_dir``: the config file's folder; path parameters
        (:data:`xnlos_core.param_paths.ConfigPath`) are resolved against it. None: left as written."""
        from .config import validate_model
        from .param_paths import PathContext

        try:
            comp = self.get(kind, name)
        except PluginError as exc:
            if source == "<config>":
                raise
            key = (prefix or f"{kind}.params").removesuffix(".params") + ".name"
            raise PluginError(f"{source}: [{key}] {exc}") from None
        model = comp.params_model
        context = None if base_dir is None else PathContext(base_dir).validation_context()
        validated = validate_model(model, params or {}, source=source, prefix=prefix or f"{kind}.params",
                                   context=context) if model else None
        return comp.factory(validated) if model else comp.factory()

    def names(self, kind: str) -> list[str]:
        return sorted(n for k, n in self._components if k == kind)

    def components(self) -> list[Component]:
        return sorted(self._components.values(), key=lambda c: (KINDS.index(c.kind), c.name))

    def __contains__(self, key) -> bool:
        return key in self._components


class PluginManager:
    """pluggy manager plus the registry it fills. Use :func:`get_registry` for the shared one."""

    def __init__(self, autoload: bool | None = None, allow: list[str] | None = None):
        self.pm = pluggy.PluginManager("xnlos")
        self.pm.add_hookspecs(hookspecs)
        self.registry = Registry()
        # Historic call first: every plugin registered afterwards is called on registration.
        self.pm.hook.xnlos_register_components.call_historic(kwargs={"registry": self.registry})
        if autoload is None:
            autoload = not os.environ.get(ENV_DISABLE)
        if allow is None and os.environ.get(ENV_ALLOW):
            allow = [s.strip() for s in os.environ[ENV_ALLOW].split(",") if s.strip()]
        self.load_entry_points(autoload=autoload, allow=allow)
        self.pm.check_pending()

    def register(self, plugin, name: str | None = None, provider: str | None = None) -> None:
        """Register a plugin object/module; its hook runs at once (historic)."""
        self.registry._provider = provider or name or getattr(plugin, "__name__", repr(plugin))
        try:
            self.pm.register(plugin, name=name)
            self.pm.check_pending()
        finally:
            self.registry._provider = "<unknown>"

    def load_entry_points(self, autoload: bool = True, allow: list[str] | None = None) -> None:
        """Load ``xnlos.plugins`` entry points (all, or those named in ``allow``)."""
        if not autoload and not allow:
            return
        for ep in entry_points(group=ENTRY_POINT_GROUP):
            if allow is None or ep.name in allow or _dist(ep) in allow:
                self._load(ep)

    def load_named(self, names: list[str], source: str = "<config>", key: str = "plugins.load") -> None:
        """Load the installed ``xnlos.plugins`` entry points named by entry-point or distribution
        name, as a config's ``[plugins] load`` asks. A name that no installed entry point has is a
        ConfigError naming ``source``, ``key`` and the installed ones: a config never imports a
        module by its dotted name (that is :meth:`load_module`, for the command line)."""
        eps = list(entry_points(group=ENTRY_POINT_GROUP))
        for name in names:
            found = [ep for ep in eps if name in (ep.name, _dist(ep))]
            if not found:
                installed = ", ".join(sorted(f"{ep.name} ({_dist(ep)})" for ep in eps)) or "(none)"
                raise ConfigError(f"{source}: [{key}] {name!r} is not an installed xnlos plugin; a config can name "
                                  f"only entry points of the {ENTRY_POINT_GROUP!r} group, by entry-point or "
                                  f"distribution name. Installed: {installed}. To import a module of your own, "
                                  f"give it on the command line: xnlos -p MODULE")
            for ep in found:
                self._load(ep)

    def _load(self, ep) -> None:
        if self.pm.get_plugin(ep.name) is not None:
            return
        dist = _dist(ep)
        try:
            plugin = ep.load()
        except Exception as exc:
            raise PluginError(f"entry point {ep.name!r} ({ep.value}) of {dist} failed to import: {exc}") from exc
        version = ep.dist.version if ep.dist is not None else ""
        self.register(plugin, name=ep.name, provider=f"{dist} {version}".strip())

    def load_module(self, dotted: str) -> None:
        """Register a plugin module by import path, for the command line's ``xnlos -p MODULE``
        (like ``pytest -p``: the user's own act, never a config's). Loading it twice is a no-op."""
        if self.pm.get_plugin(dotted) is not None:
            return
        try:
            module = importlib.import_module(dotted)
        except ModuleNotFoundError as exc:
            missing = f" (missing: {exc.name})" if exc.name and exc.name != dotted else ""
            raise PluginError(f"-p {dotted}: no module named {dotted!r} can be imported{missing}; expected the "
                              "dotted import path of a module on sys.path (e.g. mypkg.xnlos_plugin)") from None
        except Exception as exc:  # the module's own code failed while importing: name it, no traceback
            raise PluginError(f"-p {dotted}: importing the module failed: {type(exc).__name__}: {exc}") from None
        hooks = [name for name in HOOK_NAMES if callable(getattr(module, name, None))]
        if not hooks:
            raise PluginError(f"-p {dotted}: the module defines none of the xnlos hooks ({', '.join(HOOK_NAMES)}); "
                              "expected e.g. a function xnlos_register_components(registry) decorated with "
                              "@xnlos_core.hookimpl")
        self.register(module, name=dotted, provider=dotted)


def _dist(ep) -> str:
    return ep.dist.name if ep.dist is not None else "<unknown>"


_MANAGER: PluginManager | None = None


def get_manager(reload: bool = False) -> PluginManager:
    """The process-wide plugin manager, created (and entry points loaded) on first use."""
    global _MANAGER
    if _MANAGER is None or reload:
        _MANAGER = PluginManager()
    return _MANAGER


def get_registry() -> Registry:
    """The process-wide registry of components."""
    return get_manager().registry
