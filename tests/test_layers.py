"""The apps import each other in one direction only.

onboard (installed alone on drones, no Django) <- workers (broker, counters, outbox,
gateway, operations figures) <- fleet <- missions; telemetry, logs and pastview import
fleet, workers and onboard; accounts imports fleet and workers, and nothing imports
accounts but config (fleet reaches it through signals and settings); alerts listens to
fleet and missions and reads accounts' recipients, and nothing imports alerts but config,
records (which lists the alerts raised during a flight) and maintenance; records listens to
fleet and reads missions, and nothing imports records but config and maintenance (whose
schedules count the flights records keep, and which warns of tasks coming due; fleet asks
it through settings); zones builds on fleet, which names the zones' checks in settings;
airspace builds on fleet (which names its checks in settings) and missions builds on
airspace; terrain imports only onboard, and fleet builds on it (the
envelope's terrain clearance); runtime (processes, retry, MQTT packets for the ground's
tools) imports only the standard library; checklists builds on fleet and telemetry,
missions and records read it, and fleet names its gate in settings. Every import statement
counts, including ones inside functions; a handler named by a dotted path string
(workers/dispatch.py) is not an import. Migrations and tests are left out. No Django
needed: the sources are parsed, not imported. batteries builds on fleet (which reaches a
pack's verdict through its relations) and records on batteries (a flight counts against
its pack).

SKYHIVE_LAYERS_ROOT=<checkout> checks another checkout than this one.
"""

from __future__ import annotations

import ast
import functools
import os
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(os.environ.get("SKYHIVE_LAYERS_ROOT") or Path(__file__).resolve().parents[1])

DJANGO_APPS = (
    "batteries",
    "fleet",
    "missions",
    "telemetry",
    "logs",
    "pastview",
    "workers",
    "accounts",
    "alerts",
    "records",
    "checklists",
    "tiles",
    "zones",
    "airspace",
    "terrain",
    "maintenance",
)
PLAIN_PACKAGES = ("onboard", "firmware", "runtime")
PACKAGES = DJANGO_APPS + PLAIN_PACKAGES
DOMAIN_APPS = (
    "batteries",
    "fleet",
    "missions",
    "telemetry",
    "logs",
    "pastview",
    "accounts",
    "alerts",
    "records",
    "checklists",
    "zones",
    "airspace",
    "terrain",
    "maintenance",
)
# Our own top-level packages that onboard must not import: it runs on drones without them.
NOT_FOR_ONBOARD = (*DOMAIN_APPS, "workers", "config", "firmware", "runtime", "tests")

# Imports that break the layering and are tolerated until they are moved, each with its
# reason, as {(importer, imported): reason}. None today: firmware imports onboard, never
# the other way round.
ALLOWED: dict[tuple[str, str], str] = {}

Site = tuple[str, int]  # file (relative to ROOT) and line of one import statement


def python_files(package: str) -> Iterator[Path]:
    for path in sorted((ROOT / package).rglob("*.py")):
        parts = path.relative_to(ROOT).parts
        if "migrations" in parts or "tests" in parts:
            continue
        yield path


def imported_modules(path: Path, root: Path = ROOT) -> Iterator[tuple[str, int]]:
    """(absolute module name, line) of every import statement in the file."""
    # The package a relative import starts from: a/b/c.py and a/b/__init__.py are in a.b.
    package = list(path.relative_to(root).with_suffix("").parts)[:-1]
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                yield node.module or "", node.lineno
                continue
            base = package[: len(package) - (node.level - 1)]
            yield ".".join([*base, *(node.module or "").split(".")]).strip("."), node.lineno


@functools.cache
def import_graph() -> dict[str, dict[str, list[Site]]]:
    """package -> the other packages of PACKAGES it imports -> where (parsed once a run;
    the tests only read it)."""
    graph: dict[str, dict[str, list[Site]]] = {package: {} for package in PACKAGES}
    for package in PACKAGES:
        for path in python_files(package):
            for module, line in imported_modules(path):
                top = module.split(".", 1)[0]
                if top in PACKAGES and top != package:
                    site = (str(path.relative_to(ROOT)), line)
                    graph[package].setdefault(top, []).append(site)
    return graph


def find_cycle(edges: dict[str, set[str]]) -> list[str] | None:
    """One cycle as [a, b, ..., a], or None when the graph is acyclic."""
    done: set[str] = set()
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        if node in path:
            return [*path[path.index(node) :], node]
        if node in done:
            return None
        path.append(node)
        for target in sorted(edges.get(node, ())):
            cycle = visit(target)
            if cycle:
                return cycle
        path.pop()
        done.add(node)
        return None

    for start in sorted(edges):
        cycle = visit(start)
        if cycle:
            return cycle
    return None


def _shown(graph: dict[str, dict[str, list[Site]]], a: str, b: str) -> str:
    sites = ", ".join(f"{file}:{line}" for file, line in graph[a][b][:3])
    more = len(graph[a][b]) - 3
    return f"  {a} -> {b}: {sites}" + (f" (+{more} more)" if more > 0 else "")


def test_the_apps_import_each_other_without_a_cycle() -> None:
    graph = import_graph()
    edges = {
        package: {target for target in targets if (package, target) not in ALLOWED}
        for package, targets in graph.items()
    }
    cycle = find_cycle(edges)
    if cycle:
        steps = "\n".join(_shown(graph, a, b) for a, b in zip(cycle, cycle[1:], strict=False))
        raise AssertionError(f"import cycle {' -> '.join(cycle)}:\n{steps}")


