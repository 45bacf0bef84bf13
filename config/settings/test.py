"""Test settings: the suite's own services on their own ports (.data/test/env).

Under pytest-xdist each worker reads .data/test-<worker>/env (gw0, gw1, ...), which
scripts/test.sh writes: a Redis and a Mosquitto of its own, and the one PostgreSQL server,
where pytest-django gives each worker its own test database.
"""

import os

from config.env import BASE_DIR, env, pin_test_ports, read_data_env

# Children of a worker (ground processes, Celery workers, the live server) inherit the
# variable and so read the same services.
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "")
TEST_DATA_DIR = BASE_DIR / ".data" / (f"test-{_WORKER}" if _WORKER else "test")
if os.environ.get("TEST_PROFILE_DIR", str(TEST_DATA_DIR)) != str(TEST_DATA_DIR):
    # A worker inherits what its controller loaded for another profile (.data/test):
    # those values give way to the worker's own; what the user set stays.
    for _key in os.environ.get("TEST_PROFILE_KEYS", "").split(","):
        os.environ.pop(_key, None)
_before = set(os.environ)
read_data_env(TEST_DATA_DIR / "env")
if _WORKER:
    # A test that runs the service script (`services.sh start test`) must find this
    # worker's services where they are, not start others on the controller's ports.
    pin_test_ports(TEST_DATA_DIR / "env")
os.environ.setdefault("MEDIA_ROOT", str(TEST_DATA_DIR / "media"))
os.environ.setdefault("TILES_DIR", str(TEST_DATA_DIR / "tiles"))
os.environ["TEST_PROFILE_KEYS"] = ",".join(sorted(set(os.environ) - _before))
os.environ["TEST_PROFILE_DIR"] = str(TEST_DATA_DIR)
# The suite starts and stops many threads that touch the ORM; with a pool each finished
# thread would keep its connection checked out. Benchmarks turn the pool back on
# (scripts/bench.sh) to measure what production runs.
os.environ.setdefault("DB_POOL", "false")
# The suite logs in from one address far more often than a person; the throttling tests
# set the production rates themselves.
os.environ.setdefault("AUTH_TOKEN_RATE", "10000/min")
os.environ.setdefault("LOGIN_RATE", "10000/min")
# Each test that runs a worker gives it a queue of its own (shared Redis): safety work and
# imports go to the default queue unless a test names theirs (tests/config/test_queues.py).
os.environ.setdefault("SAFETY_TASK_QUEUE", "")
os.environ.setdefault("LOGS_IMPORT_QUEUE", "")
# The suite's flights keep drones closer than the separation minima (the experiments of
# [Paula 2018], ch. 5, fly three drones 7 m apart): only overlapping corridors conflict.
# The separation tests (tests/airspace) set the production minima themselves.
os.environ.setdefault("AIRSPACE_HORIZONTAL_MIN_M", "0")
os.environ.setdefault("AIRSPACE_VERTICAL_MIN_M", "0")
# The suite's organisations fly drones that have no Remote ID identity; the Remote ID
# tests (tests/remoteid) require it themselves.
os.environ.setdefault("REMOTE_ID_REQUIRED_DEFAULT", "false")
# Nor do they run pre-flight checklists; the checklist tests (tests/checklists) require them.
os.environ.setdefault("CHECKLIST_REQUIRED_DEFAULT", "false")

from .base import *  # noqa: E402,F403
from .base import DATABASES  # noqa: E402

DEBUG = False
PASSWORD_HASHERS = ["django.contrib.auth.hashers.MD5PasswordHasher"]
# Parallel runs (helpers, CI shards) each get their own test database.
DATABASES["default"]["TEST"] = {"NAME": env.str("TEST_DB_NAME", "test_skyhive")}
ALLOWED_HOSTS = ["*"]

# A Celery worker started by a test must read the database pytest-django created.
if env.str("TEST_WORKER_DB_NAME", ""):
    DATABASES["default"]["NAME"] = env.str("TEST_WORKER_DB_NAME")
# Mail stays in memory (pytest-django's outbox; the live test server keeps its own).
EMAIL_BACKEND = "django.core.mail.backends.locmem.EmailBackend"
