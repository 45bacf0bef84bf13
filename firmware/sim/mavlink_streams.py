"""What the simulated autopilot says in each streamed message, and the table that names them.

`STREAMED` maps a MAVLink message name to the function that fills its fields from a
`MavlinkSession`; the session sends what the function returns (`None`: nothing to send,
as GLOBAL_POSITION_INT without a fix). The table is the one list of streamable messages:
SET_MESSAGE_INTERVAL, REQUEST_DATA_STREAM and REQUEST_MESSAGE accept exactly its names.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

if TYPE_CHECKING:
    from firmware.sim.mavlink_server import MavlinkSession

# The message's fields in the order the codec's encoder takes them.
Fields = tuple[Any, ...] | None

# MAV_PROTOCOL_CAPABILITY bits both autopilots report in AUTOPILOT_VERSION.
CAPABILITIES = (
    mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
    | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
)
# flight_sw_version: major, minor, patch, FIRMWARE_VERSION_TYPE_OFFICIAL.
SOFTWARE_VERSIONS = {"ardupilot": (4, 5, 7, 255), "px4": (1, 15, 4, 255)}


def sys_status(session: MavlinkSession) -> Fields:
    v = session.vehicle
    sensors = 0x0020_FC2F
    healthy = sensors if session.has_position else sensors & ~mavlink.MAV_SYS_STATUS_SENSOR_GPS
    return (
        sensors,
        sensors,
        healthy,
        200,
        round(v.voltage * 1000),
        round(v.current_a * 100),
        round(v.remaining * 100),
        0,
        session.codec.stats.bad_crc + session.codec.stats.bad_data,
        0,
        0,
        0,
        0,
    )


def battery_status(session: MavlinkSession) -> Fields:
    v = session.vehicle
    cell_mv = round(v.voltage / v.config.cells * 1000)
    cells = [cell_mv] * v.config.cells + [0xFFFF] * (10 - v.config.cells)
    return (
        0,
        mavlink.MAV_BATTERY_FUNCTION_ALL,
        mavlink.MAV_BATTERY_TYPE_LIPO,
        0x7FFF,
        cells,
        round(v.current_a * 100),
        round(v.consumed_mah),
        -1,
        round(v.remaining * 100),
        round(v.estimated_flight_time()),
    )


def global_position_int(session: MavlinkSession) -> Fields:
    if not session.has_position:
        return None  # no fix, no global position estimate to send
    v = session.vehicle
    boot_ms = int(v.time * 1000) & 0xFFFFFFFF
    lat, lon, alt_msl = v.lla()
    return (
        boot_ms,
        round(lat * 1e7),
        round(lon * 1e7),
        round(alt_msl * 1000),
        round(-v.ned[2] * 1000),
        round(v.velocity[0] * 100),
        round(v.velocity[1] * 100),
        round(v.velocity[2] * 100),
        round(v.yaw * 100) % 36000,
    )


def local_position_ned(session: MavlinkSession) -> Fields:
    v = session.vehicle
    boot_ms = int(v.time * 1000) & 0xFFFFFFFF
    return (boot_ms, *v.ned, *v.velocity)


def attitude(session: MavlinkSession) -> Fields:
    v = session.vehicle
    boot_ms = int(v.time * 1000) & 0xFFFFFFFF
    roll, pitch, yaw = v.attitude()
    return (
        boot_ms,
        math.radians(roll),
        math.radians(pitch),
        math.radians(((yaw + 180) % 360) - 180),
        0.0,
        0.0,
        0.0,
    )


def highres_imu(session: MavlinkSession) -> Fields:
    v = session.vehicle
    alt_msl = v.lla()[2]
    pressure = 1013.25 * (1 - 2.25577e-5 * alt_msl) ** 5.25588
    return (
        int(v.time * 1e6),
        0.0,
        0.0,
        -9.81,
        0.0,
        0.0,
        0.0,
        0.21,
        0.0,
        0.42,
        pressure,
        0.0,
        alt_msl,
        35.0,
        0x1FFF,
    )


def gps_raw_int(session: MavlinkSession) -> Fields:
    v = session.vehicle
    lat, lon, alt_msl = v.lla()
    return (
        int(v.time * 1e6),
        3 if session.has_position else 1,
        round(lat * 1e7),
        round(lon * 1e7),
        round(alt_msl * 1000),
        90,
        110,
        round(math.hypot(*v.velocity[:2]) * 100),
        round(v.yaw * 100) % 36000,
        v.config.satellites if session.has_position else 0,
    )


def home_position(session: MavlinkSession) -> Fields:
    v = session.vehicle
    h = v.home
    return (
        round(h[0] * 1e7),
        round(h[1] * 1e7),
        round(h[2] * 1000),
        0.0,
        0.0,
        0.0,
        [1.0, 0.0, 0.0, 0.0],
        0.0,
        0.0,
        0.0,
    )


def mission_current(session: MavlinkSession) -> Fields:
    return (session.current, len(session.mission))


def extended_sys_state(session: MavlinkSession) -> Fields:
    v = session.vehicle
    if not v.airborne:
        climbing = session.armed and v.target.end[2] < -0.5 and v.target.mode != "Land"
        state = mavlink.MAV_LANDED_STATE_TAKEOFF if climbing else mavlink.MAV_LANDED_STATE_ON_GROUND
    elif v.target.mode == "Land":
        state = mavlink.MAV_LANDED_STATE_LANDING
    else:
        state = mavlink.MAV_LANDED_STATE_IN_AIR
    return (mavlink.MAV_VTOL_STATE_UNDEFINED, state)


def autopilot_version(session: MavlinkSession) -> Fields:
    major, minor, patch, kind = SOFTWARE_VERSIONS[session.autopilot]
    version = (major << 24) | (minor << 16) | (patch << 8) | kind
    capabilities = CAPABILITIES
    if not session.px4:
        capabilities |= mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
    return (
        capabilities,
        version,
        0,
        0,
        0,
        [0] * 8,
        [0] * 8,
        [0] * 8,
        0,
        0,
        0x5348495645,  # a fixed hardware uid for this simulated board
    )


def open_drone_id_arm_status(session: MavlinkSession) -> Fields:
    """The Remote ID module's answer (firmware/sim/remote_id.py); none without a module."""
    if session.remote_id is None:
        return None
    status, error = session.remote_id.arm_status()
    return (status, error.encode("ascii", "replace"))


