"""A drone the wind made return home (onboard/wind.py, fleet/wind.py): one WARNING alert
per drone and return, from the heartbeats that say so (`wind.action`)."""

from __future__ import annotations

from fleet.models import Organisation
from fleet.signals import wind_return

from .models import Alert
from .raising import raise_alert


def connect() -> None:
    wind_return.connect(on_wind_return, dispatch_uid="alerts-wind-return")


def on_wind_return(sender: object, returning: list, **kwargs: object) -> None:
    organisations = Organisation.objects.in_bulk({org for _drone, org, *_rest in returning})
    for drone_id, organisation_id, speed, limit, since in returning:
        organisation = organisations.get(organisation_id)
        if organisation is None:
            continue
        # The drone's own time of the return names it: its heartbeats repeat it until the
        # drone is on the ground, and they make one alert.
        raise_alert(
            organisation,
            Alert.Kind.WIND,
            f"{drone_id} returns home: wind {speed:.1f} m/s above its limit of {limit:g} m/s",
            source=f"wind:{drone_id}:{int(since or 0)}",
            detail="Its flight controller's wind estimate stayed above the drone's limit; "
            "the drone flies home and lands.",
            drone_id=drone_id,
        )
