"""The daemon's own measurements of itself (:mod:`percept.runtime.daemon.status.health`)."""

from __future__ import annotations

import sys
import threading
import time

import pytest

from percept.runtime.daemon.status.health import MIN_INTERVAL, Cpu

TICK = 0.01  # seconds: the kernel counts a thread's time in clock ticks


def _spin(seconds: float) -> float:
    began = time.thread_time()
    while time.thread_time() - began < seconds:
        pass
    return time.thread_time() - began


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="threads' CPU is read from /proc")
def test_each_threads_share_is_what_it_spent_by_its_own_clock() -> None:
    began = time.monotonic()  # the sample's wall time is that since the meter was made
    cpu = Cpu()
    spent: dict[str, float] = {}
    done, sampled = threading.Event(), threading.Event()

    def work(name: str, seconds: float, stay: bool) -> None:
        spent[name] = _spin(seconds)
        if stay:  # alive at the sample, as a daemon's threads are
            done.set()
            sampled.wait(10)

    ended = threading.Thread(target=work, args=("ended", 0.2, False), name="ended")
    ended.start()
    ended.join()
    staying = threading.Thread(target=work, args=("spinner", 0.3, True), name="spinner 1")
    staying.start()
    assert done.wait(10)
    total, threads = cpu.sample()
    wall = time.monotonic() - began
    sampled.set()
    staying.join()
    # Named by the first word of the thread's name; a thread that ended counts as "other".
    assert "spinner" in threads and "MainThread" in threads and "ended" not in threads
    assert abs(threads["spinner"] * wall - spent["spinner"]) <= 2 * TICK
    assert threads["other"] * wall >= spent["ended"] - 2 * TICK
    assert total * wall >= spent["spinner"] + spent["ended"] - TICK
    assert abs(sum(threads.values()) - total) * wall <= 3 * TICK


def test_a_sample_covers_the_time_since_the_last() -> None:
    cpu = Cpu()
    _spin(MIN_INTERVAL + 0.05)
    cpu.sample()
    time.sleep(0.3)
    total, threads = cpu.sample()
    assert total < 0.3  # the spin before the last sample is not in it
    assert all(0.0 <= share <= total + 0.1 for share in threads.values())


def test_samples_asked_at_once_and_from_several_threads_stay_shares_of_a_core() -> None:
    # The daemon's publisher and a caller of Daemon.status() sample at the same time; a sample
    # right after another is that one again (a few ms of clock ticks would give any share).
    cpu = Cpu()
    _spin(MIN_INTERVAL + 0.05)
    first = cpu.sample()
    assert cpu.sample() == first
    got: list[tuple[float, dict[str, float]]] = []

    def ask() -> None:
        for _ in range(200):
            got.append(cpu.sample())
            _spin(0.005)

    askers = [threading.Thread(target=ask, name=f"asker {i}") for i in range(4)]
    for a in askers:
        a.start()
    for a in askers:
        a.join()
    assert len({id(shares) for _, shares in got}) == len(got)  # each caller its own table
    for total, shares in got:
        assert 0.0 <= total <= 3.0
        assert all(0.0 <= share <= 2.0 for share in shares.values()), shares
