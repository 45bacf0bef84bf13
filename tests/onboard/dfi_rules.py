"""An independent check of a DFI archive against every rule of docs/dfi-format.md."""

from __future__ import annotations

import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

COLUMN_TAGS = {"intQuantity", "doubleQuantity", "intEnumeration", "time"}
TIME_UNITS = {"nanoseconds", "microseconds", "milliseconds", "seconds"}
SEPARATORS = {"comma": ",", "tab": "\t"}


def check_dfi(path: Path) -> dict[str, list[list[str]]]:
    """Raise AssertionError naming the broken rule; return {group name: rows}."""
    with zipfile.ZipFile(path) as zf:
        names = set(zf.namelist())
        assert "description.xml" in names, "no description.xml at the root"
        root = ET.fromstring(zf.read("description.xml"))
        assert root.tag == "recording"
        files_seen: set[str] = set()
        tables = {}
        for top in root:
            assert top.tag == "toplevelgroup"
            name, file, sep = top.get("name"), top.get("file"), top.get("separator")
            assert name and file and sep, f"toplevelgroup {name} lacks a mandatory attribute"
            assert sep in SEPARATORS
            assert file not in files_seen, f"{file} named twice"
            files_seen.add(file)
            assert file in names, f"{file} not in the archive"
            assert any(child.tag == "time" for child in top), f"{name} has no direct <time>"
            columns = [el for el in top.iter() if el.tag in COLUMN_TAGS]
            for el in top.iter("group"):
                assert el.get("name"), "group without a name"
            for col in columns:
                if col.tag == "time":
                    assert col.get("unit") in TIME_UNITS
                    assert col.get("source") in ("recorder", "board")
                else:
                    assert col.get("name"), f"{col.tag} without a name"
            rows = []
            for number, line in enumerate(zf.read(file).decode("utf-8").splitlines(), 1):
                values = line.split(SEPARATORS[sep])
                assert len(values) == len(columns), f"{file}:{number} has {len(values)} values"
                assert "" not in values, f"{file}:{number} has an empty value"
                for col, value in zip(columns, values, strict=True):
                    if col.tag == "doubleQuantity":
                        float(value)
                    else:
                        int(value)
                    if col.tag == "intEnumeration":
                        options = {int(o.get("value")) for o in col.iter("option")}
                        assert int(value) in options, f"{file}:{number} {value} not an option"
                rows.append(values)
            tables[name] = rows
        return tables


def labels(path: Path, group: str, column: str) -> dict[int, str]:
    with zipfile.ZipFile(path) as zf:
        root = ET.fromstring(zf.read("description.xml"))
    for top in root:
        if top.get("name") == group:
            for el in top.iter("intEnumeration"):
                if el.get("name") == column:
                    return {int(o.get("value")): o.get("label") for o in el.iter("option")}
    raise KeyError(column)
