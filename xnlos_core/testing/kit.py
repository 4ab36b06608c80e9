"""Run the conformance checks on a component and report what held: :func:`check_component` (in the
spirit of scikit-learn's ``check_estimator``) and :func:`parametrize_with_checks` (each check one
pytest test, as scikit-learn's ``parametrize_with_checks``).

A component is given as a registered name, a class, or a plugin module:

- ``("detector", "cfar")`` or ``("detector", "cfar", {"pfa": 1e-4})``: a name in a registry;
- ``("detector", MyDetector)`` or ``MyDetector``: a class (the kind is the class's ``kind``);
- ``mypkg``: a module or object with the hook ``xnlos_register_components``; every component it
  registers (into a plugin manager of its own, no other plugin loaded) is checked.

Every component runs three checks in order: ``is a <Base>`` (it is created from its parameters, as a
pipeline creates it, and is an instance of its kind's interface), ``params`` (:func:`check_params`)
and ``<kind> contract`` (the kind's check in :data:`~xnlos_core.testing.CHECKS`).
"""
from __future__ import annotations

import inspect
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, Callable

from ..interfaces import BASES, KINDS, Plugin
from .checks import CHECKS, check_params, passed, record_steps


@dataclass(frozen=True, eq=False)
class ComponentSpec:
    """One component to check: its kind, and either its ``name`` in ``registry`` or its class
    ``factory``, with the ``params`` to create it from. :meth:`create` makes a fresh instance."""

    kind: str
    name: str
    params: dict[str, Any] = field(default_factory=dict)
    registry: Any = None
    factory: type | None = None

    @property
    def id(self) -> str:
        """``kind:name`` and the parameters, e.g. ``detector:cfar(pfa=0.0001)``: a readable test id."""
        args = ",".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"{self.kind}:{self.name}" + (f"({args})" if args else "")

    def __str__(self) -> str:
        return self.id

    def create(self) -> Plugin:
        """A new instance, its parameters validated as a pipeline validates them; AssertionError when
        the class is not a subclass of the kind's interface."""
        base = BASES[self.kind]
        if self.factory is not None:
            if not (inspect.isclass(self.factory) and issubclass(self.factory, base)):
                raise AssertionError(f"{self.name}: is not a {base.__module__.split('.')[0]}.{base.__name__} "
                                     f"subclass (kind {self.kind!r})")
            return self.factory(dict(self.params))
        return self.registry.create(self.kind, self.name, dict(self.params), source=f"check_component({self.id})")


@dataclass(frozen=True)
class CheckResult:
    """A check that passed on one component: the component's id, the check's name and the parts of
    it that held, in order."""

    component: str
    check: str
    steps: tuple[str, ...] = ()

    def __str__(self) -> str:
        return f"PASSED {self.check}" + (f": {'; '.join(self.steps)}" if self.steps else "")


@dataclass(frozen=True)
class Check:
    """One named conformance check of a kind; ``check(component)`` runs it on a
    :class:`ComponentSpec` (creating a fresh instance) or on an instance, and returns its
    :class:`CheckResult`, or raises AssertionError naming the broken contract."""

    name: str
    func: Callable[[Plugin], None]

    @property
    def id(self) -> str:
        return self.name.replace(" ", "_")

    def __repr__(self) -> str:
        return f"Check({self.name!r})"

    def __call__(self, component: ComponentSpec | Plugin) -> CheckResult:
        spec = component if isinstance(component, ComponentSpec) else None
        plugin = spec.create() if spec is not None else component
        with record_steps() as steps:
            self.func(plugin)
        return CheckResult(spec.id if spec is not None else type(plugin).__name__, self.name, tuple(steps))


def checks_for(kind: str) -> list[Check]:
    """The checks of ``kind``, in the order they run: ``is a <Base>``, ``params``, ``<kind> contract``."""
    if kind not in KINDS:
        raise ValueError(f"unknown plugin kind {kind!r}; known kinds: {', '.join(KINDS)}")
    base = BASES[kind]

    def is_a(plugin) -> None:
        if not isinstance(plugin, base):
            raise AssertionError(f"{type(plugin).__name__}: is not a {base.__name__}")
        passed(f"created from its parameters, an instance of {base.__name__}")

    return [Check(f"is a {base.__name__}", is_a), Check("params", check_params),
            Check(f"{kind.replace('_', ' ')} contract", CHECKS[kind])]


@dataclass
class CheckReport:
    """What :func:`check_component` checked: one :class:`CheckResult` per check that passed, per
    component. ``str(report)`` lists them, one line each under a line per component."""

    results: list[CheckResult] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.results)

    def __iter__(self):
        return iter(self.results)

    @property
    def passed(self) -> list[str]:
        """``component::check`` of every check that passed."""
        return [f"{r.component}::{r.check}" for r in self.results]

    def __str__(self) -> str:
        lines: list[str] = []
        for comp in dict.fromkeys(r.component for r in self.results):
            mine = [r for r in self.results if r.component == comp]
            lines.append(f"{comp}: {len(mine)} check{'s' if len(mine) != 1 else ''} passed")
            lines += [f"  {r}" for r in mine]
        return "\n".join(lines) or "no checks run"


