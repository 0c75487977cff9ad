"""JointHistory: interpolation, age, stale flags, bounded size, concurrent use."""

from __future__ import annotations

import math
import threading

import pytest

from percept.drivers.joints import JointHistory, JointSample, JointSource


def test_interpolates_between_readings() -> None:
    h = JointHistory()
    h.add(1.0, {"pan": 0.0, "tilt": 1.0})
    h.add(2.0, {"pan": 1.0, "tilt": -1.0})
    s = h.at(1.25)
    assert s.angles == pytest.approx({"pan": 0.25, "tilt": 0.5})
    assert s.t == 1.25 and s.age == 0.0 and s.stale == frozenset()
    assert h.at(2.0).angles == pytest.approx({"pan": 1.0, "tilt": -1.0})


def test_later_times_get_the_newest_angle_and_grow_old() -> None:
    h = JointHistory()
    h.add(1.0, {"pan": 0.1})
    h.add(2.0, {"pan": 0.2, "tilt": 0.3})
    s = h.at(2.5)
    assert s.angles == pytest.approx({"pan": 0.2, "tilt": 0.3})
    assert s.age == pytest.approx(0.5)
    # A joint not read lately makes the whole sample older: its newest reading is what counts.
    h.add(3.0, {"tilt": 0.4})
    assert h.at(3.0).age == pytest.approx(1.0)
    latest = h.latest()
    assert latest is not None and latest.t == 3.0 and latest.age == pytest.approx(1.0)
    # Earlier than the history: the oldest angle.
    assert h.at(0.0).angles["pan"] == pytest.approx(0.1)


def test_empty_history() -> None:
    h = JointHistory()
    assert h.latest() is None
    s = h.at(5.0)
    assert s.angles == {} and math.isinf(s.age)


def test_stale_until_read_again() -> None:
    h = JointHistory()
    h.add(1.0, {"pan": 0.0, "tilt": 0.0})
    h.mark_stale(["tilt"])
    assert h.at(1.0).stale == frozenset({"tilt"})
    h.add(2.0, {"pan": 0.1})
    assert h.stale() == frozenset({"tilt"})
    h.add(3.0, {"tilt": 0.2})
    assert h.stale() == frozenset()


def test_bounded_and_out_of_order_readings_ignored() -> None:
    h = JointHistory(capacity=4)
    for k in range(10):
        h.add(float(k), {"pan": float(k)})
    h.add(5.0, {"pan": -100.0})  # older than the newest: dropped
    assert h.at(0.0).angles["pan"] == 6.0  # only the last four readings are kept
    assert h.at(8.5).angles["pan"] == pytest.approx(8.5)
    with pytest.raises(ValueError):
        JointHistory(capacity=1)


@pytest.mark.timeout(30)
def test_concurrent_writer_and_readers() -> None:
    h = JointHistory(capacity=64)
    errors: list[BaseException] = []
    n = 5000

    def write() -> None:
        for k in range(n):
            h.add(float(k), {"pan": float(k), "tilt": -float(k)})

    def read() -> None:
        try:
            for k in range(n):
                s = h.at(k / 2)
                if s.angles:
                    assert s.angles["pan"] == pytest.approx(-s.angles["tilt"])
        except BaseException as err:  # surfaced in the main thread below
            errors.append(err)

    threads = [threading.Thread(target=write)] + [threading.Thread(target=read) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert h.latest() == JointSample({"pan": n - 1.0, "tilt": 1.0 - n}, n - 1.0, 0.0, frozenset())


def test_joint_source_protocol_is_checkable() -> None:
    class Fixed:
        def start(self) -> None: ...
        def stop(self) -> None: ...
        def angles_at(self, t: float) -> JointSample | None:
            return None

        def status(self) -> dict[str, object]:
            return {}

    assert isinstance(Fixed(), JointSource)
    assert not isinstance(object(), JointSource)
