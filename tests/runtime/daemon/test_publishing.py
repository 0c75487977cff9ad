"""The publisher thread over a real Zenoh session: the status at its interval, and at once when
the faults or the background's phase change."""

from __future__ import annotations

import threading
import time
from dataclasses import replace

import pytest

from percept.runtime.daemon.publishing import FAULT_CHECK, Outbox, Publisher
from percept.runtime.net.link import Link
from percept.runtime.net.messages import Status
from tests.support.messages import MESSAGES
from tests.support.polling import wait_for
from tests.support.zenoh_rig import experiment

STATUS = next(m for m in MESSAGES if isinstance(m, Status))


@pytest.mark.timeout(60)
def test_the_status_goes_at_once_when_the_faults_or_the_background_phase_change() -> None:
    state = {"background": "not started", "faults": ["no background model yet"]}
    stop = threading.Event()
    with Link(experiment("a"), "a") as link:
        publisher = Publisher(
            "a",
            Outbox(link, 0.0),
            None,
            lambda now: None,
            lambda: replace(STATUS, background=state["background"], faults=tuple(state["faults"])),
            lambda: list(state["faults"]),
            lambda: state["background"].partition(" ")[0],
            5.0,
            60.0,  # no status by the interval while the test runs, but the first
            stop,
        )
        thread = threading.Thread(target=publisher.run, daemon=True)
        thread.start()

        def shown() -> Status:
            status = publisher.published
            assert status is not None
            return status

        try:
            assert wait_for(lambda: publisher.published is not None, 5.0)
            assert shown().background == "not started"
            state["background"] = "calibrating 0/30"  # a calibration begins
            assert wait_for(lambda: shown().background == "calibrating 0/30", 2.0)
            state["background"] = "calibrating 12/30"  # progress alone waits for the interval
            time.sleep(10 * FAULT_CHECK)
            assert shown().background == "calibrating 0/30"
            state["background"] = "calibrated on 30 frames"  # and it ends
            assert wait_for(lambda: shown().background == "calibrated on 30 frames", 2.0)
            state["faults"] = []  # a fault clears
            assert wait_for(lambda: shown().faults == (), 2.0)
        finally:
            stop.set()
            thread.join(5.0)
    assert not thread.is_alive()
