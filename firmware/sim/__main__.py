"""`python -m firmware.sim`: a software dRonin flight controller on a pty (or TCP port).

Prints exactly one line, `pty: /dev/pts/N` (or `tcp: HOST:PORT`), then serves UAVTalk
until SIGTERM/SIGINT. With `--fc mavlink` it is an ArduCopter-like MAVLink autopilot on
TCP port 5760 (or `--tcp PORT`, or a pty with `--serial`).
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
from pathlib import Path

from firmware.sim.mavlink_server import MavlinkSession
from firmware.sim.receiver import ReceiverArming
from firmware.sim.remote_id import RemoteIdModule
from firmware.sim.server import PtyTransport, TcpTransport, serve
from firmware.sim.telemetry import BoardSession
from firmware.sim.vehicle import Vehicle, VehicleConfig
from firmware.sim.wind import WindError, WindFile, parse_wind, wind_ned
from onboard.arming_frames import load_frames
from onboard.uavtalk import ObjectRegistry, arming_vetoes, generations


class UnknownParameter(ValueError):
    """A `--param` the MAVLink autopilot does not have."""


def _home(text: str) -> tuple[float, float, float]:
    try:
        lat, lon, alt = (float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError("home must be LAT,LON,ALT") from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise argparse.ArgumentTypeError("latitude or longitude out of range")
    return lat, lon, alt


def _param(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError("a parameter is NAME=NUMBER") from None


def _setting(text: str) -> tuple[str, str]:
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError("a setting is FIELD[.ELEMENT]=VALUE")
    return name.strip(), value.strip()


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m firmware.sim", description=__doc__)
    p.add_argument("--home", type=_home, default=(38.736946, -9.142685, 100.0), help="LAT,LON,ALT")
    p.add_argument("--time-scale", type=float, default=1.0, help="simulated seconds per second")
    _add_vehicle_options(p)
    p.add_argument("--arming-line", type=Path, help="two-character file: request pin, mode pin")
    p.add_argument(
        "--arming-time", type=float, help="seconds (simulated); default arming_frames.json"
    )
    p.add_argument("--tcp", type=int, metavar="PORT", help="serve on TCP instead of a pty (0: any)")
    p.add_argument("--tcp-host", default="127.0.0.1")
    p.add_argument("--pty-link", type=Path, help="keep a symlink to the pty at this path")
    p.add_argument(
        "--objects-dir", type=Path, help="UAVObject XML folder (default: the onboard package's)"
    )
    p.add_argument("--link-timeout", type=float, default=8.0, help="wall-clock seconds")
    p.add_argument(
        "--fc",
        choices=["uavtalk", "mavlink"],
        default="uavtalk",
        help="protocol personality; mavlink serves TCP (default port 5760, like ArduPilot SITL)",
    )
    p.add_argument("--serial", action="store_true", help="mavlink on a pty instead of TCP")
    p.add_argument(
        "--autopilot",
        choices=["ardupilot", "px4"],
        default="ardupilot",
        help="mavlink flavour: ArduCopter's modes or PX4's",
    )
    p.add_argument(
        "--param",
        type=_param,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="mavlink parameter at boot, e.g. SIM_CMD_MUTE=400 or BATT_CRT_PCT=30 (repeatable)",
    )
    p.add_argument(
        "--remote-id",
        action="store_true",
        help="mavlink: a Remote ID module on the bus answering OPEN_DRONE_ID_ARM_STATUS",
    )
    p.add_argument(
        "--remote-id-fail",
        metavar="REASON",
        help="mavlink: the Remote ID module (implies --remote-id) reports this pre-arm failure",
    )
    p.add_argument(
        "--battery-serial",
        metavar="SERIAL",
        help="mavlink: the battery's serial number, sent in SMART_BATTERY_INFO when asked",
    )
    _add_uavtalk_board_options(p)
    p.add_argument("-v", "--verbose", action="store_true")
    return p


def _add_vehicle_options(p: argparse.ArgumentParser) -> None:
    """The vehicle model: its battery, its speeds and the wind it flies in."""
    p.add_argument("--battery-capacity-mah", type=float, default=5500.0)
    p.add_argument(
        "--drain", type=float, default=15_000 / 3600, help="mAh per simulated second hovering"
    )
    p.add_argument("--cells", type=int, default=4)
    p.add_argument("--max-horizontal-speed", type=float, default=10.0, help="m/s")
    p.add_argument("--max-climb-rate", type=float, default=2.0, help="m/s, climb and descent")
    _add_wind_options(p)


def _wind(text: str) -> tuple[float, float]:
    try:
        return parse_wind(text)
    except WindError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _add_wind_options(p: argparse.ArgumentParser) -> None:
    """The wind the vehicle flies in (firmware/sim/wind.py)."""
    p.add_argument(
        "--wind",
        type=_wind,
        metavar="SPEED,FROM",
        help="wind at boot: m/s and degrees it comes from; mavlink reports it (PX4 "
        "WIND_COV, ArduPilot WIND), both protocols drift with it",
    )
    p.add_argument(
        "--wind-file",
        type=Path,
        metavar="PATH",
        help="mavlink: a file holding SPEED,FROM, read again whenever it changes",
    )


def apply_wind(session: BoardSession | MavlinkSession, args: argparse.Namespace) -> None:
    """The launch wind into the session (MAVLink: its SIM_WIND_* parameters)."""
    if isinstance(session, MavlinkSession):
        if args.wind is not None:
            session.params["SIM_WIND_SPD"], session.params["SIM_WIND_DIR"] = args.wind
        if args.wind_file is not None:
            session.wind_file = WindFile(args.wind_file)
    elif args.wind is not None:
        session.vehicle.wind = wind_ned(*args.wind)


def _add_uavtalk_board_options(p: argparse.ArgumentParser) -> None:
    """The dRonin board played: its firmware generation, receiver settings and alarms."""
    p.add_argument(
        "--receiver-setting",
        type=_setting,
        action="append",
        default=[],
        metavar="FIELD[.ELEMENT]=VALUE",
        help="uavtalk: a ManualControlSettings value other than the default set-up "
        "(Yaw Right+Throttle on channels 1-4, 1000/1500/2000, an arming channel on 5), "
        "e.g. Arming=Switch+Throttle or ChannelGroups.Throttle=PWM (repeatable)",
    )
    p.add_argument(
        "--firmware",
        choices=[g.key for g in generations.GENERATIONS],
        default=generations.DEFAULT.key,
        help="uavtalk: the dRonin generation played, with its object definitions; objects "
        "of another generation are NACKed, as the board does (release: Release-20180729, "
        "latest: dRonin's latest source, 2021)",
    )
    p.add_argument(
        "--alarm",
        type=_setting,
        action="append",
        default=[],
        metavar="ALARM=LEVEL",
        help="uavtalk: a SystemAlarms entry raised from boot, e.g. Sensors=Critical "
        "(Error or above keeps the board from arming, as dRonin's ok_to_arm does)",
    )


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.time_scale <= 0:
        print("--time-scale must be positive", file=sys.stderr)
        return 2
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        stream=sys.stderr,
        format="sim %(levelname)s %(message)s",
    )
    try:
        session = _session(args)
        apply_wind(session, args)
    except (UnknownParameter, KeyError, ValueError) as exc:
        print(exc, file=sys.stderr)
        return 2
    if args.fc == "mavlink" and args.tcp is None and not args.serial:
        args.tcp = 5760
    if args.tcp is not None:
        transport: PtyTransport | TcpTransport = TcpTransport(args.tcp_host, args.tcp)
    else:
        transport = PtyTransport(args.pty_link)
    stopping = False

    def _stop(signum, frame) -> None:
        nonlocal stopping
        stopping = True

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    print(transport.announce(), flush=True)
    try:
        serve(session, transport, lambda: stopping)
    finally:
        transport.close()
        logging.info("stopped: %s; decoder %s", session.stats, session.decoder.stats.as_dict())
    return 0


def _session(args: argparse.Namespace) -> BoardSession | MavlinkSession:
    """The flight controller the arguments ask for, on a fresh vehicle model."""
    frames = load_frames()
    config = VehicleConfig(
        home=args.home,
        max_horizontal=args.max_horizontal_speed,
        max_climb=args.max_climb_rate,
        max_descent=args.max_climb_rate,
        battery_capacity_mah=args.battery_capacity_mah,
        hover_drain_mah_s=args.drain,
        cells=args.cells,
    )
    vehicle = Vehicle(
        config=config, receiver=ReceiverArming(frames, arming_time_s=args.arming_time)
    )
    if args.fc != "mavlink":
        board = BoardSession(
            vehicle=vehicle,
            registry=ObjectRegistry.load(args.objects_dir, args.firmware),
            frames=frames,
            time_scale=args.time_scale,
            arming_line=args.arming_line,
            link_timeout_s=args.link_timeout,
            receiver_settings=dict(args.receiver_setting),
        )
        raise_alarms(board, dict(args.alarm))
        return board
    session = MavlinkSession(
        vehicle=vehicle,
        time_scale=args.time_scale,
        autopilot=args.autopilot,
        link_timeout_s=args.link_timeout,
        remote_id=RemoteIdModule(fail_reason=args.remote_id_fail)
        if args.remote_id or args.remote_id_fail
        else None,
        battery_serial=args.battery_serial,
    )
    for name, value in args.param:
        if name not in session.params:
            raise UnknownParameter(f"unknown MAVLink parameter {name}")
        session.params[name] = value
    return session


def raise_alarms(board: BoardSession, alarms: dict[str, str]) -> None:
    """SystemAlarms entries as the board's modules would raise them (ValueError for an
    alarm or level dRonin does not have)."""
    if not alarms:
        return
    field = board.registry["SystemAlarms"].field("Alarm")
    values = board.values[("SystemAlarms", 0)]["Alarm"]
    for name, level in alarms.items():
        if name not in field.element_names or level not in field.options:
            raise ValueError(f"no SystemAlarms alarm {name} at level {level}")
        values[field.element_names.index(name)] = level
    alarm_values = board.values[("SystemAlarms", 0)]
    board.vehicle.receiver.vetoed = bool(arming_vetoes.vetoes(alarm_values, field.element_names))


if __name__ == "__main__":
    sys.exit(main())
