"""Flight logs with known faults, for the checks' tests and benchmarks, written in each
format's own structure: PX4 ULog by logs.synth.write_ulog (read back by pyulog in test_ulog.py), ArduPilot DataFlash by
logs.synth.write_dataflash (read back by pymavlink in test_dataflash.py), and MAVLink
.tlog packets encoded by pymavlink itself.

A flight lasts SECONDS: disarmed for the first ARM_AT seconds and after DISARM_AT, hovering
in between. Each fault happens at its time in FAULT_AT, so a check must report it there.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from logs.synth import dataflash_dtype, write_dataflash, write_ulog

SECONDS = 60.0
ARM_AT, DISARM_AT = 5.0, 55.0
FAULTS = ("motor", "clipping", "gps", "battery", "rc")
FAULT_AT = {"motor": 20.0, "clipping": 40.0, "gps": 30.0, "battery": 45.0, "rc": 50.0}
FAULT_FOR = {"motor": 5.0, "clipping": 0.5, "gps": 4.0, "battery": 3.0, "rc": 2.0}
# The check each fault must trip, its severity, and any check it also trips by design
# (an RC loss is a failsafe too).
EXPECTED = {
    "motor": {"motor_imbalance": "fail"},
    "clipping": {"clipping": "fail"},
    "gps": {"gps": "fail"},
    "battery": {"battery_sag": "fail"},
    "rc": {"rc_loss": "fail", "failsafe": "fail"},
}
CELLS = 4


def _times(hz: float, seconds: float = SECONDS) -> np.ndarray:
    return np.arange(int(seconds * hz)) / hz


def _during(t: np.ndarray, fault: str, faults: set[str]) -> np.ndarray:
    if fault not in faults:
        return np.zeros(len(t), dtype=bool)
    return (t >= FAULT_AT[fault]) & (t < FAULT_AT[fault] + FAULT_FOR[fault])


def _disarm_at(t: np.ndarray) -> float:
    """DISARM_AT in a flight of SECONDS; as long before the end in a longer one."""
    step = float(t[1] - t[0]) if len(t) > 1 else 0.0
    return float(t[-1]) + step - (SECONDS - DISARM_AT) if len(t) else DISARM_AT


def _armed(t: np.ndarray) -> np.ndarray:
    return (t >= ARM_AT) & (t < _disarm_at(t))


def _motors(t: np.ndarray, faults: set[str], rng: np.random.Generator) -> np.ndarray:
    """Four PWM outputs: 1000 µs disarmed, about 1500 µs hovering; motor 3 (index 2) held
    at 2000 µs during the motor fault."""
    out = np.full((len(t), 4), 1000.0)
    armed = _armed(t)
    hover = 1500 + np.array([-15.0, 10.0, 5.0, -5.0]) + rng.normal(0, 8, size=(len(t), 4))
    out[armed] = hover[armed]
    out[_during(t, "motor", faults), 2] = 2000.0
    return out


def _cell_volts(t: np.ndarray, faults: set[str]) -> np.ndarray:
    """4.1 V per cell at rest, falling from 3.95 to 3.75 V in flight; 3.2 V in the sag."""
    v = np.full(len(t), 4.1)
    armed = _armed(t)
    v[armed] = 3.95 - 0.2 * (t[armed] - ARM_AT) / (_disarm_at(t) - ARM_AT)
    v[_during(t, "battery", faults)] = 3.2
    return v * CELLS


def _clips(t: np.ndarray, faults: set[str]) -> np.ndarray:
    """A running clip count: 120 clips a record through the burst."""
    return np.cumsum(np.where(_during(t, "clipping", faults), 120, 0)).astype(np.uint32)


def _gps_ok(t: np.ndarray, faults: set[str]) -> np.ndarray:
    return ~_during(t, "gps", faults)


# --- PX4 ULog ---


def _ulog_topic(
    hz: float, fields: list[tuple[str, str]], seconds: float = SECONDS
) -> tuple[np.ndarray, np.ndarray]:
    t = _times(hz, seconds)
    arr = np.zeros(len(t), dtype=np.dtype([("timestamp", "<u8"), *fields]))
    arr["timestamp"] = np.round(t * 1e6).astype(np.uint64)
    return t, arr


def _px4_vehicle_status(faults: set[str], seconds: float) -> np.ndarray:
    """Armed between ARM_AT and the disarm; in AUTO_RTL with the failsafe set while RC is lost."""
    t, a = _ulog_topic(
        5,
        [
            ("arming_state", "u1"),
            ("nav_state", "u1"),
            ("failsafe", "?"),
            ("vehicle_type", "u1"),
            ("is_vtol", "?"),
        ],
        seconds,
    )
    a["arming_state"] = np.where(_armed(t), 2, 1)
    a["nav_state"] = np.where(_during(t, "rc", faults), 5, 2)  # 5 = AUTO_RTL
    a["failsafe"] = _during(t, "rc", faults)
    a["vehicle_type"] = 1
    return a


def _px4_sensor_combined(rng: np.random.Generator, seconds: float) -> np.ndarray:
    t, a = _ulog_topic(200, [("gyro_rad", "(3,)<f4"), ("accelerometer_m_s2", "(3,)<f4")], seconds)
    a["gyro_rad"] = rng.normal(0, 0.02, size=(len(t), 3))
    a["accelerometer_m_s2"] = rng.normal(0, 0.5, size=(len(t), 3)) + [0, 0, -9.81]
    return a


def _px4_imu_status(
    faults: set[str], rng: np.random.Generator, seconds: float, vibration: float = 2.0
) -> np.ndarray:
    """The z accelerometer's running clip count and the vibration metrics (`vibration`
    m/s² while armed)."""
    t, a = _ulog_topic(
        10,
        [
            ("accel_clipping", "(3,)<u4"),
            ("accel_vibration_metric", "<f4"),
            ("gyro_vibration_metric", "<f4"),
        ],
        seconds,
    )
    a["accel_clipping"][:, 2] = _clips(t, faults)
    a["accel_vibration_metric"] = np.where(_armed(t), vibration, 0.3) + rng.normal(0, 0.1, len(t))
    a["gyro_vibration_metric"] = 0.01
    return a


def _px4_gps_position(faults: set[str], seconds: float) -> np.ndarray:
    """A 3D fix on 14 satellites; no fix and no satellites through the GPS fault."""
    t, a = _ulog_topic(
        5,
        [
            ("lat", "<i4"),
            ("lon", "<i4"),
            ("hdop", "<f4"),
            ("jamming_indicator", "u1"),
            ("fix_type", "u1"),
            ("satellites_used", "u1"),
        ],
        seconds,
    )
    ok = _gps_ok(t, faults)
    a["lat"], a["lon"] = 473977420, 85455940
    a["hdop"] = np.where(ok, 0.8, 99.0)
    a["jamming_indicator"] = 20
    a["fix_type"] = np.where(ok, 3, 0)
    a["satellites_used"] = np.where(ok, 14, 0)
    return a


def _px4_battery_status(faults: set[str], seconds: float) -> np.ndarray:
    """The pack voltage of _cell_volts, with 40 A more drawn through the sag."""
    t, a = _ulog_topic(
        10,
        [("voltage_v", "<f4"), ("current_a", "<f4"), ("remaining", "<f4"), ("cell_count", "u1")],
        seconds,
    )
    a["voltage_v"] = _cell_volts(t, faults)
    a["current_a"] = np.where(_armed(t), 18.0, 0.5) + np.where(_during(t, "battery", faults), 40, 0)
    a["remaining"] = 0.8
    a["cell_count"] = CELLS
    return a


def _px4_input_rc(faults: set[str], seconds: float) -> np.ndarray:
    t, a = _ulog_topic(
        10,
        [("rc_lost_frame_count", "<u2"), ("rc_total_frame_count", "<u2"), ("rc_lost", "?")],
        seconds,
    )
    a["rc_total_frame_count"] = np.arange(len(t)) * 5
    a["rc_lost"] = _during(t, "rc", faults)
    return a


def _px4_actuator_outputs(faults: set[str], rng: np.random.Generator, seconds: float) -> np.ndarray:
    t, a = _ulog_topic(50, [("noutputs", "<u4"), ("output", "(16,)<f4")], seconds)
    a["noutputs"] = 4
    a["output"][:, :4] = _motors(t, faults, rng)
    return a


_PX4_TEST_RATIOS = ("vel_test_ratio", "pos_test_ratio", "hgt_test_ratio", "mag_test_ratio")


def _px4_estimator_status(rng: np.random.Generator, seconds: float) -> np.ndarray:
    """EKF innovation test ratios near 0.1, well inside their limit of 1."""
    t, a = _ulog_topic(10, [(name, "<f4") for name in _PX4_TEST_RATIOS], seconds)
    for name in _PX4_TEST_RATIOS:
        a[name] = np.abs(rng.normal(0.1, 0.05, len(t)))
    return a


def _px4_cpuload(seconds: float) -> np.ndarray:
    _, a = _ulog_topic(2, [("load", "<f4"), ("ram_usage", "<f4")], seconds)
    a["load"], a["ram_usage"] = 0.45, 0.6
    return a


def px4_ulog(
    path: Path,
    faults: set[str] = frozenset(),
    *,
    topics: set[str] | None = None,
    seconds: float = SECONDS,
    vibration: float = 2.0,
    parameters: dict[str, int | float] | None = None,
) -> Path:
    """A PX4 (v1.13-style topics) hover with the given faults; `topics` keeps only those.
    Every topic is drawn, in this order, from one generator, so keeping fewer topics
    changes none of the kept ones. `vibration` is the accelerometer vibration metric while
    armed (m/s²); `parameters` are written as the ULog's parameters."""
    rng = np.random.default_rng(5)
    out = {
        "vehicle_status": _px4_vehicle_status(faults, seconds),
        "sensor_combined": _px4_sensor_combined(rng, seconds),
        "vehicle_imu_status": _px4_imu_status(faults, rng, seconds, vibration),
        "vehicle_gps_position": _px4_gps_position(faults, seconds),
        "battery_status": _px4_battery_status(faults, seconds),
        "input_rc": _px4_input_rc(faults, seconds),
        "actuator_outputs": _px4_actuator_outputs(faults, rng, seconds),
        "estimator_status": _px4_estimator_status(rng, seconds),
        "cpuload": _px4_cpuload(seconds),
    }
    if topics is not None:
        out = {k: v for k, v in out.items() if k in topics}
    write_ulog(path, out, info={"sys_name": "PX4", "ver_hw": "SKYHIVE_TEST"}, parameters=parameters)
    return path


