"""The dRonin firmware generations the agent knows, and where their definitions differ.

A board's object ids are hashes of its firmware's definitions (docs/uavtalk.md "Object
ids"), so one changed enum option makes another object for the board. Definitions common
to every generation live in `definitions/`; each generation's own versions of the objects
that differ live in `definitions/generations/<folder>/`. The agent loads them all and,
on connect, asks the board for each version of those objects: the one it answers is its
generation (the other is NACKed or ignored).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Generation:
    key: str  # the simulator's --firmware
    firmware: str  # as a user reads it in a report
    folder: str  # definitions/generations/<folder>


GENERATIONS: tuple[Generation, ...] = (
    Generation("release", "dRonin Release-20180729", "Release-20180729"),
    Generation("latest", "dRonin latest source (next, 2021)", "next-2021"),
)
DEFAULT = GENERATIONS[0]


def get(key: str) -> Generation:
    """The generation of a key; ValueError naming the known keys otherwise."""
    for generation in GENERATIONS:
        if generation.key == key:
            return generation
    known = ", ".join(g.key for g in GENERATIONS)
    raise ValueError(f"unknown dRonin firmware generation {key!r} (one of {known})")
