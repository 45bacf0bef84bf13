"""Checks of the vehicle's own state: battery sag, RC loss, motor balance and saturation,
failsafes, processor load and gaps in the log. Each takes a LogView and its thresholds."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from logs.checks.base import (
    FAIL,
    NOT_CHECKED,
    PASS,
    WARNING,
    LogView,
    Result,
    grade,
    not_checked,
    window_around,
    worst,
)
from logs.checks.signals import first_time, held, runs, timed_runs

# ArduPilot ERR subsystems and codes (AP_Logger's LogErrorSubsystem, "ERR" in the
# ArduPilot log-message reference): a non-zero code starts the condition, 0 resolves it.
ERR_RADIO = 2  # ECode 2: late frame, no radio input
ERR_FAILSAFE_RADIO = 5
ERR_FAILSAFES = {
    5: "radio",
    6: "battery",
    7: "GPS",
    8: "GCS",
    9: "fence",
    12: "crash check",
    16: "EKF check",
    17: "EKF/inertial nav",
    20: "ADSB",
    23: "terrain",
    25: "thrust loss",
    26: "sensors",
    27: "leak",
    29: "vibration",
    31: "dead reckoning",
}
# MAVLink MAV_SYS_STATUS_SENSOR_RC_RECEIVER; MAV_STATE_CRITICAL and MAV_STATE_EMERGENCY.
MAV_SENSOR_RC_RECEIVER = 0x10000
MAV_STATE_CRITICAL = 5


def _read_armed(view: LogView, path: str) -> tuple[np.ndarray, np.ndarray]:
    t, v = view.read(path)
    keep = view.armed_at(t) & np.isfinite(v)
    return t[keep], v[keep]


def _err_events(view: LogView) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]] | None:
    for layer in view.instances("ERR"):
        sub, code = view.path(layer, "Subsys"), view.path(layer, "ECode")
        if sub and code:
            t, s = view.read(sub)
            _, c = view.read(code)
            return t, s.astype(np.int64), c.astype(np.int64), [sub, code]
    return None


def _err_spans(t: np.ndarray, subsys: np.ndarray, codes: np.ndarray, wanted, end: float):
    """(start, end, subsystem) of each condition an ERR record started, until the same
    subsystem's next record with code 0 (or the log's end)."""
    spans = []
    open_at: dict[int, float] = {}
    for when, sub, code in zip(t.tolist(), subsys.tolist(), codes.tolist(), strict=True):
        if not wanted(sub, code) and code != 0:
            continue
        if code != 0 and sub not in open_at:
            open_at[sub] = when
        elif code == 0 and sub in open_at:
            spans.append((open_at.pop(sub), when, sub))
    spans += [(a, end, sub) for sub, a in open_at.items()]
    return sorted(spans)


class Sighting(NamedTuple):
    """What one source recorded: its topic, the paths that show it and the spans it found
    ((start, end) for RC loss, (start, end, kind) for failsafes)."""

    source: str
    series: list[str]
    spans: list[tuple]


def _combined(sightings: list[Sighting]) -> Sighting:
    """The sources together, named after the first."""
    return Sighting(
        sightings[0].source,
        [p for s in sightings for p in s.series],
        [span for s in sightings for span in s.spans],
    )


def _armed_err_spans(
    view: LogView, wanted: Callable[[int, int], bool]
) -> tuple[list[str], list[tuple[float, float, int]]] | None:
    """The ERR paths and the conditions of the wanted subsystems that began while armed,
    or None when the log has no ERR records."""
    err = _err_events(view)
    if err is None:
        return None
    t, subsys, codes, paths = err
    spans = [
        (a, b, sub)
        for a, b, sub in _err_spans(t, subsys, codes, wanted, view.duration)
        if view.armed_at(np.array([a]))[0]
    ]
    return paths, spans


# --- battery sag ---

_BATTERY = (
    # topic, voltage field, scale to volts, current field, scale to amperes
    ("battery_status", "voltage_v", 1.0, "current_a", 1.0),
    ("BAT", "Volt", 1.0, "Curr", 1.0),
    ("CURR", "Volt", 1.0, "Curr", 1.0),
    ("SYS_STATUS", "voltage_battery", 1e-3, "current_battery", 1e-2),
    ("BATTERY_STATUS", "voltages[0]", 1e-3, "current_battery", 1e-2),
    # dRonin FlightBatteryState (flightbatterystate.xml).
    ("FlightBatteryState", "Voltage", 1.0, "Current", 1.0),
)
# ROS sensor_msgs/BatteryState, found by its fields; its current is negative while
# discharging, so the scale turns the draw positive.
ROS_BATTERY = ("voltage", 1.0, "current", -1.0)
ROS_BATTERY_FIELDS = ("voltage", "current", "percentage", "power_supply_status")


def _cells(view: LogView, layer: str, volts: np.ndarray, full_cell_v: float) -> tuple[int, str]:
    # PX4 battery_status.cell_count; dRonin FlightBatteryState.DetectedCellCount.
    p = view.path(layer, "cell_count") or view.path(layer, "DetectedCellCount")
    if p:
        _, c = view.read(p)
        c = c[np.isfinite(c) & (c > 0)]
        if len(c):
            return int(np.median(c)), "recorded"
    n = view.parameter("BAT1_N_CELLS", "BAT_N_CELLS")
    if n and n > 0:
        return int(n), "parameter"
    rest = float(np.max(volts[: min(len(volts), 20)]))
    return max(1, math.ceil(rest / full_cell_v)), "guessed"


def battery_sag(view: LogView, thresholds: dict) -> Result:
    """The lowest voltage per cell while armed, against the empty and critical levels."""
    name = "battery_sag"
    level = thresholds["battery_sag"]
    sources = [[(layer, *fields) for layer in view.instances(topic)] for topic, *fields in _BATTERY]
    sources.append([(layer, *ROS_BATTERY) for layer in view.layers_with(*ROS_BATTERY_FIELDS)])
    for group in sources:
        findings = [
            r for r in (_battery_layer(name, view, level, *source) for source in group) if r
        ]
        if findings:
            return worst(findings)
    return not_checked(
        name,
        "no battery_status, BAT, SYS_STATUS, BATTERY_STATUS, FlightBatteryState or "
        "BatteryState voltage",
    )


def _battery_layer(  # noqa: PLR0913 - one battery record's fields and scales
    name: str,
    view: LogView,
    level: dict,
    layer: str,
    v_field: str,
    v_scale: float,
    i_field: str,
    i_scale: float,
) -> Result | None:
    """The lowest voltage per cell of one battery record while armed, or None when it
    holds no battery or was never armed."""
    vp = view.path(layer, v_field)
    if not vp:
        return None
    t, volts = view.read(vp)
    volts = np.where(volts >= 65535, np.nan, volts) * v_scale
    # Under half a volt is no battery connected (or an unused instance).
    valid = np.isfinite(volts) & (volts > 0.5)
    if valid.sum() < 2:
        return None
    t, volts = t[valid], volts[valid]
    cells, how = _cells(view, layer, volts, level["full_cell_v"])
    armed = view.armed_at(t)
    if not armed.any():
        return None
    per_cell = volts / cells
    ta, va = t[armed], per_cell[armed]
    low = float(np.min(va))
    status = grade(low, level, higher_is_worse=False)
    limit = level["fail"] if status == FAIL else level["warning"]
    at = first_time(ta, va < limit) if status != PASS else float(ta[np.argmin(va)])
    rest = float(np.max(volts[: min(len(volts), 20)]))
    series = [vp]
    ip = view.path(layer, i_field)
    current = ""
    if ip:
        series.append(ip)
        ti, amps = view.read(ip)
        if len(ti):
            k = min(int(np.searchsorted(ti, at)), len(ti) - 1)
            draw = amps[k] * i_scale
            if math.isfinite(draw) and draw >= 0:
                current = f" drawing {draw:.1f} A"
    return Result(
        name,
        status,
        low,
        "V/cell",
        {"warning": level["warning"], "fail": level["fail"]},
        at,
        f"lowest {low:.2f} V per cell ({cells} cells, {how}; {low * cells:.2f} V, "
        f"{rest - low * cells:.2f} V below the first {rest:.2f} V) at {at:.1f} s{current}",
        series=series,
        window=window_around(view, at),
    )


# --- RC loss ---


def rc_loss(view: LogView, thresholds: dict) -> Result:
    """RC lost while armed (PX4 input_rc.rc_lost and vehicle_status.rc_signal_lost;
    ArduPilot ERR radio records; MAVLink SYS_STATUS RC receiver health), and PX4's
    lost-frame share."""
    name = "rc_loss"
    flags = _px4_rc_lost(view)
    lost_frames = _lost_frame_share(name, view, thresholds["rc_loss"])
    sightings = [
        s
        for s in (flags, _err_rc_lost(view), _sys_status_rc_lost(view), _dronin_rc_lost(view))
        if s is not None
    ]
    if not sightings:
        return _rc_unrecorded(name, view)
    seen = _combined(sightings)
    spans = sorted(seen.spans)
    findings = [r for r in (lost_frames, _rc_lost_spans(name, spans)) if r is not None]
    if not findings:
        findings.append(Result(name, PASS, 0.0, "s", {}, None, f"no RC loss in {seen.source}"))
    result = worst(findings)
    result.series = list(dict.fromkeys(seen.series))[:6]
    result.window = window_around(view, result.t)
    return result


def _px4_rc_lost(view: LogView) -> Sighting | None:
    """PX4's RC-lost flags while armed, from every topic that has one."""
    source, series, spans = "", [], []
    for topic, field in (
        ("input_rc", "rc_lost"),
        ("vehicle_status", "rc_signal_lost"),
        ("failsafe_flags", "manual_control_signal_lost"),
    ):
        for layer in view.instances(topic):
            p = view.path(layer, field)
            if p:
                t, v = view.read(p)
                source = source or topic
                series.append(p)
                spans += timed_runs(t, (v > 0) & view.armed_at(t))
    return Sighting(source, series, spans) if source else None