# --- ArduPilot DataFlash ---

_Record = tuple[str, np.ndarray]


def _message(chars: str, columns: str, hz: float) -> tuple[np.ndarray, np.ndarray]:
    t = _times(hz)
    arr = np.zeros(len(t), dtype=dataflash_dtype(chars, columns.split(",")))
    arr["TimeUS"] = np.round(t * 1e6).astype(np.uint64)
    return t, arr


def _ap_parm(parameters: dict[str, float]) -> _Record:
    parm = np.zeros(len(parameters), dtype=dataflash_dtype("QNf", ["TimeUS", "Name", "Value"]))
    parm["Name"] = [k.encode() for k in parameters]
    parm["Value"] = list(parameters.values())
    return "QNf", parm


def _ap_events() -> _Record:
    events = np.zeros(2, dtype=dataflash_dtype("QB", ["TimeUS", "Id"]))
    events["TimeUS"] = [int(ARM_AT * 1e6), int(DISARM_AT * 1e6)]
    events["Id"] = [10, 11]  # ArduPilot LogEvent ARMED, DISARMED
    return "QB", events


def _ap_imu(rng: np.random.Generator) -> _Record:
    t, a = _message("Qffffff", "TimeUS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ", 100)
    a["AccX"], a["AccY"] = rng.normal(0, 0.5, len(t)), rng.normal(0, 0.5, len(t))
    a["AccZ"] = -9.81 + rng.normal(0, 0.5, len(t))
    return "Qffffff", a