def test_workers_imports_no_domain_app() -> None:
    graph = import_graph()
    upward = [target for target in DOMAIN_APPS if target in graph["workers"]]
    assert not upward, "workers imports a domain app:\n" + "\n".join(
        _shown(graph, "workers", target) for target in upward
    )


def test_onboard_imports_only_itself_the_standard_library_and_third_party() -> None:
    found = []
    for path in python_files("onboard"):
        for module, line in imported_modules(path):
            top = module.split(".", 1)[0]
            if top in NOT_FOR_ONBOARD and ("onboard", top) not in ALLOWED:
                found.append(f"  {path.relative_to(ROOT)}:{line} imports {module}")
    assert not found, "onboard imports ground or repository code:\n" + "\n".join(found)


def test_every_allowed_exception_is_still_needed() -> None:
    """Once an allowed import is gone, its exception goes too, so it cannot come back."""
    graph = import_graph()
    stale = [f"{a} -> {b}" for a, b in ALLOWED if b not in graph[a]]
    assert not stale, f"no longer imported, remove from ALLOWED: {', '.join(stale)}"


def test_no_app_imports_accounts() -> None:
    """Accounts sits on top of the domain apps: they send signals it listens to."""
    graph = import_graph()
    # alerts sits above accounts and reads the recipients its admins set.
    importers = [app for app in PACKAGES if "accounts" in graph[app] and app != "alerts"]
    assert not importers, "imports accounts:\n" + "\n".join(
        _shown(graph, app, "accounts") for app in importers
    )


def test_nothing_but_config_imports_alerts() -> None:
    graph = import_graph()
    # records sits above alerts: a flight's record lists the alerts raised during it;
    # maintenance sits above records and warns of tasks coming due.
    found = [p for p in PACKAGES if "alerts" in graph[p] and p not in ("records", "maintenance")]
    assert not found, "alerts is imported by:\n" + "\n".join(
        _shown(graph, package, "alerts") for package in found
    )


def test_nothing_but_config_imports_records() -> None:
    """Flight records sit on top: they hear the fleet's signals and read the other apps."""
    graph = import_graph()
    # maintenance sits above records: its schedules fall due by the flights recorded.
    found = [p for p in PACKAGES if "records" in graph[p] and p != "maintenance"]
    assert not found, "records is imported by:\n" + "\n".join(
        _shown(graph, package, "records") for package in found
    )


def test_terrain_imports_only_onboard() -> None:
    """The flight envelope (fleet) checks the terrain clearance: terrain may not reach back."""
    graph = import_graph()
    assert set(graph["terrain"]) <= {"onboard"}, "terrain imports:\n" + "\n".join(
        _shown(graph, "terrain", target) for target in graph["terrain"] if target != "onboard"
    )


def test_runtime_imports_none_of_our_packages() -> None:
    """The ground's process and connection tooling stands alone: no app, no drone code."""
    graph = import_graph()
    assert graph["runtime"] == {}, "\n".join(_shown(graph, "runtime", t) for t in graph["runtime"])


# Who may import paho: the broker package (workers/broker, the ground's one place that
# knows the broker) and the drone's agent (onboard, installed without the ground). Tests
# and benchmarks stand in for drones and measure bare MQTT, so they are not ground code.
PAHO_ALLOWED = ("workers/broker", "onboard", "tests", "bench", ".venv")


def paho_importers(root: Path = ROOT) -> list[str]:
    """`file:line` of every import of paho outside PAHO_ALLOWED."""
    found = []
    for path in _python_files_outside(root, PAHO_ALLOWED):
        relative = path.relative_to(root)
        for module, line in imported_modules(path, root):
            if module.split(".", 1)[0] == "paho":
                found.append(f"  {relative}:{line} imports {module}")
    return found


def _python_files_outside(root: Path, skipped: tuple[str, ...]) -> list[Path]:
    """Every .py file under root but in the folders `skipped` names and hidden folders,
    which are never entered (the virtualenv alone holds tens of thousands of files)."""
    found = []
    for folder, subfolders, files in os.walk(root):
        relative = Path(folder).relative_to(root).as_posix()
        subfolders[:] = [
            name
            for name in subfolders
            if not name.startswith(".")
            and (name if relative == "." else f"{relative}/{name}") not in skipped
        ]
        found += [Path(folder) / n for n in files if n.endswith(".py") and not n.startswith(".")]
    return sorted(found)


def test_only_the_broker_package_and_the_agent_import_paho() -> None:
    """The gateway, a web process's direct link and the past view get their MQTT client
    from workers.broker.client; a ground module with a paho client of its own would set
    its own credentials, TLS and failover."""
    found = paho_importers()
    assert not found, "paho imported outside workers/broker and onboard:\n" + "\n".join(found)


def test_the_paho_rule_sees_an_import_in_a_ground_module(tmp_path: Path) -> None:
    (tmp_path / "pastview").mkdir()
    (tmp_path / "pastview" / "runner.py").write_text("def f():\n    import paho.mqtt.client\n")
    (tmp_path / "workers" / "broker").mkdir(parents=True)
    (tmp_path / "workers" / "broker" / "client.py").write_text("import paho.mqtt.client\n")
    (tmp_path / "workers" / "gateway.py").write_text("from paho.mqtt import client\n")
    assert paho_importers(tmp_path) == [
        "  pastview/runner.py:2 imports paho.mqtt.client",
        "  workers/gateway.py:1 imports paho.mqtt",
    ]
