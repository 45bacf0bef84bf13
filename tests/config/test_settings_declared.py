"""Every setting the code reads is declared: in one of config/settings' modules, or among
Django's own defaults. A setting read but declared nowhere would silently take whatever
fallback the reader wrote, and no environment variable would reach it."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

from django.conf import global_settings

ROOT = Path(__file__).resolve().parents[2]
SETTINGS = ROOT / "config" / "settings"
# Our code: every top-level package with Python in it, but not tests, the virtualenv or data.
SKIPPED = {"tests", ".venv", ".data", "node_modules", "static", "templates", "docs"}


def declared() -> set[str]:
    names = {name for name in dir(global_settings) if name.isupper()}
    for path in SETTINGS.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            targets = []
            if isinstance(node, ast.Assign):
                targets = node.targets
            elif isinstance(node, ast.AnnAssign | ast.AugAssign):
                targets = [node.target]
            names |= {t.id for t in targets if isinstance(t, ast.Name) and t.id.isupper()}
    return names


def _sources() -> Iterator[Path]:
    for path in sorted(ROOT.rglob("*.py")):
        parts = path.relative_to(ROOT).parts
        if parts[0] in SKIPPED or "migrations" in parts or path.is_relative_to(SETTINGS):
            continue
        yield path


def _name_read(node: ast.AST) -> str | None:
    """NAME of `settings.NAME` or `getattr(settings, "NAME", ...)`."""
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
        if node.value.id == "settings" and node.attr.isupper():
            return node.attr
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "getattr":
        args = node.args
        if len(args) >= 2 and isinstance(args[0], ast.Name) and args[0].id == "settings":
            if isinstance(args[1], ast.Constant) and isinstance(args[1].value, str):
                return args[1].value
    return None


def reads() -> dict[str, list[str]]:
    """Setting name -> where the code reads it (file:line)."""
    found: dict[str, list[str]] = {}
    for path in _sources():
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            name = _name_read(node)
            if name is not None:
                found.setdefault(name, []).append(f"{path.relative_to(ROOT)}:{node.lineno}")
    return found


def test_every_setting_read_is_declared() -> None:
    known = declared()
    missing = {name: sites for name, sites in reads().items() if name not in known}
    assert missing == {}, "read but declared nowhere:\n" + "\n".join(
        f"  {name}: {', '.join(sites[:3])}" for name, sites in sorted(missing.items())
    )


def test_the_check_sees_reads_and_declarations() -> None:
    # The walk finds what it must, so an empty result above means something.
    found = reads()
    assert "COMMAND_TIMEOUT_S" in found and "REDIS_URL" in found
    assert {"COMMAND_TIMEOUT_S", "INSTALLED_APPS", "SECRET_KEY"} <= declared()
