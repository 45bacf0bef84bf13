"""Development settings: `make run` writes .data/run/env with the services' URLs."""

from config.env import BASE_DIR, read_data_env

read_data_env(BASE_DIR / ".data" / "run" / "env")

from .base import *  # noqa: E402,F403

DEBUG = True
