"""The onboard agent is a distribution of its own: it imports nothing of the repository,
and its wheel, installed into a fresh virtualenv outside the repository from local wheels
only, flies a mission against the simulator."""

from __future__ import annotations

import ast
import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from onboard import protocol
from onboard.__main__ import parse_args
from runtime.processes import REPO_ROOT, Supervised
from workers.mosquitto import start_broker

from .ground import Ground

PACKAGE = REPO_ROOT / "onboard"
# scripts/bootstrap.sh (test profile) downloads the build backend and the dependencies here.
WHEELHOUSE = REPO_ROOT / ".data" / "wheels" / "onboard"
# Distribution name -> the top-level module it provides.
MODULE_OF = {
    "paho-mqtt": "paho",
    "pyserial": "serial",
    "pymavlink": "pymavlink",
    "numpy": "numpy",
    "pillow": "PIL",
    "gpiod": "gpiod",
    "aiortc": "aiortc",
    "av": "av",
}
HOME = (40.6303, -8.6575, 12.0)
SCALE = 20.0
DRONE = "PKG_DRONE1"
RECEIVER_ID = 0x0D2720A4  # dRonin Release-20180729's UAVTalkReceiver (docs/uavtalk.md)


def _declared() -> tuple[set[str], dict[str, set[str]]]:
    """Modules of the required dependencies, and of each optional extra."""
    project = tomllib.loads((PACKAGE / "pyproject.toml").read_text())["project"]

    def modules(requirements: list[str]) -> set[str]:
        names = [re.split(r"[<>=!~\[; ]", r, maxsplit=1)[0].lower() for r in requirements]
        return {MODULE_OF[name] for name in names}

    extras = {k: modules(v) for k, v in project["optional-dependencies"].items()}
    return modules(project["dependencies"]), extras


def _imports(path: Path, *, top_level_only: bool) -> set[str]:
    """Absolute modules a file imports; with `top_level_only`, not those inside functions."""
    tree = ast.parse(path.read_text(), filename=str(path))
    nodes: list[ast.AST] = []
    todo: list[ast.AST] = list(tree.body)
    while todo:
        node = todo.pop()
        if top_level_only and isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        nodes.append(node)
        todo.extend(ast.iter_child_nodes(node))
    package = ["onboard", *path.relative_to(PACKAGE).with_suffix("").parts[:-1]]
    found = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            found.add(node.module or "")
        elif isinstance(node, ast.ImportFrom):
            base = ".".join(
                [*package[: len(package) - node.level + 1], *filter(None, [node.module])]
            )
            # `from . import protocol` imports the module onboard.protocol.
            found |= {base, *(f"{base}.{alias.name}" for alias in node.names)}
    return found


def _sources() -> dict[str, Path]:
    modules = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(["onboard", *parts])] = path
    return modules


def test_onboard_imports_only_itself_the_standard_library_and_its_dependencies() -> None:
    required, extras = _declared()
    allowed = required | set().union(*extras.values()) | set(sys.stdlib_module_names)
    outside = {
        f"{path.relative_to(REPO_ROOT)} imports {module}"
        for path in _sources().values()
        for module in _imports(path, top_level_only=False)
        if module.split(".")[0] not in allowed | {"onboard"}
    }
    assert not outside, sorted(outside)


def _submodules_named(path: Path) -> set[str]:
    """`a.b.c` for each `from a.b import c` (c may be a module of package a.b)."""
    return {
        f"{node.module}.{alias.name}"
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module
        for alias in node.names
    }


# What a drone runs: the agent, and the command that writes its internal broker's bridge.
ENTRY_POINTS = ("onboard.__main__", "onboard.bridge")


def test_every_module_of_the_package_is_what_a_drone_runs() -> None:
    """The package holds what flies: each module is imported, at any depth, from one of
    the commands a drone runs; tools for the ground, benches or tests live elsewhere."""
    sources = _sources()

    def own(module: str) -> set[str]:
        # `from onboard.fc import mavlink` names onboard.fc.mavlink; a name inside a module
        # (onboard.protocol.Step) counts as its module.
        found = set()
        while module:
            if module in sources:
                found.add(module)
                break
            module = module.rpartition(".")[0]
        return found

    reached: set[str] = set()
    todo = list(ENTRY_POINTS)
    while todo:
        module = todo.pop()
        if module in reached:
            continue
        reached.add(module)
        parent = module.rpartition(".")[0]  # importing a module runs its packages first
        todo += [parent] if parent in sources else []
        for imported in _imports(sources[module], top_level_only=False) | _submodules_named(
            sources[module]
        ):
            todo += own(imported)
    assert sorted(set(sources) - reached) == []


def test_the_agent_starts_with_the_required_dependencies_alone() -> None:
    """What `python -m onboard` imports at load time needs no optional extra: those are
    imported inside the functions that use them, which say which extra is missing."""
    _, extras = _declared()
    optional = set().union(*extras.values())
    sources = _sources()
    seen, todo, loaded = set(), ["onboard.__main__"], set()
    while todo:
        name = todo.pop()
        if name in seen or name not in sources:
            continue
        seen.add(name)
        imported = _imports(sources[name], top_level_only=True)
        loaded |= {m.split(".")[0] for m in imported}
        todo += [m for m in imported if m.startswith("onboard")]
    assert {"onboard.agent", "onboard.mqtt"} <= seen and "paho" in loaded  # the walk is real
    assert not loaded & optional, loaded & optional