def _lost_frame_share(name: str, view: LogView, level: dict) -> Result | None:
    """A warning when PX4's share of RC frames lost while armed is over lost_frames."""
    lost_frames = next(
        (
            (view.path(x, "rc_lost_frame_count"), view.path(x, "rc_total_frame_count"))
            for x in view.instances("input_rc")
            if view.path(x, "rc_lost_frame_count") and view.path(x, "rc_total_frame_count")
        ),
        None,
    )
    if not lost_frames:
        return None
    t, lost_n = _read_armed(view, lost_frames[0])
    _, total_n = _read_armed(view, lost_frames[1])
    if len(t) < 2 or not total_n[-1] > total_n[0]:
        return None
    share = float((lost_n[-1] - lost_n[0]) / (total_n[-1] - total_n[0]))
    limit = level["lost_frames"]
    if not share > limit:
        return None
    return Result(
        name,
        WARNING,
        share,
        "",
        {"lost_frames": limit},
        float(t[0]),
        f"{share:.0%} of RC frames lost (over {limit:.0%})",
    )


def _err_rc_lost(view: LogView) -> Sighting | None:
    """ArduPilot's radio and radio-failsafe ERR conditions begun while armed."""
    found = _armed_err_spans(view, lambda s, c: s in (ERR_RADIO, ERR_FAILSAFE_RADIO))
    if found is None:
        return None
    paths, spans = found
    return Sighting("ERR", paths, [(a, b) for a, b, _ in spans])