def _ap_vibe(faults: set[str], rng: np.random.Generator) -> _Record:
    t, a = _message("QfffIII", "TimeUS,VibeX,VibeY,VibeZ,Clip0,Clip1,Clip2", 10)
    for axis in ("VibeX", "VibeY", "VibeZ"):
        a[axis] = np.where(_armed(t), 12.0, 2.0) + np.abs(rng.normal(0, 1, len(t)))
    a["Clip0"] = _clips(t, faults)
    return "QfffIII", a


def _ap_xkf4(rng: np.random.Generator) -> _Record:
    t, a = _message("QBccccc", "TimeUS,C,SV,SP,SH,SM,SVT", 10)
    for col in ("SV", "SP", "SH", "SM", "SVT"):
        a[col] = np.abs(rng.normal(10, 5, len(t))).astype(np.int16)  # x 0.01: about 0.1
    return "QBccccc", a


def _ap_gps(faults: set[str]) -> _Record:
    """A 3D fix on 15 satellites; no fix on 2 through the GPS fault."""
    t, a = _message("QBIHBcLLe", "TimeUS,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt", 5)
    ok = _gps_ok(t, faults)
    a["Status"] = np.where(ok, 3, 1)
    a["NSats"] = np.where(ok, 15, 2)
    a["HDop"] = np.where(ok, 75, 9999)  # x 0.01
    a["Lat"], a["Lng"], a["Alt"] = 473977420, 85455940, 50000
    return "QBIHBcLLe", a


