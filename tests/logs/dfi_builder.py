"""Builds DFI archives by hand for the tests (the format of docs/dfi-format.md)."""

from __future__ import annotations

import zipfile
from pathlib import Path

DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<recording>
  <toplevelgroup name="navdata" file="navdata.csv" separator="comma">
    <time unit="microseconds" source="board"/>
    <time unit="milliseconds" source="recorder"/>
    <doubleQuantity name="Altitude" unit="m"/>
    <group name="Rotation">
      <doubleQuantity name="roll" unit="deg"/>
      <doubleQuantity name="pitch" unit="deg"/>
      <doubleQuantity name="yaw" unit="deg"/>
    </group>
    <group name="Motor powers">
      <intQuantity name="motor 1"/>
      <intQuantity name="motor 2"/>
    </group>
    <intEnumeration name="state">
      <option value="2" label="Landed"/>
      <option value="3" label="Flying"/>
    </intEnumeration>
  </toplevelgroup>
  <toplevelgroup name="commands" file="cmd/commands.tsv" separator="tab">
    <time unit="milliseconds" source="recorder"/>
    <group name="Velocity">
      <doubleQuantity name="x" unit="m/s"/>
      <doubleQuantity name="y" unit="m/s"/>
      <doubleQuantity name="z" unit="m/s"/>
    </group>
  </toplevelgroup>
</recording>
"""

NAVDATA = """1000,5,0.5,1.5,-2.25,90.0,100,101,2
2000,6,0.75,1.0,-2.0,91.5,120,121,3
3000,7,1.25,0.5,-1.5,93.0,140,141,3
"""

COMMANDS = "5\t0.1\t0.0\t-0.2\n6\t0.2\t0.1\t0.0\n"


def write_dfi(
    path: Path, files: dict[str, str | bytes] | None = None, description: str = DESCRIPTION
) -> Path:
    members: dict[str, str | bytes] = {
        "description.xml": description,
        "navdata.csv": NAVDATA,
        "cmd/commands.tsv": COMMANDS,
    }
    members.update(files or {})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, content in members.items():
            if content is not None:
                zf.writestr(name, content)
    return path
