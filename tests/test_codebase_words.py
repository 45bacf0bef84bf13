"""The repository speaks of the product only, and product code never needs the tests.

Every file git tracks (or would track: new files not yet added count too) is read, except
third-party code (static/vendor/), test data (tests/data/), the benchmark results file and
this file. No comment, docstring, API text, template or test may point at the documents
the design was drawn from by their working names, at issue numbers or at a folder outside
the repository: the design's sources are cited by the keys of docs/references.md.
"""

from __future__ import annotations

import ast
import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
THIS_FILE = Path(__file__).resolve().relative_to(ROOT).as_posix()

TEXT_SUFFIXES = {
    ".py", ".html", ".js", ".css", ".sh", ".toml", ".json", ".md", ".txt",
    ".cpp", ".h", ".ino", ".xml", ".cfg", ".ini", ".yml", ".yaml", ".plan", ".lock",
}  # fmt: skip
TEXT_NAMES = {"Makefile", "Dockerfile", ".gitignore"}
EXCLUDED_PREFIXES = ("static/vendor/", "tests/data/")
EXCLUDED_FILES = {"bench/results.json", THIS_FILE}

# Case-insensitive: a source document's working name, an issue number, a path out of the
# repository. A random generator's `seed=` or `rng(seed)` matches none of them.
FORBIDDEN = [
    re.compile(pattern, re.IGNORECASE)
    for pattern in (
        r"\bseed\s*0\d\d\b",
        r"\bseed\s+(table|figure|text|document|listing|chapter|ch\.|\d)",
        r"\bseed'?s\b",
        r"\bthe seeds?\b",
        r"\bseed-compatible\b",
        r"\bissues?\s*#?\d+\b",
        r"\.\./shared",
        r"\bshared/(PROTOCOL|UAVTALK|ARCHITECTURE|DFI_FORMAT|SEEDS|STYLE)",
        r"\bengineer'?s? (harness|work)",
    )
]
# Case-sensitive: the upper-case names the documents had outside the repository; the
# repository's own are docs/protocol.md, docs/uavtalk.md, docs/dfi-format.md, ...
FORBIDDEN.append(re.compile(r"\b(PROTOCOL|UAVTALK|ARCHITECTURE|DFI_FORMAT|SEEDS|STYLE)\.md\b"))


def repository_files() -> list[str]:
    """Tracked files and new files not ignored, relative to the repository root."""
    listed = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.splitlines()
    return sorted({name for name in listed if (ROOT / name).is_file()})


def is_checked_text(name: str) -> bool:
    if name in EXCLUDED_FILES or name.startswith(EXCLUDED_PREFIXES):
        return False
    path = Path(name)
    return path.suffix in TEXT_SUFFIXES or path.name in TEXT_NAMES


def forbidden_references(text: str) -> list[tuple[int, str]]:
    """(line number, offending text) for every forbidden reference in text."""
    found = []
    for number, line in enumerate(text.splitlines(), start=1):
        matches = [m.group(0) for p in FORBIDDEN if (m := p.search(line))]
        if matches:
            found.append((number, " / ".join(matches)))
    return found


def imports_of_tests(source: str, filename: str) -> list[tuple[int, str]]:
    """(line number, module) for every import of the `tests` package in Python source,
    including imports inside functions and `importlib.import_module("tests...")`."""
    found = []
    for node in ast.walk(ast.parse(source, filename=filename)):
        modules: list[str] = []
        if isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            modules = [node.module]
        elif isinstance(node, ast.Call) and _is_import_call(node) and node.args:
            first = node.args[0]
            if isinstance(first, ast.Constant) and isinstance(first.value, str):
                modules = [first.value]
        found += [(node.lineno, m) for m in modules if m == "tests" or m.startswith("tests.")]
    return found


def _is_import_call(node: ast.Call) -> bool:
    func = node.func
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
    return name in ("import_module", "__import__")


def test_no_file_cites_source_documents_issues_or_folders_outside_the_repository():
    offences = []
    for name in filter(is_checked_text, repository_files()):
        text = (ROOT / name).read_text(encoding="utf-8", errors="replace")
        offences += [f"{name}:{line}: {found}" for line, found in forbidden_references(text)]
    assert not offences, "forbidden references:\n" + "\n".join(offences)


def test_no_product_module_imports_the_tests_package():
    offences = []
    for name in repository_files():
        if not name.endswith(".py") or name.startswith(("tests/", "static/vendor/")):
            continue
        source = (ROOT / name).read_text(encoding="utf-8")
        offences += [f"{name}:{line}: {module}" for line, module in imports_of_tests(source, name)]
    assert not offences, "product code importing tests:\n" + "\n".join(offences)


def test_the_word_patterns_catch_references_and_spare_random_seeds():
    caught = [
        "# hover at 10 m (seed 001, 5.1)",
        "Seed 5.3: 13 by the first drone",
        "the seed's order (z, then y, then x)",
        "as the seed describes",
        "Send one command of seed table 4.2",
        "The seed-compatible `/control` endpoint",
        "benchmarks (issue 7).",
        "every check of Issue #4",
        "see ../shared/PROTOCOL.md",
        "shared/UAVTALK.md, Connection",
        "the missions engineer's harness",
        "valid per DFI_FORMAT.md",
    ]
    spared = [
        "rng = np.random.default_rng(seed)",
        "random.seed(7)",
        "def sample(n: int, seed: int = 7):",
        "random_unit_quaternions(20, seed=1)",
        "the wire contract of docs/protocol.md",
        "read the shared queue skyhive.ingest",
        "issue new broker credentials",
        "hover at 10 m, as in the panic-button experiment of [Paula 2018], §5.1",
    ]
    assert [bool(forbidden_references(line)) for line in caught] == [True] * len(caught)
    assert [forbidden_references(line) for line in spared] == [[]] * len(spared)


def test_the_import_check_sees_every_form_of_importing_tests():
    source = (
        "import tests\n"
        "import tests.support.paths as paths\n"
        "from tests.support import ground\n"
        "def f():\n"
        "    from tests import factories\n"
        "    importlib.import_module('tests.planning.helpers')\n"
        "import testsuite\n"
        "from .tests import local\n"
        "from fleet import tests_helpers\n"
    )
    assert [line for line, _ in imports_of_tests(source, "example.py")] == [1, 2, 3, 5, 6]