def _sys_status_rc_lost(view: LogView) -> Sighting | None:
    """MAVLink SYS_STATUS: an RC receiver present but not healthy while armed. A vehicle
    that never reports a receiver present tells nothing of RC loss (not a sighting)."""
    series, spans = [], []
    for layer in view.instances("SYS_STATUS"):
        present = view.path(layer, "onboard_control_sensors_present")
        health = view.path(layer, "onboard_control_sensors_health")
        if present and health:
            t, pres = view.read(present)
            _, heal = view.read(health)
            has_rc = (pres.astype(np.int64) & MAV_SENSOR_RC_RECEIVER) > 0
            if not has_rc.any():
                continue
            series.append(health)
            bad = has_rc & ((heal.astype(np.int64) & MAV_SENSOR_RC_RECEIVER) == 0)
            spans += timed_runs(t, bad & view.armed_at(t))
    return Sighting("SYS_STATUS", series, spans) if series else None


def _dronin_rc_lost(view: LogView) -> Sighting | None:
    """dRonin ManualControlCommand.Connected "False" while armed (its manual control
    module's verdict on the receiver). A recording where it never reads "True" had no
    transmitter (a drone flown by its companion computer): not a sighting."""
    for layer in view.instances("ManualControlCommand"):
        p = view.path(layer, "Connected")
        if not p:
            continue
        t, connected = view.labelled(p, {"False": 0.0, "True": 1.0})
        if not (connected == 1.0).any():
            return None
        return Sighting(
            "ManualControlCommand", [p], timed_runs(t, (connected == 0.0) & view.armed_at(t))
        )
    return None


