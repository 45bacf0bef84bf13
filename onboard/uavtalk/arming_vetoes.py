"""Why a dRonin board will not arm, said in its own objects' terms.

dRonin arms only when `ok_to_arm()` allows it (flight/Modules/ManualControl/manualcontrol.c,
Release-20180729 and next alike): no `SystemAlarms.Alarm` element at Error or above, the
GPS and Telemetry alarms excepted, and a flight mode other than Failsafe. The modules
that raise an alarm say why in their own error fields (`SystemAlarms.ManualControl`,
`ConfigError`, `StateEstimation`), so those are named too. `ManualControl` at `NoRx` is
only a Warning, yet a board that reads no receiver never sees an arming gesture.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

VETO_LEVELS = ("Error", "Critical")
NOT_VETOING = ("GPS", "Telemetry")  # ok_to_arm skips these two alarms
# Per alarm, the SystemAlarms field in which its module says why (when not None).
REASON_FIELDS = {
    "ManualControl": "ManualControl",
    "SystemConfiguration": "ConfigError",
    "Attitude": "StateEstimation",
}
NO_REASON = ("None", "Undefined")


def vetoes(
    alarms: Mapping[str, object] | None,
    alarm_names: Sequence[str],
    flight_status: Mapping[str, object] | None = None,
) -> list[str]:
    """Each reason the board refuses to arm, e.g. "SystemAlarms.Alarm.Sensors is
    Critical"; empty when none is known. `alarm_names` are the Alarm field's elements."""
    found: list[str] = []
    levels = list(alarms["Alarm"]) if alarms is not None else []  # type: ignore[call-overload]
    for name, level in zip(alarm_names, levels, strict=False):
        if level in VETO_LEVELS and name not in NOT_VETOING:
            reason = _reason(alarms, name)
            found.append(f"SystemAlarms.Alarm.{name} is {level}{reason}")
    if flight_status is not None and flight_status.get("FlightMode") == "Failsafe":
        found.append("FlightStatus.FlightMode is Failsafe")
    return found


def no_receiver(alarms: Mapping[str, object] | None) -> str | None:
    """The board's own word that it reads no receiver, if it says so."""
    if alarms is not None and alarms.get("ManualControl") == "NoRx":
        return "SystemAlarms.ManualControl is NoRx: the board reads no receiver"
    return None


def _reason(alarms: Mapping[str, object] | None, name: str) -> str:
    field = REASON_FIELDS.get(name)
    value = alarms.get(field) if alarms is not None and field else None
    return f" (SystemAlarms.{field} is {value})" if value and value not in NO_REASON else ""
