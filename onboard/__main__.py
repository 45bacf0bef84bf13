"""`skyhive-agent` (or `python -m onboard`): run the onboard agent for one drone until
SIGTERM/SIGINT. `--config FILE` reads the options from a TOML file (keys are the long
option names, e.g. `link = "serial:/dev/ttyAMA0?baud=57600"`); flags given on the command
line override the file's values."""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import time
import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .agent import Agent, AgentConfig
from .arming import ArmingError, GpiodLine, SimulatedLine, UAVTalkReceiverSwitch
from .failsafe import LINK_LOSS_ACTIONS, Limits, parse_bounds
from .heartbeat import DEFAULT_PREFIX, derive_drone_id
from .protocol import is_drone_id
from .sensors import SensorConfigError, SensorField, load_field, parse_plume_option
from .wind import DEFAULT_HOLD_S

log = logging.getLogger("onboard")
MAVLINK_EXTRA = "--fc mavlink needs pymavlink: pip install 'skyhive-onboard[mavlink]'"


def _positive(text: str) -> float:
    value = float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError("must be positive")
    return value


def _fraction(text: str) -> float:
    value = float(text)
    if not 0 <= value <= 1:
        raise argparse.ArgumentTypeError("must be between 0 and 1")
    return value


def _drone_id(text: str) -> str:
    if not is_drone_id(text):
        raise argparse.ArgumentTypeError("must match ^[A-Za-z0-9_-]{1,64}$")
    return text


def _bounds(text: str) -> tuple[str, tuple[float | None, float | None]]:
    try:
        return parse_bounds(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _plume(text: str) -> Any:
    try:
        return parse_plume_option(text)
    except SensorConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="skyhive-agent", description=__doc__)
    p.add_argument("--config", type=Path, help="TOML file of options (flags override it)")
    _add_connections(p)
    _add_behaviour(p)
    return p


class ConfigFileError(ValueError):
    """A configuration file that cannot be read, or a setting no option takes."""


def config_file_args(
    parser: argparse.ArgumentParser, path: Path, given: set[str] = frozenset()
) -> list[str]:
    """The TOML file's settings as command-line tokens, to be parsed before the real flags.

    A repeatable option (`plume`, `bounds`) that is also among the `given` flags is left
    out: the command line's list replaces the file's.
    """
    try:
        settings = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigFileError(f"{path}: {exc}") from None
    tokens: list[str] = []
    for key, value in settings.items():
        option = "--" + key.replace("_", "-")
        action = parser._option_string_actions.get(option)  # noqa: SLF001 - argparse's index
        if action is None or option in ("--config", "--help"):
            raise ConfigFileError(f"{path}: unknown setting {key!r}")
        repeatable = isinstance(action, argparse._AppendAction)  # noqa: SLF001
        setting = _setting_tokens(path, key, option, action.nargs == 0, repeatable, value)
        if not (repeatable and option in given):
            tokens += setting
    return tokens