def _rc_unrecorded(name: str, view: LogView) -> Result:
    """No RC-loss record: an ArduPilot log with RC input and no radio ERR had none."""
    if view.instances("RCIN"):
        return Result(
            name,
            PASS,
            0.0,
            "s",
            {},
            None,
            "RCIN recorded and no radio ERR record",
            series=[p for p in (view.path(view.instances("RCIN")[0], "C3"),) if p],
            window=window_around(view, None),
        )
    return not_checked(
        name, "no input_rc, vehicle_status, ERR, SYS_STATUS or ManualControlCommand Connected"
    )


def _rc_lost_spans(name: str, spans: list[tuple[float, float]]) -> Result | None:
    """Any RC loss while armed fails, at the first one."""
    if not spans:
        return None
    total = sum(b - a for a, b in spans)
    return Result(
        name,
        FAIL,
        total,
        "s",
        {},
        spans[0][0],
        f"RC lost at {spans[0][0]:.1f} s while armed ({_times(len(spans))}, {total:.1f} s in all)",
    )


def _times(n: int) -> str:
    return "once" if n == 1 else f"{n} times"


# --- motors ---

_OUTPUTS = (
    ("actuator_outputs", [f"output[{i}]" for i in range(16)]),
    ("RCOU", [f"C{i}" for i in range(1, 15)]),
    ("SERVO_OUTPUT_RAW", [f"servo{i}_raw" for i in range(1, 17)]),
)
MAX_MOTORS = 8
# Fixed-wing vehicles: PX4 vehicle_status.vehicle_type 2 (VEHICLE_TYPE_FIXED_WING);
# MAVLink HEARTBEAT.type 1 (MAV_TYPE_FIXED_WING).
FIXED_WING = {("vehicle_status", "vehicle_type"): 2, ("HEARTBEAT", "type"): 1}


def _fixed_wing(view: LogView) -> bool:
    """A fixed-wing or VTOL vehicle: its outputs mix motors with control surfaces."""
    for layer in view.instances("vehicle_status"):
        p = view.path(layer, "is_vtol")
        if p and view.read(p)[1].any():
            return True
    for layer in view.instances("HEARTBEAT"):
        p = view.path(layer, "type")
        # MAV_TYPE 19-22 and 24-25: the VTOL kinds.
        if p and np.isin(view.read(p)[1], [19, 20, 21, 22, 24, 25]).any():
            return True
    for (topic, field), value in FIXED_WING.items():
        for layer in view.instances(topic):
            p = view.path(layer, field)
            if p:
                _, v = view.read(p)
                if len(v) and np.median(v) == value:
                    return True
    return False


def _output_range(view: LogView, values: np.ndarray) -> tuple[float, float]:
    """The outputs' span: normalised (0..1 or -1..1) or PWM µs, PWM limits from the
    parameters when recorded (PX4 PWM_MAIN_MIN/MAX, ArduPilot MOT_PWM_MIN/MAX), else the
    RC standard 1000-2000 µs."""
    top_seen = float(np.nanmax(values))
    if top_seen <= 1.0001:
        return (-1.0 if float(np.nanmin(values)) < -0.01 else 0.0), 1.0
    low = view.parameter("PWM_MAIN_MIN", "MOT_PWM_MIN") or 1000.0
    high = view.parameter("PWM_MAIN_MAX", "MOT_PWM_MAX") or 2000.0
    return low, high if high > low else 2000.0


