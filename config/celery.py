"""The Celery app: Redis broker, JSON only, late acks, time limits, prompt redelivery."""

import logging
import os

from celery import Celery, bootsteps

# Production unless told otherwise: `make run` and the tests name their settings module.
os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.production")
# Workers start without Django's system checks, as the ground's services do
# (config/service_command.py says where the checks run instead).
os.environ.setdefault("CELERY_SKIP_CHECKS", "1")

log = logging.getLogger(__name__)

app = Celery("skyhive")
app.config_from_object("django.conf:settings", namespace="CELERY")
app.autodiscover_tasks(["workers", "fleet", "telemetry", "logs", "missions", "records", "airspace"])

# How often a worker looks for messages of dead workers, at most (see RestoreUnacked).
RESTORE_EVERY_S = 10.0


class RestoreUnacked(bootsteps.StartStopStep):
    """Put back the tasks of workers that died (-9, lost machine) once their visibility
    timeout has passed.

    With Redis, a message a worker took stays in an "unacknowledged" hash until that worker
    acknowledges it; only a live worker puts old entries back. Kombu does that at start and
    then on every tenth 10-second tick, so a task of a killed worker would wait up to
    100 s beyond its visibility timeout. We check every quarter of the timeout (at most
    every 10 s) instead. Other transports redeliver on their own and are left alone.
    """

    requires = {"celery.worker.consumer.tasks:Tasks"}

    def __init__(self, parent, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(parent, **kwargs)
        self.timer_ref = None

    def start(self, parent) -> None:  # type: ignore[no-untyped-def]
        qos = getattr(getattr(parent.task_consumer, "channel", None), "qos", None)
        if qos is None or not hasattr(qos, "restore_visible"):
            return
        timeout = float(app.conf.broker_transport_options.get("visibility_timeout", 3600))
        every = max(0.5, min(RESTORE_EVERY_S, timeout / 4))
        self.timer_ref = parent.timer.call_repeatedly(every, self._restore, (qos,))

    def stop(self, parent) -> None:  # type: ignore[no-untyped-def]
        if self.timer_ref is not None:
            self.timer_ref.cancel()
            self.timer_ref = None

    shutdown = stop

    @staticmethod
    def _restore(qos) -> None:  # type: ignore[no-untyped-def]
        try:
            # interval=1: restore on this call (kombu's own default only every tenth).
            qos.restore_visible(num=qos.channel.unacked_restore_limit, interval=1)
        except Exception as exc:  # noqa: BLE001 - the broker may be away; the next tick retries
            log.warning("could not put back unacknowledged tasks: %s", exc)


app.steps["consumer"].add(RestoreUnacked)
