"""Celery entry point of the airspace app: the live separation watch."""

from __future__ import annotations

from celery import shared_task

from airspace import live


@shared_task(name="airspace.watch_separation", ignore_result=True)
def watch_separation() -> list[str]:
    return live.watch()
