from django.apps import AppConfig
from django.core import checks


class LogsConfig(AppConfig):
    """Uploaded flight logs: the Django side of the log viewer.

    Lives inside `logs/` beside the Django-free core, as its own app (label
    `logs`) so the core package stays importable without Django.
    """

    name = "logs"
    label = "logs"
    verbose_name = "Flight logs"
    default_auto_field = "django.db.models.BigAutoField"

    def ready(self) -> None:
        checks.register(check_thresholds_setting, "logs")


def check_thresholds_setting(app_configs, **kwargs) -> list[checks.Error]:  # type: ignore[no-untyped-def]
    """Each entry of LOGS_CHECK_THRESHOLDS must name known checks and numbers."""
    from django.conf import settings

    from logs.checks.thresholds import ThresholdError, merged

    errors = []
    overrides = getattr(settings, "LOGS_CHECK_THRESHOLDS", None) or {}
    if not isinstance(overrides, dict):
        return [checks.Error("LOGS_CHECK_THRESHOLDS must be a JSON object.", id="logs.E001")]
    for key, value in overrides.items():
        try:
            merged(value)
        except ThresholdError as exc:
            errors.append(checks.Error(f"LOGS_CHECK_THRESHOLDS[{key!r}]: {exc}", id="logs.E001"))
    return errors
