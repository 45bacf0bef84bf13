#!/usr/bin/env python
import os
import sys


def main() -> None:
    # Production unless told otherwise: `make run` and the tests name their settings module.
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.production")
    from django.core.exceptions import ImproperlyConfigured
    from django.core.management import execute_from_command_line

    try:
        execute_from_command_line(sys.argv)
    except ImproperlyConfigured as exc:
        # A missing secret is a setup mistake, not a crash: one line says what to set.
        sys.exit(f"{os.environ['DJANGO_SETTINGS_MODULE']}: {exc}")


if __name__ == "__main__":
    main()
