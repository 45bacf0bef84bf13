"""No product function is longer than 60 lines: a longer one is split into named steps
that read as the decisions they make. Tests and migrations are exempt."""

from __future__ import annotations

import ast
import subprocess
from pathlib import Path

from tests.support.paths import ROOT

MAX_LINES = 60


def product_sources(root: Path) -> list[Path]:
    """Every git-tracked Python file outside tests/ and outside migrations."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--", "*.py"],
        cwd=root,
        capture_output=True,
        check=True,
        text=True,
    ).stdout.split("\0")
    return [
        root / name
        for name in listed
        if name
        and not name.startswith("tests/")
        and "migrations" not in Path(name).parts
        and (root / name).is_file()
    ]


def long_functions(path: Path, root: Path, limit: int = MAX_LINES) -> list[str]:
    """`path:line name length` for each function (nested ones too) over `limit` lines."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            length = node.end_lineno - node.lineno + 1
            if length > limit:
                found.append(f"{path.relative_to(root)}:{node.lineno} {node.name} {length}")
    return found


def test_the_check_finds_a_long_function(tmp_path: Path) -> None:
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_LINES))
    source = tmp_path / "long.py"
    source.write_text(f"def short():\n    return 1\n\n\nasync def long():\n{body}\n")
    assert long_functions(source, tmp_path) == [f"long.py:5 long {MAX_LINES + 1}"]


def test_no_product_function_is_over_60_lines() -> None:
    sources = product_sources(ROOT)
    assert sources, "git lists no Python files"
    too_long = [entry for path in sources for entry in long_functions(path, ROOT)]
    assert not too_long, f"functions over {MAX_LINES} lines:\n" + "\n".join(sorted(too_long))
