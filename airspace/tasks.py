"""Celery entry points of the airspace app: the live separation watch and the landing queue."""

from __future__ import annotations

from celery import shared_task

from airspace import landing, live


@shared_task(name="airspace.watch_separation", ignore_result=True)
def watch_separation() -> list[str]:
    return live.watch()


@shared_task(name="airspace.advance_landings", ignore_result=True)
def advance_landings() -> list[str]:
    return landing.advance()
