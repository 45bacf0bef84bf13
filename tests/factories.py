"""Small factories for tests: organisations, people with roles, drones."""

from __future__ import annotations

import itertools

from django.contrib.auth import get_user_model

from fleet.models import Drone, Membership, Organisation, Role

_seq = itertools.count(1)


def organisation(slug: str | None = None) -> Organisation:
    n = next(_seq)
    slug = slug or f"org-{n}"
    return Organisation.objects.create(name=slug.title(), slug=slug)


def person(
    org: Organisation | None,
    role: str = Role.OPERATOR,
    username: str | None = None,
    password: str = "correct horse battery staple",
):  # type: ignore[no-untyped-def]
    user = get_user_model().objects.create_user(username or f"user{next(_seq)}", password=password)
    if org is not None:
        Membership.objects.create(user=user, organisation=org, role=role)
    return user


def drone(org: Organisation, drone_id: str | None = None, **fields: object) -> Drone:
    return Drone.objects.create(
        organisation=org, drone_id=drone_id or f"DRONE_{next(_seq):04d}", **fields
    )