# -- the installed distribution -----------------------------------------------------------


def _run(argv: list[str], cwd: Path, **kwargs) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "PIP_"))}
    result = subprocess.run(
        argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=300, **kwargs
    )
    return result


def _pip(python: Path, *args: str, cwd: Path) -> None:
    """pip with nothing but the wheelhouse: no index, no user or machine configuration."""
    argv = [str(python), "-m", "pip", *args[:1], "--isolated", "--no-index"]
    argv += ["--find-links", str(WHEELHOUSE), "--disable-pip-version-check", *args[1:]]
    result = _run(argv, cwd)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]


@pytest.fixture(scope="module")
def venv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh virtualenv outside the repository with the agent's wheel installed."""
    if not any(WHEELHOUSE.glob("setuptools-*.whl")):
        pytest.fail(f"no wheels in {WHEELHOUSE}: run scripts/bootstrap.sh test")
    root = tmp_path_factory.mktemp("package")
    source = root / "src"
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info", "build")
    shutil.copytree(PACKAGE, source, ignore=ignore)  # the build writes beside its sources
    _pip(Path(sys.executable), "wheel", "--no-deps", str(source), "-w", str(root), cwd=root)
    [wheel] = root.glob("skyhive_onboard-*.whl")
    result = _run([sys.executable, "-m", "venv", str(root / "venv")], root)
    assert result.returncode == 0, result.stderr
    _pip(root / "venv" / "bin" / "python", "install", str(wheel), cwd=root)
    (root / "wheel").write_text(str(wheel))
    return root


@pytest.mark.slow
def test_the_installed_agent_runs_from_the_venv_with_its_package_data(venv: Path) -> None:
    bin_dir = venv / "venv" / "bin"
    help_text = _run([str(bin_dir / "skyhive-agent"), "--help"], venv)
    assert help_text.returncode == 0 and "--config" in help_text.stdout, help_text.stderr
    probe = (
        "import json, onboard; from onboard.uavtalk import ObjectRegistry, default_objects_dir\n"
        "from onboard.arming_frames import load_frames\n"
        "print(json.dumps({'file': onboard.__file__, 'dir': str(default_objects_dir()),\n"
        " 'receiver': ObjectRegistry.load()['UAVTalkReceiver'].id,\n"
        " 'arm': load_frames().arm_frame_us}))"
    )
    result = _run([str(bin_dir / "python"), "-c", probe], venv)
    assert result.returncode == 0, result.stderr
    found = json.loads(result.stdout)
    site = (venv / "venv").resolve()
    assert Path(found["file"]).resolve().is_relative_to(site)
    assert Path(found["dir"]).resolve().is_relative_to(site)
    assert found["receiver"] == RECEIVER_ID and len(found["arm"]) == 6


@pytest.mark.slow
@pytest.mark.parametrize(
    ("flags", "extra"),
    [
        (["--fc", "mavlink"], "mavlink"),
        (["--video-rate", "2"], "camera"),
        (["--arming", "gpiod:gpiochip0:17:27"], "gpio"),
    ],
)
def test_a_feature_whose_extra_is_not_installed_names_it(
    venv: Path, flags: list[str], extra: str
) -> None:
    agent = str(venv / "venv" / "bin" / "skyhive-agent")
    argv = [agent, "--link", "tcp://127.0.0.1:9", "--broker", "mqtt://x:1", *flags]
    refused = _run(argv, venv)
    assert refused.returncode == 2
    assert f"pip install 'skyhive-onboard[{extra}]'" in refused.stderr, refused.stderr


@pytest.mark.slow
def test_the_mavlink_extra_installs_from_the_wheel(venv: Path) -> None:
    wheel = (venv / "wheel").read_text()
    _pip(venv / "venv" / "bin" / "python", "install", f"{wheel}[mavlink]", cwd=venv)
    check = _run([str(venv / "venv" / "bin" / "python"), "-c", "import onboard.fc.mavlink"], venv)
    assert check.returncode == 0, check.stderr


MISSION = [
    {"index": 0, "command": "arm"},
    {"index": 1, "command": "takeoff", "params": {"altitude": 8}},
    {"index": 2, "command": "wait_for_flight"},
    {"index": 3, "command": "navigate", "params": {"lat": HOME[0] + 0.0003, "lon": HOME[1]}},
    {"index": 4, "command": "wait_for_flight", "params": {"horizontal_tolerance": 1.5}},
    {"index": 5, "command": "land"},
    {"index": 6, "command": "wait_for_flight", "params": {"vertical_tolerance": 0.5}},
    {"index": 7, "command": "disarm"},
]