def _ap_bat(faults: set[str]) -> _Record:
    t, a = _message("Qfff", "TimeUS,Volt,VoltR,Curr", 10)
    a["Volt"] = _cell_volts(t, faults)
    a["VoltR"] = a["Volt"]
    a["Curr"] = np.where(_armed(t), 20.0, 0.4)
    return "Qfff", a


def _ap_rcin() -> _Record:
    """Sticks centred; throttle (channel 3) at 1000 µs while disarmed."""
    t, a = _message("QHHHH", "TimeUS,C1,C2,C3,C4", 25)
    a["C1"] = a["C2"] = a["C4"] = 1500
    a["C3"] = np.where(_armed(t), 1500, 1000)
    return "QHHHH", a


def _ap_rcou(faults: set[str], rng: np.random.Generator) -> _Record:
    t, a = _message("QHHHH", "TimeUS,C1,C2,C3,C4", 25)
    motors = _motors(t, faults, rng)
    for i in range(4):
        a[f"C{i + 1}"] = np.round(motors[:, i]).astype(np.uint16)
    return "QHHHH", a


def _ap_pm() -> _Record:
    _, a = _message("QHHIH", "TimeUS,NLon,NLoop,MaxT,Load", 1)
    a["NLoop"], a["MaxT"], a["Load"] = 400, 3000, 350  # Load in tenths of a percent
    return "QHHIH", a


def _ap_radio_failsafe() -> _Record:
    """ERR records raising the radio failsafe when RC is lost and clearing it after."""
    err = np.zeros(2, dtype=dataflash_dtype("QBB", ["TimeUS", "Subsys", "ECode"]))
    start = FAULT_AT["rc"]
    err["TimeUS"] = [int(start * 1e6), int((start + FAULT_FOR["rc"]) * 1e6)]
    err["Subsys"] = 5  # FAILSAFE_RADIO
    err["ECode"] = [1, 0]
    return "QBB", err


def ardupilot_bin(
    path: Path, faults: set[str] = frozenset(), *, parameters: dict[str, float] | None = None
) -> Path:
    """An ArduCopter hover with the given faults (message layouts as ArduCopter 4 logs
    them, scaled types included) and PARM records for `parameters`."""
    rng = np.random.default_rng(6)
    out: dict[str, _Record] = {}
    if parameters:
        out["PARM"] = _ap_parm(parameters)
    out["EV"] = _ap_events()
    out["IMU"] = _ap_imu(rng)
    out["VIBE"] = _ap_vibe(faults, rng)
    out["XKF4"] = _ap_xkf4(rng)
    out["GPS"] = _ap_gps(faults)
    out["BAT"] = _ap_bat(faults)
    out["RCIN"] = _ap_rcin()
    out["RCOU"] = _ap_rcou(faults, rng)
    out["PM"] = _ap_pm()
    if "rc" in faults:
        out["ERR"] = _ap_radio_failsafe()
    write_dataflash(path, out)
    return path


# --- MAVLink .tlog ---

T0_US = 1_700_000_000_000_000


@dataclass(frozen=True)
class _TlogFlight:
    """The flight's series at the .tlog's record times."""

    t: np.ndarray
    armed: np.ndarray
    volts: np.ndarray
    clips: np.ndarray
    gps_ok: np.ndarray
    motors: np.ndarray
    rc_lost: np.ndarray