def _setting_tokens(
    path: Path, key: str, option: str, switch: bool, repeatable: bool, value: object
) -> list[str]:
    if switch:  # such as --native-missions
        if not isinstance(value, bool):
            raise ConfigFileError(f"{path}: {key} must be true or false")
        return [option] if value else []
    if isinstance(value, list) and not repeatable:
        raise ConfigFileError(f"{path}: {key} takes one value, not a list")
    items = value if isinstance(value, list) else [value]
    if any(isinstance(item, (bool, dict, list)) for item in items):
        raise ConfigFileError(f"{path}: {key} must be a string or a number")
    return [token for item in items for token in (option, str(item))]


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """Flags, with a --config file's settings underneath them."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--config", type=Path)
    known, _ = pre.parse_known_args(argv)
    if known.config is None:
        return parser.parse_args(argv)
    given = {arg.split("=", 1)[0] for arg in argv if arg.startswith("--")}
    try:
        from_file = config_file_args(parser, known.config, given)
    except ConfigFileError as exc:
        parser.error(str(exc))
    return parser.parse_args(from_file + argv)


def _add_connections(p: argparse.ArgumentParser) -> None:
    """Who the drone is and how it reaches its flight controller, broker and arming switch."""
    p.add_argument("--drone-id", type=_drone_id, help="default: <PREFIX>_<last 3 MAC bytes>")
    p.add_argument("--id-prefix", default=DEFAULT_PREFIX, help="prefix of a MAC-derived id")
    p.add_argument(
        "--link",
        required=True,
        help="flight-controller link: serial:/dev/ttyACM0?baud=115200, tcp://host:9000, /dev/pts/N",
    )
    p.add_argument(
        "--broker",
        required=True,
        help="mqtt://user:pass@host:port; several nodes of one cluster comma-separated, tried "
        "in turn when the connection is lost",
    )
    p.add_argument(
        "--fc",
        default="uavtalk",
        choices=["uavtalk", "mavlink"],
        help="flight-controller protocol: uavtalk (dRonin) or mavlink (PX4, ArduPilot)",
    )
    p.add_argument(
        "--native-missions",
        action="store_true",
        help="mavlink: fly mission steps as native MAVLink missions (for weak links)",
    )
    p.add_argument(
        "--arming",
        default="none",
        help="sim-line:PATH | gpiod:CHIP:REQUEST_LINE:MODE_LINE | uavtalk-receiver | none",
    )


def _add_failsafe(p: argparse.ArgumentParser) -> None:
    """The fail-safe's limits (onboard.failsafe.Limits): waits on the ground in wall
    seconds, the auto-disarm delay in flight seconds."""
    p.add_argument(
        "--battery-reserve", type=_fraction, default=Limits.battery_reserve, help="hold → return"
    )
    p.add_argument(
        "--alarm-repeat", type=_positive, default=Limits.alarm_repeat, help="CRITICAL resend, s"
    )
    p.add_argument(
        "--critical-takeover",
        type=_positive,
        default=Limits.critical_takeover,
        help="then return, s",
    )
    p.add_argument(
        "--link-loss-timeout", type=_positive, default=Limits.link_loss_timeout, help="seconds"
    )
    p.add_argument("--link-loss-action", choices=LINK_LOSS_ACTIONS, default=Limits.link_loss_action)
    p.add_argument(
        "--return-speed", type=_positive, default=Limits.return_speed, help="m/s, energy estimate"
    )
    p.add_argument(
        "--auto-disarm-delay",
        type=_positive,
        default=Limits.auto_disarm_delay,
        help="after landing, s",
    )
    p.add_argument(
        "--wind-hold",
        type=_positive,
        default=DEFAULT_HOLD_S,
        help="flight s the wind stays above the gear's MAX_WIND_M_S before the drone returns",
    )
    p.add_argument("--max-control-age", type=_positive, default=10.0, help="wall s; older refused")
    p.add_argument("--max-mission-age", type=_positive, default=60.0, help="wall s; older refused")


def _add_behaviour(p: argparse.ArgumentParser) -> None:
    """Files, rates, safety thresholds and the simulated sensors."""
    p.add_argument("--gear-dir", type=Path, help="folder with specs.json and sensors.json")
    p.add_argument("--log-dir", type=Path, help="folder for DFI flight logs")
    p.add_argument(
        "--envelope-file",
        type=Path,
        help="where the last flight envelope is kept across restarts (default: "
        "<log-dir>/envelope.json)",
    )
    p.add_argument("--pictures-dir", type=Path, help="default: <log-dir>/pictures")
    p.add_argument("--time-scale", type=_positive, default=1.0, help="simulation speed-up")
    p.add_argument("--heartbeat-interval", type=_positive, default=5.0, help="seconds")
    p.add_argument("--telemetry-interval", type=_positive, default=0.1, help="batch period, s")
    p.add_argument(
        "--battery-critical", type=_fraction, default=Limits.battery_critical, help="0..1"
    )
    p.add_argument(
        "--bounds",
        type=_bounds,
        action="append",
        default=[],
        help="SENSOR:LO:HI reading bounds for OUT_MEASURE (repeatable)",
    )
    _add_failsafe(p)
    p.add_argument(
        "--ground-link-topic",
        help="bridge state topic when behind an internal broker (python -m onboard.bridge "
        "prints it)",
    )
    p.add_argument("--sensor-field", type=Path, help="JSON file of simulated plumes")
    p.add_argument(
        "--plume",
        type=_plume,
        action="append",
        default=[],
        help="LAT,LON,RADIUS_M,PEAK[,SENSOR] simulated plume (repeatable)",
    )
    p.add_argument("--gear-reread-interval", type=_positive, default=5.0, help="seconds")
    p.add_argument("--video-rate", type=float, default=0.0, help="camera/out frames per second")
    p.add_argument("--pose-rate", type=float, default=0.0, help="Pose samples per second")
    p.add_argument("--media-url", help="the ground's media server (http://host:port): live video")
    p.add_argument("--live-fps", type=float, default=15.0, help="live video frames per second")
    p.add_argument("--arm-timeout", type=_positive, default=20.0, help="seconds")
    _add_collection(p)
    p.add_argument("--log-level", default="INFO")


def _add_collection(p: argparse.ArgumentParser) -> None:
    """Logs collected by themselves after each landing (onboard.collect)."""
    p.add_argument(
        "--ground-url",
        help="the ground's web address: after each landing the flight's logs are uploaded "
        "there (docs/protocol.md); without it they stay on the drone",
    )
    p.add_argument(
        "--uplink",
        default="unknown",
        help="the link to the ground: wifi, ground, cellular, radio (gear uplink.json overrides)",
    )
    p.add_argument(
        "--log-upload-rate", type=_positive, default=512 * 1024, help="bytes/s, log uploads"
    )
    p.add_argument(
        "--fc-log-rate", type=_positive, default=32 * 1024, help="bytes/s, the FC's log download"
    )


def build_arming(spec: str) -> Any:
    """The arming switch named on the command line (None for `none`)."""
    if spec == "none":
        return None
    if spec.startswith("sim-line:"):
        return SimulatedLine(spec.removeprefix("sim-line:"))
    if spec.startswith("gpiod:"):
        parts = spec.split(":")
        if len(parts) != 4:
            raise ArmingError("gpiod arming is gpiod:CHIP:REQUEST_LINE:MODE_LINE")
        return GpiodLine(parts[1], int(parts[2]), int(parts[3]))
    if spec == "uavtalk-receiver":
        return UAVTalkReceiverSwitch()
    raise ArmingError(f"unknown arming switch {spec!r}")


def build_flight_controller(kind: str, link: str, arming: Any, time_scale: float) -> Any:
    if kind == "uavtalk":
        from .fc.uavtalk import UAVTalkFlightController

        fc = UAVTalkFlightController(link, arming_switch=arming, time_scale=time_scale)
        if isinstance(arming, UAVTalkReceiverSwitch):
            arming.attach(fc)
        return fc
    if kind == "mavlink":
        try:
            from .fc.mavlink import MavlinkFlightController
        except ImportError:
            raise ValueError(MAVLINK_EXTRA) from None

        if arming is not None:
            raise ValueError("--arming is for UAVTalk boards; MAVLink arms by COMMAND_LONG")
        return MavlinkFlightController(link)  # timeouts are wall-clock: no time scale
    raise ValueError(f"unknown flight controller protocol {kind!r}")


def config_from_args(args: argparse.Namespace) -> AgentConfig:
    if args.video_rate > 0 or args.pose_rate > 0:
        try:
            from . import video  # noqa: F401 - the `camera` extra, checked before flight
        except ImportError as exc:
            raise ValueError(str(exc)) from None
    if args.media_url:
        try:
            import aiortc  # noqa: F401 - the `camera` extra, checked before flight
        except ImportError:
            raise ValueError(
                "Live video needs aiortc: pip install 'skyhive-onboard[camera]'"
            ) from None
    sensor_field = None
    if args.sensor_field is not None:
        sensor_field = load_field(args.sensor_field)
    if args.plume:
        sensor_field = sensor_field or SensorField()
        sensor_field.plumes.extend(args.plume)
    pictures = args.pictures_dir or (args.log_dir / "pictures" if args.log_dir else None)
    return AgentConfig(
        drone_id=args.drone_id or derive_drone_id(args.id_prefix),
        broker_url=args.broker,
        gear_dir=args.gear_dir,
        log_dir=args.log_dir,
        pictures_dir=pictures,
        time_scale=args.time_scale,
        heartbeat_interval=args.heartbeat_interval,
        telemetry_interval=args.telemetry_interval,
        battery_critical=args.battery_critical,
        bounds=dict(args.bounds),
        battery_reserve=args.battery_reserve,
        alarm_repeat=args.alarm_repeat,
        critical_takeover=args.critical_takeover,
        link_loss_timeout=args.link_loss_timeout,
        link_loss_action=args.link_loss_action,
        return_speed=args.return_speed,
        auto_disarm_delay=args.auto_disarm_delay,
        wind_hold=args.wind_hold,
        max_control_age=args.max_control_age,
        max_mission_age=args.max_mission_age,
        ground_link_topic=args.ground_link_topic,
        sensor_field=sensor_field,
        gear_reread_interval=args.gear_reread_interval,
        arm_timeout=args.arm_timeout,
        video_rate=args.video_rate,
        pose_rate=args.pose_rate,
        media_url=args.media_url,
        live_fps=args.live_fps,
        ground_url=args.ground_url,
        uplink=args.uplink,
        log_upload_rate=args.log_upload_rate,
        fc_log_rate=args.fc_log_rate,
        envelope_file=args.envelope_file
        or (args.log_dir / "envelope.json" if args.log_dir else None),
    )


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    logging.basicConfig(
        level=args.log_level.upper(),
        stream=sys.stderr,
        format="%(asctime)s agent %(levelname)s %(name)s: %(message)s",
    )
    try:
        config = config_from_args(args)
        arming = build_arming(args.arming)
        fc = build_flight_controller(args.fc, args.link, arming, args.time_scale)
        agent = Agent(config, fc)
        if args.native_missions:
            try:
                from .mavlink_mission import install_native_missions
            except ImportError:
                raise ValueError(MAVLINK_EXTRA) from None

            install_native_missions(agent)
    except (ArmingError, SensorConfigError, ValueError, OSError) as exc:
        print(f"onboard: {exc}", file=sys.stderr)
        return 2
    # A plain flag: a threading.Event set from a signal handler deadlocks when the signal
    # arrives while the main thread is inside that event's own wait.
    stopping: list[int] = []

    def _stop(signum: int, frame: object) -> None:
        stopping.append(signum)

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    agent.start()
    log.info(
        "agent %s running (link %s, broker %s)", config.drone_id, args.link, agent.mqtt.broker.host
    )
    print(f"agent: {config.drone_id}", flush=True)
    while not stopping:
        time.sleep(0.2)
    log.info("stopping")
    agent.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
