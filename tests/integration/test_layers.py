"""The layers of the house: the import-linter contracts of pyproject.toml hold for the code, and
each contract breaks when an import crosses the line it draws (so a passing run means something)."""
import copy
import importlib.util
from pathlib import Path

import grimp
import pytest
from importlinter.api import read_configuration
from importlinter.contracts.acyclic_siblings import AcyclicSiblingsContract
from importlinter.contracts.forbidden import ForbiddenContract
from importlinter.contracts.independence import IndependenceContract
from importlinter.contracts.layers import LayersContract

ROOT = Path(__file__).resolve().parents[2]
CONFIG = read_configuration(str(ROOT / "pyproject.toml"))
TYPES = {c.type_name: c for c in (ForbiddenContract, IndependenceContract, LayersContract, AcyclicSiblingsContract)}
CONTRACTS = {c["id"]: c for c in CONFIG["contracts_options"]}


@pytest.fixture(scope="module")
def graph():
    """The import graph of the five root packages, as this checkout has them (no cache on disk), with
    the modules outside them they import (squashed to their top-level name, e.g. ``benchmarks``)."""
    roots = CONFIG["session_options"]["root_packages"]
    for pkg in roots:  # grimp reads the packages Python finds: they must be this checkout's
        assert Path(importlib.util.find_spec(pkg).origin).is_relative_to(ROOT), pkg
    return grimp.build_graph(*roots, cache_dir=None,
                             include_external_packages=CONFIG["session_options"]["include_external_packages"])


def check(contract_id: str, graph):
    """The ContractCheck of one contract of pyproject.toml on (a copy of) ``graph``."""
    options = CONTRACTS[contract_id]
    contract = TYPES[options["type"]](name=options["name"], session_options=CONFIG["session_options"],
                                      contract_options=options)
    return contract.check(copy.deepcopy(graph), verbose=False)


def test_the_contracts_are_the_houses():
    assert set(CONTRACTS) == {"core", "benchmarks", "app", "below-app", "stages", "plugins", "training", "acyclic"}
    assert CONTRACTS["core"]["forbidden_modules"] == ["sims", "plugins", "estimators", "hardware"]
    # the app is guarded as one package, and the stages contract has no exceptions
    assert CONTRACTS["app"]["forbidden_modules"] == CONTRACTS["below-app"]["forbidden_modules"] == ["xnlos_core.app"]
    assert CONTRACTS["below-app"]["source_modules"] == ["xnlos_core.*"]
    assert not CONTRACTS["stages"].get("ignore_imports")


@pytest.mark.parametrize("contract_id", ["core", "benchmarks", "app", "below-app", "stages", "plugins", "training",
                                         "acyclic"])
def test_the_code_keeps_the_contract(contract_id, graph):
    result = check(contract_id, graph)
    assert result.kept, (f"import-linter contract {CONTRACTS[contract_id]['name']!r} is broken: "
                         f"{result.metadata}; run `lint-imports` in {ROOT} for the import chains")


@pytest.mark.parametrize("contract_id, importer, imported", [
    ("core", "xnlos_core.scene", "sims.materials"),  # the arrow this refactor removed
    ("core", "xnlos_core.radar", "hardware.protocol"),
    ("benchmarks", "xnlos_core.app.crossmodal.study", "benchmarks"),  # the study writes its page markers itself
    ("benchmarks", "sims.image", "benchmarks"),
    ("app", "sims.image", "xnlos_core.app.runner"),
    ("app", "estimators.lsq", "xnlos_core.app.plot.palette"),  # any module of the app package
    ("below-app", "xnlos_core.pipeline", "xnlos_core.app.runner"),  # the core reaching up into the app
    ("below-app", "xnlos_core.signal.chain", "xnlos_core.app.plot.figures"),
    ("stages", "plugins.detectors.data", "sims.dataset"),  # training reads frames through the registry
    ("stages", "plugins.mirror.residual.train", "sims.dataset"),
    ("stages", "plugins.mirror.mirror", "estimators.lsq"),  # a stage reaching another stage
    ("stages", "hardware.emulator", "sims.image"),
    ("stages", "plugins.detectors.cfar", "plugins.mirror.association"),
    ("training", "plugins.training.run", "sims.dataset"),
    ("acyclic", "hardware.emulator", "hardware.can_backend"),  # the circle this refactor removed
    ("acyclic", "xnlos_core.interfaces", "xnlos_core.config"),
])
def test_a_crossing_import_breaks_the_contract(contract_id, importer, imported, graph):
    g = copy.deepcopy(graph)
    g.add_import(importer=importer, imported=imported, line_number=1, line_contents=f"import {imported}")
    result = check(contract_id, g)
    assert not result.kept
    assert importer in repr(result.metadata) and imported in repr(result.metadata)


def test_an_indirect_crossing_breaks_the_independence_contract(graph):
    # estimators → a core module → sims: the core would carry the arrow between two stages
    g = copy.deepcopy(graph)
    g.add_import(importer="xnlos_core.types", imported="sims.materials", line_number=1,
                 line_contents="import sims.materials")
    assert not check("stages", g).kept


def test_a_new_app_or_core_module_is_covered_without_editing_a_list(graph):
    g = copy.deepcopy(graph)
    g.add_module("xnlos_core.app.newcommand")
    g.add_import(importer="sims.image", imported="xnlos_core.app.newcommand", line_number=1,
                 line_contents="import xnlos_core.app.newcommand")
    assert not check("app", g).kept
    g = copy.deepcopy(graph)
    g.add_module("xnlos_core.newcore")
    g.add_import(importer="xnlos_core.newcore", imported="xnlos_core.app.cli", line_number=1,
                 line_contents="import xnlos_core.app.cli")
    assert not check("below-app", g).kept


def test_a_new_package_in_plugins_must_be_named_in_the_contract(graph):
    g = copy.deepcopy(graph)
    g.add_module("plugins.unnamed_stage")
    result = check("plugins", g)
    assert not result.kept and "plugins.unnamed_stage" in repr(result.metadata)


def test_the_training_core_may_not_import_a_stage(graph):
    # plugins.training sits below the learned stages: they import it, never the other way round
    g = copy.deepcopy(graph)
    assert check("plugins", g).kept
    g.add_import(importer="plugins.training", imported="plugins.detectors.cfar", line_number=1,
                 line_contents="import plugins.detectors.cfar")
    assert not check("plugins", g).kept