def _tlog_flight(faults: set[str], hz: float, rng: np.random.Generator) -> _TlogFlight:
    t = _times(hz)
    return _TlogFlight(
        t=t,
        armed=_armed(t),
        volts=_cell_volts(t, faults),
        clips=_clips(t, faults),
        gps_ok=_gps_ok(t, faults),
        motors=np.round(_motors(t, faults, rng)).astype(int),
        rc_lost=_during(t, "rc", faults),
    )


def _heartbeat(flight: _TlogFlight, i: int) -> mavlink2.MAVLink_message:
    """ArduCopter's heartbeat: armed flag, RTL (mode 6) and CRITICAL while RC is lost."""
    base = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
        mavlink2.MAV_MODE_FLAG_SAFETY_ARMED if flight.armed[i] else 0
    )
    rc_lost = flight.rc_lost[i]
    state = mavlink2.MAV_STATE_CRITICAL if rc_lost else mavlink2.MAV_STATE_ACTIVE
    return mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_QUADROTOR,
        mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
        base,
        6 if rc_lost else 5,
        state,
        3,
    )


def _sys_status(flight: _TlogFlight, i: int) -> mavlink2.MAVLink_message:
    """The RC receiver present and enabled, unhealthy while RC is lost; pack volts and amps."""
    rc_bit = mavlink2.MAV_SYS_STATUS_SENSOR_RC_RECEIVER
    return mavlink2.MAVLink_sys_status_message(
        rc_bit,
        rc_bit,
        0 if flight.rc_lost[i] else rc_bit,
        350,
        int(flight.volts[i] * 1000),
        1800 if flight.armed[i] else 40,
        80,
        0,
        0,
        0,
        0,
        0,
        0,
    )


def _gps_raw_int(flight: _TlogFlight, i: int) -> mavlink2.MAVLink_message:
    ok = flight.gps_ok[i]
    return mavlink2.MAVLink_gps_raw_int_message(
        int(flight.t[i] * 1e6),
        3 if ok else 1,
        473977420,
        85455940,
        50000,
        80 if ok else 9999,
        120,
        0,
        0,
        14 if ok else 2,
    )


def _vibration(flight: _TlogFlight, i: int, rng: np.random.Generator) -> mavlink2.MAVLink_message:
    return mavlink2.MAVLink_vibration_message(
        int(flight.t[i] * 1e6),
        *(12.0 + abs(rng.normal(0, 1)) for _ in range(3)),
        int(flight.clips[i]),
        0,
        0,
    )


def _servo_output_raw(flight: _TlogFlight, i: int) -> mavlink2.MAVLink_message:
    return mavlink2.MAVLink_servo_output_raw_message(
        int(flight.t[i] * 1e6) & 0xFFFFFFFF,
        0,
        *flight.motors[i].tolist(),
        0,
        0,
        0,
        0,
    )


def _tlog_messages(
    flight: _TlogFlight, i: int, rng: np.random.Generator
) -> list[mavlink2.MAVLink_message]:
    """One record time's packets, in the order a ground station receives them."""
    return [
        _heartbeat(flight, i),
        _sys_status(flight, i),
        _gps_raw_int(flight, i),
        _vibration(flight, i, rng),
        _servo_output_raw(flight, i),
        mavlink2.MAVLink_ekf_status_report_message(0x1FF, 0.1, 0.12, 0.08, 0.05, 0.0),
    ]


def mavlink_tlog(path: Path, faults: set[str] = frozenset(), *, hz: float = 10.0) -> Path:
    """What a ground station records from an ArduCopter: HEARTBEAT, SYS_STATUS,
    GPS_RAW_INT, VIBRATION, SERVO_OUTPUT_RAW and EKF_STATUS_REPORT at `hz`, each record an
    8-byte big-endian µs stamp and the packet as pymavlink encodes it."""
    rng = np.random.default_rng(8)
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    flight = _tlog_flight(faults, hz, rng)
    with open(path, "wb") as f:
        for i, now in enumerate(flight.t):
            stamp = struct.pack(">Q", T0_US + int(now * 1e6))
            for msg in _tlog_messages(flight, i, rng):
                f.write(stamp + msg.pack(mav))
    return path
