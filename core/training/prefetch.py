"""Generate training batches in a background thread so data never waits on the optimiser step
(and the step never waits on data, as long as generation is faster)."""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Iterable, Iterator
from typing import TypeVar

Item = TypeVar("Item")


class Prefetcher(Iterator[Item]):
    """Iterate over ``source`` with up to ``depth`` items made ahead in a daemon thread.

    Torch and OpenCV release the GIL in their kernels, so generation overlaps with training.
    An exception in the producer is re-raised by ``__next__``. Call :meth:`close` (or use it as
    a context manager) to stop the thread early.
    """

    _DONE = object()

    def __init__(self, source: Iterable[Item], depth: int = 2) -> None:
        self._queue: queue.Queue = queue.Queue(maxsize=depth)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._produce, args=(iter(source),), daemon=True)
        self._thread.start()

    def _produce(self, iterator: Iterator[Item]) -> None:
        try:
            for item in iterator:
                while not self._stop.is_set():
                    try:
                        self._queue.put(item, timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if self._stop.is_set():
                    return
            self._queue.put(self._DONE)
        except BaseException as error:  # handed to the consumer
            self._queue.put(error)

    def __next__(self) -> Item:
        item = self._queue.get()
        if item is self._DONE:
            raise StopIteration
        if isinstance(item, BaseException):
            raise item
        return item

    def close(self) -> None:
        self._stop.set()
        while self._thread.is_alive():
            with contextlib.suppress(queue.Empty):
                self._queue.get(timeout=0.05)
            self._thread.join(timeout=0.05)

    def __enter__(self) -> Prefetcher[Item]:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