def resolve(component: Any, name: Any = None, params: dict | None = None, registry=None) -> list[ComponentSpec]:
    """The components that ``check_component(component, name, params, registry)`` checks (see the
    module's description of the forms); TypeError for anything else."""
    if isinstance(name, dict) and params is None and not isinstance(component, str):
        name, params = None, name  # check_component(MyDetector, {"threshold_db": 20.0})
    params = dict(params or {})
    if isinstance(component, str):
        if component not in KINDS:
            raise ValueError(f"unknown plugin kind {component!r}; known kinds: {', '.join(KINDS)}")
        if inspect.isclass(name):
            return [ComponentSpec(component, name.__name__, params, factory=name)]
        if not isinstance(name, str):
            raise TypeError(f"check_component({component!r}, ...): expected a registered name or a class after "
                            f"the kind, got {name!r}")
        from ..registry import get_registry

        registry = registry or get_registry()
        registry.get(component, name)  # an unknown name: PluginError listing the names (did you mean …?)
        return [ComponentSpec(component, name, params, registry)]
    if inspect.isclass(component):
        kind = getattr(component, "kind", None)
        if kind not in KINDS:
            raise TypeError(f"{component.__name__} is no xnlos plugin class (its kind {kind!r} is none of "
                            f"{', '.join(KINDS)}); subclass one of the interfaces in xnlos_core.interfaces")
        return [ComponentSpec(kind, component.__name__, params, factory=component)]
    if callable(getattr(component, "xnlos_register_components", None)):
        return _module_specs(component, name, params)
    raise TypeError(f"expected a plugin kind and a name or class, a plugin class, or a plugin module (with "
                    f"xnlos_register_components), got {component!r}")


def _module_specs(module, name, params: dict) -> list[ComponentSpec]:
    from ..registry import PluginManager

    label = getattr(module, "__name__", None) or type(module).__name__
    manager = PluginManager(autoload=False, allow=[])  # this module's components alone
    manager.register(module, name=label)
    comps = [c for c in manager.registry.components() if name is None or c.name == name]
    if not comps:
        what = f"no component named {name!r}" if name is not None else "no component"
        raise AssertionError(f"{label}: xnlos_register_components registered {what} (registry.add(kind, name, "
                             "class) adds one)")
    if params and len(comps) > 1:
        raise TypeError(f"{label} registers {len(comps)} components; give the name of the one the parameters are "
                        f"for: check_component({label}, NAME, params)")
    return [ComponentSpec(c.kind, c.name, params, manager.registry) for c in comps]


def check_component(component: Any, name: Any = None, params: dict | None = None, registry=None, *,
                    verbose: bool = False) -> CheckReport:
    """Run every check of a component's kind on it and return the :class:`CheckReport` of what
    passed; the first check that fails raises AssertionError naming the broken contract.

    ``check_component("detector", "my_detector", {"threshold_db": 20.0})`` checks a registered
    name (in ``registry``, default the process-wide one); ``check_component("detector", MyDetector)``
    or ``check_component(MyDetector, {...})`` a class; ``check_component(mypkg)`` every component that
    a plugin module registers (``name`` picks one). ``verbose``: print each check as it passes.
    """
    report = CheckReport()
    for spec in resolve(component, name, params, registry):
        plugin = spec.create()
        if verbose:
            print(f"{spec.id} ({type(plugin).__module__}.{type(plugin).__qualname__})")
        for check in checks_for(spec.kind):
            with record_steps() as steps:
                check.func(plugin)
            report.results.append(CheckResult(spec.id, check.name, tuple(steps)))
            if verbose:
                print(f"  {report.results[-1]}")
    return report


def parametrize_with_checks(components: Iterable[Any], registry=None):
    """A ``pytest.mark.parametrize`` over (component, check) pairs, each check a separate test with an
    id such as ``detector:my_detector-params``. Each entry of ``components`` is a tuple
    ``(kind, name_or_class[, params])``, a class, or a plugin module (see the module's description)::

        @parametrize_with_checks([("detector", MyDetector), ("detector", "cfar", {"pfa": 1e-4})])
        def test_conformance(component, check):
            check(component)
    """
    import pytest  # the kit is a library: pytest only where its marks are asked for

    specs: list[ComponentSpec] = []
    for entry in components:
        args = entry if isinstance(entry, tuple) else (entry,)
        specs += resolve(*args, registry=registry)
    pairs = [(spec, check) for spec in specs for check in checks_for(spec.kind)]
    return pytest.mark.parametrize("component, check", pairs, ids=[f"{s.id}-{c.id}" for s, c in pairs])
