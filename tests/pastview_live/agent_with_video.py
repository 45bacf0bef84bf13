"""`python -m tests.pastview_live.agent_with_video [--video-rate HZ] [--pose-rate HZ] ARGS`:
the onboard agent (`python -m onboard ARGS`) with the past-view camera and pose stream of
onboard/video.py started alongside, until the agent's own flags for it exist."""

from __future__ import annotations

import argparse
import sys

from onboard import __main__ as cli
from onboard.agent import Agent
from onboard.video import VideoConfig, VideoStreamer


def main(argv: list[str]) -> int:
    own = argparse.ArgumentParser(add_help=False)
    own.add_argument("--video-rate", type=float, default=2.0)
    own.add_argument("--pose-rate", type=float, default=50.0)
    options, rest = own.parse_known_args(argv)
    start, stop = Agent.start, Agent.stop

    def start_with_video(agent: Agent) -> None:
        start(agent)
        agent.video = VideoStreamer(
            lambda: agent.fc.state,
            agent.send,
            VideoConfig(
                rate_hz=options.video_rate,
                pose_hz=options.pose_rate,
                time_scale=agent.config.time_scale,
            ),
            enabled=agent.gear.has_camera,
        )
        agent.video.start()

    def stop_with_video(agent: Agent) -> None:
        agent.video.stop()
        stop(agent)

    Agent.start, Agent.stop = start_with_video, stop_with_video  # type: ignore[method-assign]
    return cli.main(rest)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
