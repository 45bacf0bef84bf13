"""One BLAS thread per process, unless the user chose otherwise.

OpenBLAS, the BLAS in numpy's wheels, keeps a worker thread per core spinning after each
large product, waiting for the next one. The synthetic camera's one product per frame
(76 800 rays by a 3×3 rotation) then cost a tenth of a core at 2 frames a second, and a
whole core at 10, where the rendering itself takes 2 ms on one thread: on a companion
computer, or ten simulated drones on one machine, that is the CPU the flight link needs.
Nothing here multiplies matrices large enough to gain from more threads.

It must run before numpy is first imported: the packages' `__init__` call it.
"""

from __future__ import annotations

import os

THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_thread() -> None:
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