def motor_imbalance(view: LogView, thresholds: dict) -> Result:
    """The spread of the motors' mean outputs in flight, and any motor held at its limit."""
    name = "motor_imbalance"
    level = thresholds["motor_imbalance"]
    if _fixed_wing(view):
        return not_checked(name, "not a multicopter (fixed-wing or VTOL outputs)")
    seen = ""
    for topic, fields in _OUTPUTS:
        for layer in view.instances(topic):
            paths = [p for p in (view.path(layer, f) for f in fields) if p]
            if not paths:
                continue
            seen = seen or topic
            t, first = view.read(paths[0])
            armed = view.armed_at(t)
            columns, used = [], []
            for p in paths:
                tp, v = view.read(p)
                if len(tp) != len(t):
                    continue
                va = v[armed]
                # A motor moves in flight; a constant output is a servo at rest or unused.
                if len(va) >= 2 and np.isfinite(va).all() and float(np.ptp(va)) > 0:
                    columns.append(v)
                    used.append(p)
                if len(used) == MAX_MOTORS:
                    break
            if len(used) < 2:
                continue
            return _motors(view, name, level, t, armed, np.vstack(columns), used)
    if seen:
        return not_checked(name, f"fewer than two {seen} outputs moved while armed")
    return not_checked(name, "no actuator_outputs, RCOU or SERVO_OUTPUT_RAW")


def _motors(view, name, level, t, armed, outputs, paths) -> Result:  # type: ignore[no-untyped-def]
    low, high = _output_range(view, outputs[:, armed])
    span = high - low
    frac = (outputs - low) / span
    # In flight: armed and the motors together above a fifth of their range (idle spin
    # on the ground is left out).
    flying = armed & (frac.mean(axis=0) > 0.2)
    if flying.sum() < 2:
        return not_checked(name, "the motors never left idle")
    findings = []
    limit = level["limit"]
    for m, p in enumerate(paths):
        for a, b in runs(flying & (frac[m] >= limit)):
            end = t[b] if b < len(t) else t[b - 1]
            if end - t[a] >= level["saturated_s"]:
                findings.append(
                    Result(
                        name,
                        FAIL,
                        float(end - t[a]),
                        "s",
                        {"limit": limit, "saturated_s": level["saturated_s"]},
                        float(t[a]),
                        f"{p.split('/')[-1]} at its limit for {end - t[a]:.1f} s from {t[a]:.1f} s",
                    )
                )
                break
    means = frac[:, flying].mean(axis=1)
    spread = float(means.max() - means.min())
    status = grade(spread, level)
    start = float(t[np.argmax(flying)])
    hi_m, lo_m = int(np.argmax(means)), int(np.argmin(means))
    findings.append(
        Result(
            name,
            status,
            spread,
            "of range",
            {"warning": level["warning"], "fail": level["fail"]},
            start,
            f"motor means spread {spread:.0%} of the output range "
            f"({paths[hi_m].split('/')[-1]} highest, {paths[lo_m].split('/')[-1]} lowest)",
        )
    )
    result = worst(findings)
    result.series = paths
    result.window = window_around(view, result.t)
    return result


# --- failsafe ---


def failsafe(view: LogView, thresholds: dict) -> Result:
    """Failsafes while armed: PX4 vehicle_status.failsafe, ArduPilot ERR failsafe
    subsystems, MAVLink HEARTBEAT system_status critical or emergency."""
    name = "failsafe"
    sightings = [
        s
        for s in (_px4_failsafes(view), _err_failsafes(view), _dronin_failsafes(view))
        if s is not None
    ]
    # HEARTBEAT's state, else ArduPilot's modes, speak only for a log with neither
    # vehicle_status nor ERR.
    seen = (
        _combined(sightings) if sightings else _heartbeat_critical(view) or _modes_without_err(view)
    )
    if seen is None:
        return not_checked(name, "no vehicle_status, ERR, HEARTBEAT or FlightStatus")
    if not seen.spans:
        return Result(
            name,
            PASS,
            0.0,
            "events",
            {},
            None,
            f"no failsafe in {seen.source}",
            series=seen.series[:6],
            window=window_around(view, None),
        )
    spans = sorted(seen.spans)
    a, b, what = spans[0]
    kinds = ", ".join(dict.fromkeys(k for _, _, k in spans))
    return Result(
        name,
        FAIL,
        float(len(spans)),
        "events",
        {},
        a,
        f"{what} at {a:.1f} s while armed ({len(spans)} in all: {kinds})",
        series=seen.series[:6],
        window=window_around(view, a),
    )


