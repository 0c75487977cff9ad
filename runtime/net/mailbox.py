"""A bounded hand-off from threads that must never block (Zenoh's callbacks) to our own."""

from __future__ import annotations

import queue
from typing import Generic, TypeVar

T = TypeVar("T")


class DropOldest(Generic[T]):
    """A bounded queue whose producer never waits: when it is full, the oldest item is dropped
    and counted, so a slow consumer sees the newest messages and the producer's thread (one
    Zenoh callback stalls the whole session) goes on at once."""

    def __init__(self, size: int) -> None:
        self._queue: queue.Queue[T] = queue.Queue(size)
        self.dropped = 0

    def put(self, item: T) -> None:
        while True:
            try:
                self._queue.put_nowait(item)
                return
            except queue.Full:
                try:
                    self._queue.get_nowait()
                    self.dropped += 1
                except queue.Empty:
                    pass

    def get(self) -> T:
        """The oldest item, waiting for one."""
        return self._queue.get()

    def drain(self) -> list[T]:
        """Every item there is now, oldest first, without waiting."""
        items = []
        while True:
            try:
                items.append(self._queue.get_nowait())
            except queue.Empty:
                return items
