"""README.md's Layout table names exactly the repository's top-level folders.

A folder added or removed without updating the table leaves newcomers with a wrong map
of the repository, so the table is checked against what git tracks.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROW = re.compile(r"^\|\s*`?([^|`]+?)`?\s*\|")


def layout_table_folders(readme: str) -> list[str]:
    """Folder names in the first column of the table under the `## Layout` heading."""
    section = readme.split("\n## Layout", 1)[1].split("\n## ", 1)[0]
    rows = [line.strip() for line in section.splitlines() if line.strip().startswith("|")]
    header, separator, *body = rows
    assert ROW.match(header).group(1) == "folder", f"unexpected table header: {header}"
    assert set(separator.replace("|", "").strip()) <= set("-: "), separator
    return [ROW.match(row).group(1).strip().rstrip("/") for row in body]


def tracked_top_level_folders() -> set[str]:
    """First path component of every tracked file inside a folder, dot-folders left out."""
    listing = subprocess.run(
        ["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True
    ).stdout.decode("utf-8")
    return {
        path.split("/", 1)[0]
        for path in listing.split("\0")
        if "/" in path and not path.startswith(".")
    }


def test_layout_table_lists_every_top_level_folder_and_nothing_else() -> None:
    listed = layout_table_folders((ROOT / "README.md").read_text(encoding="utf-8"))
    assert len(listed) == len(set(listed)), f"a folder is listed twice: {sorted(listed)}"
    folders = tracked_top_level_folders()
    assert set(listed) == folders, (
        f"README.md's Layout table lacks {sorted(folders - set(listed))} "
        f"and lists folders that do not exist {sorted(set(listed) - folders)}"
    )
