"""Settings for the whole test session.

One OpenMP (torch) thread per test process, unless ``OMP_NUM_THREADS`` is already set. The
tests run many small tensor operations (the evidence fits, tiny networks), where a second
OpenMP thread costs more than it gives: every operation ends at a barrier where one thread
spins until the other arrives, and on a busy 2-core machine the other is often descheduled.
Measured on the 2-core VM at load 7-8, ``test_evaluation_multi_view_shape.py``'s evidence run
took 187 s with torch's default 2 threads and 21 s with one. The variable is set before any
test module imports torch, and the programs that tests start (``hkpd-predict``, ``torchrun``,
the explorer) inherit it. What a test asserts does not depend on it: the tests that fix a
thread count themselves still do.
"""

from __future__ import annotations

import os
import sys

os.environ.setdefault("OMP_NUM_THREADS", "1")
# Compiled bytecode is kept (Python's default): where the environment switches that off
# (PYTHONDONTWRITEBYTECODE, as on our VMs), every program a test starts would compile torch's
# and hkpd's sources again (importing hkpd.prediction: 8.5 s instead of 3.5 s of CPU).
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
sys.dont_write_bytecode = False