def smart_battery_info(session: MavlinkSession) -> Fields:
    """The pack's identity and ratings [MAVLink common]; none without a serial number."""
    if session.battery_serial is None:
        return None
    config = session.vehicle.config
    capacity = round(config.battery_capacity_mah)
    return (
        0,
        mavlink.MAV_BATTERY_FUNCTION_ALL,
        mavlink.MAV_BATTERY_TYPE_LIPO,
        capacity,
        capacity,
        0xFFFF,  # cycle count not known
        session.battery_serial.encode("ascii", "replace"),
        b"SIM LIPO",
        0xFFFF,
        0,
        0,
        0,
        0,
        config.cells,
        0,
        0,
        b"",
    )


def wind_cov(session: MavlinkSession) -> Fields:
    """PX4's wind estimate: the air's velocity North, East, Down [MAVLink WIND_COV];
    ArduPilot does not send it."""
    if not session.px4:
        return None
    v = session.vehicle
    north, east, down = v.wind
    # time_usec, wind_x/y/z, var_horiz, var_vert, wind_alt (MSL), horiz/vert accuracy
    # (0: unknown).
    return (int(v.time * 1e6), north, east, down, 0.5, 0.2, v.lla()[2], 0.0, 0.0)


def wind(session: MavlinkSession) -> Fields:
    """ArduPilot's wind estimate: the direction it comes from (degrees), its speed in the
    ground plane and vertical speed [MAVLink ardupilotmega]; PX4 does not send it."""
    if session.px4:
        return None
    north, east, down = session.vehicle.wind
    from_deg = math.degrees(math.atan2(-east, -north)) % 360.0
    return (from_deg, math.hypot(north, east), down)


# Messages only one of the autopilots sends: the other refuses a request for them.
AUTOPILOT_ONLY = {"WIND_COV": "px4", "WIND": "ardupilot"}

STREAMED: dict[str, Callable[[MavlinkSession], Fields]] = {
    "SYS_STATUS": sys_status,
    "BATTERY_STATUS": battery_status,
    "GLOBAL_POSITION_INT": global_position_int,
    "LOCAL_POSITION_NED": local_position_ned,
    "ATTITUDE": attitude,
    "HIGHRES_IMU": highres_imu,
    "GPS_RAW_INT": gps_raw_int,
    "HOME_POSITION": home_position,
    "MISSION_CURRENT": mission_current,
    "EXTENDED_SYS_STATE": extended_sys_state,
    "AUTOPILOT_VERSION": autopilot_version,
    "OPEN_DRONE_ID_ARM_STATUS": open_drone_id_arm_status,
    "WIND_COV": wind_cov,
    "WIND": wind,
    "SMART_BATTERY_INFO": smart_battery_info,
}
