from onboard.blas import one_thread

one_thread()  # before numpy is imported anywhere in a ground process (onboard/blas.py)

from .celery import app as celery_app  # noqa: E402

__all__ = ["celery_app"]