def _agent_config(venv: Path, sim_url: str, broker_url: str) -> Path:
    """The agent's settings as a TOML file, the way a drone is configured."""
    drone = venv / "drone"
    shutil.copytree(PACKAGE / "gear_example", drone / "gear", dirs_exist_ok=True)
    settings = {
        "drone-id": DRONE,
        "link": sim_url,
        "broker": broker_url,
        "arming": f"sim-line:{drone / 'arming_line'}",
        "gear-dir": str(drone / "gear"),
        "log-dir": str(drone / "logs"),
        "time-scale": 1.0,  # overridden on the command line
    }
    path = drone / "agent.toml"
    path.write_text("".join(f"{k} = {json.dumps(v)}\n" for k, v in settings.items()))
    return path


@pytest.mark.slow
@pytest.mark.e2e
def test_the_installed_agent_flies_a_mission_sent_over_mqtt(venv: Path) -> None:
    broker = start_broker(venv / "broker", {"ground": "pw", DRONE: "dpw"})
    drone = venv / "drone"
    drone.mkdir(exist_ok=True)
    sim = start_simulator(
        home=HOME, time_scale=SCALE, arming_line=drone / "arming_line", log_file=venv / "sim.log"
    )
    config = _agent_config(venv, sim.url, broker.url_for(DRONE))
    argv = [str(venv / "venv" / "bin" / "skyhive-agent"), "--config", str(config)]
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    agent = Supervised(
        "installed agent", [*argv, "--time-scale", str(SCALE)], env, drone / "agent.log", cwd=venv
    )
    ground = None
    try:
        agent.start()
        ground = Ground(broker.port, DRONE)
        _fly(ground)
    finally:
        if ground is not None:
            ground.close()
        code = agent.stop() if agent.alive else agent.process.returncode
        sim.stop()
        broker.stop()
    assert code == 0, agent.output()[-3000:]


def _fly(ground: Ground) -> None:
    ground.wait_for("heartbeats", lambda m: m["fc"]["connected"] and m["position"], timeout=30)
    ground.send("mission", protocol.mission_start("pm1", "pa1", MISSION).to_dict())
    done = ground.wait_for(
        "mission",
        lambda m: m.get("type") == "mission" and m["status"] not in ("accepted",),
        timeout=90,
    )
    assert done["status"] == "completed", done
    steps = [m for m in ground.on("mission") if m.get("type") == "step"]
    seen = {(m["index"], m["status"]) for m in steps}
    assert seen == {(s["index"], st) for s in MISSION for st in ("started", "completed")}
    reached = next(m for m in steps if m["index"] == 4 and m["status"] == "completed")
    assert reached["position"]["lat"] == pytest.approx(HOME[0] + 0.0003, abs=2e-5)


# -- the configuration file ---------------------------------------------------------------


def _config(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "agent.toml"
    path.write_text(text)
    return path


def test_a_config_file_gives_the_options_and_flags_override_them(tmp_path: Path) -> None:
    path = _config(
        tmp_path,
        'drone_id = "PI_1"\nlink = "serial:/dev/ttyAMA0?baud=57600"\n'
        'broker = "mqtt://PI_1:pw@ground:1883"\ntime-scale = 2\nnative-missions = true\n'
        'plume = ["40.6,-8.6,30,900", "40.7,-8.6,30,900"]\nbounds = ["CO2::1000"]\n',
    )
    args = parse_args(["--config", str(path), "--time-scale", "5", "--plume", "1,2,3,4"])
    assert (args.drone_id, args.link) == ("PI_1", "serial:/dev/ttyAMA0?baud=57600")
    assert args.broker == "mqtt://PI_1:pw@ground:1883" and args.native_missions is True
    assert args.time_scale == 5.0  # the flag wins
    assert [p.lat for p in args.plume] == [1.0]  # a repeatable flag replaces the file's list
    assert args.bounds == [("CO2", (None, 1000.0))]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('link = "x"\nbroker = "mqtt://h"\nspeed = 3\n', "unknown setting 'speed'"),
        ('link = "x"\nbroker = "mqtt://h"\nconfig = "other.toml"\n', "unknown setting 'config'"),
        ('link = "x"\nbroker = "mqtt://h"\nnative-missions = "yes"\n', "must be true or false"),
        ('link = ["a", "b"]\nbroker = "mqtt://h"\n', "link takes one value, not a list"),
        ('link = "x"\nbroker = "mqtt://h"\ntime-scale = -1\n', "must be positive"),
        ('link = "x"\nbroker = "mqtt://h"\nfc = "dji"\n', "invalid choice: 'dji'"),
        ('link = "x"\nbroker = { host = "h" }\n', "broker must be a string or a number"),
        ('link = "x\nbroker = "mqtt://h"\n', "agent.toml"),
        ('broker = "mqtt://h"\n', "--link"),
    ],
)
def test_a_bad_config_file_is_refused_with_the_reason(
    tmp_path: Path, capsys: pytest.CaptureFixture, text: str, message: str
) -> None:
    path = _config(tmp_path, text)
    with pytest.raises(SystemExit) as exit_info:
        parse_args(["--config", str(path)])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err


def test_a_missing_config_file_is_refused(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit):
        parse_args(["--config", str(tmp_path / "absent.toml")])
    assert "absent.toml" in capsys.readouterr().err