def _px4_failsafes(view: LogView) -> Sighting | None:
    """PX4's vehicle_status.failsafe flag while armed, shown with the navigation state."""
    for layer in view.instances("vehicle_status"):
        p = view.path(layer, "failsafe")
        if p:
            t, v = view.read(p)
            nav = view.path(layer, "nav_state")
            spans = [(a, b, "failsafe") for a, b in timed_runs(t, (v > 0) & view.armed_at(t))]
            return Sighting("vehicle_status", [p, nav] if nav else [p], spans)
    return None


def _err_failsafes(view: LogView) -> Sighting | None:
    """ArduPilot's failsafe ERR conditions begun while armed, shown with the flight mode."""
    found = _armed_err_spans(view, lambda s, c: s in ERR_FAILSAFES)
    if found is None:
        return None
    paths, spans = found
    mode = next(
        (view.path(x, "ModeNum") or view.path(x, "Mode") for x in view.instances("MODE")), None
    )
    return Sighting(
        "ERR",
        [*paths, mode] if mode else list(paths),
        [(a, b, f"{ERR_FAILSAFES[sub]} failsafe") for a, b, sub in spans],
    )


# dRonin FlightStatus.ControlSource: who sets the flight mode. Failsafe and Geofence are
# the flight controller taking control; Transmitter and Tablet are the pilot's choice.
DRONIN_TAKEOVER = ("Failsafe", "Geofence")


def _dronin_failsafes(view: LogView) -> Sighting | None:
    """dRonin FlightStatus while armed: control taken by the failsafe or the geofence,
    or the flight mode Failsafe, each named with the flight mode it brought."""
    for layer in view.instances("FlightStatus"):
        source_p = view.path(layer, "ControlSource")
        mode_p = view.path(layer, "FlightMode")
        if not (source_p or mode_p):
            continue
        t = view.read(source_p or mode_p)[0]
        taken = np.zeros(len(t), dtype=bool)
        cause = np.full(len(t), "", dtype=object)
        if source_p:
            _, src = view.labelled(source_p, {k: float(i) for i, k in enumerate(DRONIN_TAKEOVER)})
            for i, kind in enumerate(DRONIN_TAKEOVER):
                cause[src == i] = kind.lower()
            taken |= np.isfinite(src)
        modes = np.full(len(t), "", dtype=object)
        if mode_p:
            _, raw = view.read(mode_p)
            labels = view.store.info(mode_p).get("labels") or {}
            modes = np.array([labels.get(str(int(x)), "") if np.isfinite(x) else "" for x in raw])
            in_failsafe = modes == "Failsafe"
            cause[in_failsafe & ~taken] = "failsafe"
            taken |= in_failsafe
        armed = view.armed_at(t)
        spans = []
        for a, b in runs(taken & armed):
            end = float(t[b]) if b < len(t) else float(t[b - 1])
            mode = f" (flight mode {modes[a]})" if modes[a] else ""
            spans.append((float(t[a]), end, f"{cause[a]} control{mode}"))
        return Sighting("FlightStatus", [p for p in (source_p, mode_p) if p], spans)
    return None


def _heartbeat_critical(view: LogView) -> Sighting | None:
    """MAVLink HEARTBEAT system_status critical or emergency while armed."""
    for layer in view.instances("HEARTBEAT"):
        p = view.path(layer, "system_status")
        if p:
            t, v = view.read(p)
            spans = [
                (a, b, "critical state")
                for a, b in timed_runs(t, (v >= MAV_STATE_CRITICAL) & view.armed_at(t))
            ]
            mode = view.path(layer, "custom_mode")
            return Sighting("HEARTBEAT", [p, mode] if mode else [p], spans)
    return None


def _modes_without_err(view: LogView) -> Sighting | None:
    """An ArduPilot log of modes and events with no ERR record."""
    if not (view.instances("MODE") or view.instances("EV")):
        return None
    # ArduPilot writes an ERR record at each failsafe: a log of modes and events
    # without one had none.
    series = [p for p in (view.path(x, "ModeNum") for x in view.instances("MODE")) if p]
    return Sighting("ERR (none recorded)", series, [])


# --- processor load ---


def cpu_load(view: LogView, thresholds: dict) -> Result:
    """The highest load held for three records (PX4 cpuload.load, ArduPilot PM.Load,
    MAVLink SYS_STATUS.load), as a fraction of the processor."""
    name = "cpu_load"
    for topic, field in (
        ("cpuload", "load"),
        ("PM", "Load"),
        ("SYS_STATUS", "load"),
        ("SystemStats", "CPULoad"),
    ):
        for layer in view.instances(topic):
            p = view.path(layer, field)
            if not p:
                continue
            t, v = _read_armed(view, p)
            if len(t) < 2:
                return not_checked(name, f"too few {topic} samples")
            # PX4 records a fraction; ArduPilot PM.Load and MAVLink SYS_STATUS.load are
            # in tenths of a percent (d%).
            if topic == "SystemStats":
                # dRonin SystemStats.CPULoad is in percent.
                v = v / 100.0
            elif topic != "cpuload":
                v = v / 1000.0
            v = held(v, 3)
            level = thresholds["cpu_load"]
            value = float(np.max(v))
            status = grade(value, level)
            limit = level["fail"] if status == FAIL else level["warning"]
            at = first_time(t, v > limit) if status != PASS else float(t[np.argmax(v)])
            return Result(
                name,
                status,
                value,
                "",
                dict(level),
                at,
                f"highest processor load {value:.0%} at {at:.1f} s",
                series=[p],
                window=window_around(view, at),
            )
    return not_checked(name, "no cpuload, PM, SYS_STATUS or SystemStats")


# --- logging dropouts ---


def logging_dropouts(view: LogView, thresholds: dict) -> Result:
    """The longest gap in the log's densest stream against its usual interval, and the
    data a PX4 logger recorded it dropped (ULog dropout messages)."""
    name = "logging_dropouts"
    result = _stream_gaps(view, thresholds["logging_dropouts"])
    dropped = (view.store.index.get("metadata") or {}).get("dropouts_ms")
    if not isinstance(dropped, int) or dropped <= 0 or result.status == NOT_CHECKED:
        return result
    logger_result = Result(
        name,
        WARNING,
        dropped / 1000.0,
        "s",
        result.threshold,
        None,
        f"the logger dropped {dropped} ms of data (ULog dropout records)",
    )
    combined = worst([result, logger_result])
    combined.series, combined.window = result.series, result.window
    return combined


def _stream_gaps(view: LogView, level: dict) -> Result:
    name = "logging_dropouts"
    series = view.store.index["series"]
    numeric = [(i["count"], p) for p, i in series.items() if i["kind"] in ("int", "double")]
    if not numeric:
        return not_checked(name, "no numeric series")
    count, path = max(numeric)
    if count < 10:
        return not_checked(name, "log too short: under 10 records in its densest stream")
    t, _ = view.read(path)
    dt = np.diff(t)
    usual = float(np.median(dt[dt > 0])) if (dt > 0).any() else 0.0
    gap_limit = max(level["factor"] * usual, level["min_gap_s"])
    gaps = np.flatnonzero(dt > gap_limit)
    if not len(gaps):
        return Result(
            name,
            PASS,
            float(dt.max()),
            "s",
            {"gap_s": round(gap_limit, 6), "fail": level["fail_s"]},
            None,
            f"no gap over {gap_limit:.3g} s in {path.split('/')[0]} ({1 / usual:.0f} Hz)"
            if usual
            else "no gap",
            series=[path],
            window=window_around(view, None),
        )
    longest = float(dt[gaps].max())
    status = FAIL if longest >= level["fail_s"] else WARNING
    at = (
        float(t[gaps[0]])
        if status == WARNING
        else float(t[gaps[np.argmax(dt[gaps] >= level["fail_s"])]])
    )
    return Result(
        name,
        status,
        longest,
        "s",
        {"gap_s": round(gap_limit, 6), "fail": level["fail_s"]},
        at,
        f"{len(gaps)} gaps over {gap_limit:.3g} s in {path.split('/')[0]}, the longest {longest:.2f} s",
        series=[path],
        window=window_around(view, at),
    )
