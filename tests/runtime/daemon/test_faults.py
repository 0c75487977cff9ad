"""Faults across the running daemon: for each, the daemon stays up, names the fault in its
status and its log within a second, recovers by itself within five seconds of the fault's end,
and keeps every recorded message written before it; bad configuration ends it with exit code 2
and a message naming the file and the key.

The daemon (robot a, simulated world, emulated servos read by the real driver, real Zenoh on
127.0.0.1) runs in this process with short timings (see :mod:`tests.support.fault_rig`, which
``bench/faults.py`` shares); the full disk and the exit codes use ``percept run`` processes.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from percept.runtime.net.messages import (
    SIGNALS,
    Boxes,
    MessageError,
    PointingRequest,
    Signal,
    Status,
    World,
    decode,
    document,
    encode,
)
from tests.support.fault_rig import (
    EXPERIMENT,
    PROFILE,
    ROOT,
    SCENARIOS,
    SCENE,
    Measurement,
    ProcessRig,
    Rig,
    disk_full,
    endpoint,
    write_config,
)
from tests.support.zenoh_rig import free_port

os.environ.setdefault("MUJOCO_GL", "egl")

REPORT_WITHIN = 1.0  # seconds from a fault to the status and the log naming it
RECOVER_WITHIN = 5.0  # seconds from a fault's end to a status without faults

MEASURED: list[Measurement] = []


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory):
    rig = Rig(tmp_path_factory.mktemp("faults"))
    try:
        yield rig.start()
    finally:
        rig.close()


def _check(m: Measurement, alive: bool, error: object) -> None:
    assert alive, f"the daemon did not stay up: {error}"
    assert m.reported is not None, f"{m.fault}: not reported"
    assert m.reported <= REPORT_WITHIN, f"{m.fault}: reported after {m.reported:.2f} s"
    assert m.logged is not None and m.logged <= REPORT_WITHIN, f"{m.fault}: logged {m.logged}"
    assert m.recovered is not None, f"{m.fault}: no recovery"
    assert m.recovered <= RECOVER_WITHIN, f"{m.fault}: recovered after {m.recovered:.2f} s"


@pytest.mark.timeout(120)
@pytest.mark.parametrize("scenario", SCENARIOS, ids=[s.name for s in SCENARIOS])
def test_fault_is_reported_and_recovered(rig: Rig, scenario) -> None:
    threads = threading.active_count()
    m = rig.measure(
        scenario.name, scenario.expect, lambda: scenario.inject(rig), lambda: scenario.end(rig)
    )
    MEASURED.append(m)
    print(f"{m.fault}: reported {m.reported}, logged {m.logged}, recovered {m.recovered}")
    _check(m, rig.alive(), rig.daemon.error)
    assert scenario.shows(m.status), json.dumps(m.status)[:2000]
    # e.g. a flood of start signals must not leave a thread per game behind
    assert threading.active_count() <= threads + 2


ARENA = 20.0  # [peers] arena, the default
_EDGES = [0.0, 5e-324, -5e-324, ARENA, -ARENA, ARENA + 1e-9, 1e4 - 1e-9, 1e4, -1e4]
_COORDINATE = st.sampled_from(_EDGES) | st.floats(-1e4, 1e4)
_ANGLE = st.sampled_from([0.0, math.pi, -math.pi, 4 * math.pi, -4 * math.pi])
_ANGLE = _ANGLE | st.floats(-4 * math.pi, 4 * math.pi)
_SENDER = st.sampled_from(["b", "c", "c9", "z" * 64])
_NAME = _SENDER | st.just("a")
_GAME = st.sampled_from(["g", "1", "a-1-abc", "." * 64]) | st.from_regex(
    r"[A-Za-z0-9_.:-]{1,64}", fullmatch=True
)
_OBJECT = st.none() | st.integers(-(2**53), 2**53) | _GAME
_BOX = st.fixed_dictionaries(
    {
        "id": st.sampled_from([1, 2, 0, 10**9]) | st.integers(0, 10**9),
        "x": _COORDINATE,
        "y": _COORDINATE,
        "theta": _ANGLE,
    },
    optional={"n": st.integers(0, 10**9)},
)


def _pointing(sender: str) -> st.SearchStrategy[dict]:
    head = {"game": _GAME, "from": st.just(sender), "to": _NAME}
    request = st.fixed_dictionaries({**head, "x": _COORDINATE, "y": _COORDINATE})
    answer = st.fixed_dictionaries(
        {**head, "object": _OBJECT}, optional={"x": _COORDINATE, "y": _COORDINATE}
    )
    return request | answer


def _signal(sender: str) -> st.SearchStrategy[dict]:
    head = {"game": _GAME, "from": st.just(sender), "to": _NAME, "signal": st.sampled_from(SIGNALS)}
    return st.fixed_dictionaries(head, optional={"speaker": _NAME, "hearer": _NAME})


@st.composite
def inbound(draw: st.DrawFn) -> tuple[str, dict]:
    """(key, message): a schema-valid message of a topic the daemon receives, at the extremes
    the schema allows, from robot b or a made-up sender."""
    sender = draw(_SENDER)
    topic = draw(st.sampled_from(["boxes", "pointing", "signal"]))
    if topic == "boxes":
        stamp = draw(st.sampled_from([0.0, 1e11, time.time()]) | st.floats(0.0, 1e11))
        boxes = draw(st.lists(_BOX, max_size=8) | st.lists(_BOX, min_size=256, max_size=256))
        body = {"schema": Boxes.SCHEMA, "robot": sender, "stamp": stamp, "boxes": boxes}
    elif topic == "pointing":
        body = {"schema": PointingRequest.SCHEMA, **draw(_pointing(sender))}
    else:
        body = {"schema": Signal.SCHEMA, **draw(_signal(sender))}
    return f"percept/{sender}/{topic}", body


@pytest.mark.timeout(300)
def test_schema_valid_extremes_of_every_inbound_message_keep_the_daemon_running(rig: Rig) -> None:
    """Boxes, pointing and signals at the extremes the schema allows, from robot b and made-up
    senders, through the whole pipeline: the daemon stays up, its world models and statuses keep
    coming and every one of them validates. (A daemon receives no world or status messages.)"""
    import zenoh

    from percept.runtime.net.zenoh_config import client_config

    session = zenoh.open(client_config([endpoint(rig.experiment, "a")], connect_timeout=None))
    began = time.monotonic()

    @settings(max_examples=300, deadline=None, database=None)
    @given(message=inbound())
    def send(message: tuple[str, dict]) -> None:
        key, body = message
        payload = json.dumps(body).encode()
        decode(payload, body["schema"])  # the strategy makes only valid messages
        session.put(key, payload)
        time.sleep(0.01)

    try:
        send()
        # and the issue's own message: a box 10 km away on each axis from robot b
        box = {"id": 1, "x": 10000, "y": 10000, "theta": 0, "n": 1}
        far = {"schema": Boxes.SCHEMA, "robot": "b", "stamp": time.time(), "boxes": [box]}
        session.put("percept/b/boxes", json.dumps(far).encode())
        sent = time.monotonic()
        time.sleep(1.5)
    finally:
        session.close()
    assert rig.alive(), rig.daemon.error
    with rig.watch._lock:
        worlds = [w for t, w in rig.watch.worlds if t >= began]
        statuses = [(t, s) for t, s in rig.watch.statuses if t >= began]
        after = [w for t, w in rig.watch.worlds if t > sent + 0.5]
    assert len(after) >= 10, "world models stopped coming"
    for message in worlds:
        decode(json.dumps(message).encode(), World.SCHEMA)
    for _, status in statuses:
        decode(json.dumps(status).encode(), Status.SCHEMA)
    last = [s for t, s in statuses if t > sent][-1]
    assert last["peers"]["b"]["implausible"] > 0, last["peers"]
    assert any(f.startswith("implausible data from peer b") for f in last["faults"]), last
    assert last["games"]["ignored"] > 0
    assert not any(f.startswith("own ") for f in last["faults"]), last["faults"]
    peers = [p for w in worlds for p in w["peers"].values()]
    assert all(math.hypot(p["x"], p["y"]) <= ARENA for p in peers)


@pytest.mark.timeout(240)
def test_a_liveliness_token_of_a_long_name_is_rejected_and_the_daemon_goes_on(rig: Rig) -> None:
    """The issue's token: ``percept/<name>/alive`` of a 300-character name, declared while the
    daemon runs, ended it 0.6 s later (the name reached its frame record). Now it is counted
    among the rejected messages and the frames go on; the status says whom peer mode trusts."""
    import zenoh

    from percept.runtime.net.zenoh_config import client_config

    session = zenoh.open(client_config([endpoint(rig.experiment, "a")], connect_timeout=None))
    try:
        began = time.monotonic()
        before = rig.watch.first_status(began, lambda s: True, 10.0)
        assert before is not None
        token = session.liveliness().declare_token(f"percept/{'m' * 300}/alive")
        counted = rig.watch.first_status(
            began, lambda s: s["rejected_messages"] > before[1]["rejected_messages"], 10.0
        )
        time.sleep(2.0)
        token.undeclare()
    finally:
        session.close()
    assert rig.alive(), rig.daemon.error
    assert counted is not None, "the token was not counted"

    def taken(status: dict) -> int:  # frames, with or without joint readings (a loaded machine)
        return status["frames"] + status["frames_without_joints"]

    # the frames go on (the first ones after a fresh install wait for numba's kernels)
    later = rig.watch.first_status(counted[0], lambda s: taken(s) > taken(counted[1]), 60.0)
    assert later is not None and rig.alive(), rig.watch.statuses[-1]
    network = later[1]["network"]
    assert network["mode"] == "peer" and network["games_look"] is True
    assert network["trust"].startswith("peer mode: any process that reaches tcp/127.0.0.1:")


@pytest.mark.timeout(120)
def test_a_second_daemon_of_the_same_name_exits_2_before_opening_anything(
    rig: Rig, tmp_path: Path
) -> None:
    """A second ``percept run --name a`` that meets the first on the network (its experiment
    lists the first's endpoint as robot b's) refuses to start and leaves no recording."""
    a, b = endpoint(rig.experiment, "a"), endpoint(rig.experiment, "b")
    other = tmp_path / "other.toml"
    text = rig.experiment.read_text(encoding="utf-8").replace(a, f"tcp/127.0.0.1:{free_port()}")
    other.write_text(text.replace(b, a), encoding="utf-8")
    record = tmp_path / "second.mcap"
    cmd = [sys.executable, "-m", "percept.runtime.cli", "run", "--experiment", str(other)]
    cmd += ["--name", "a", "--sim", SCENE, "--record", str(record)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, encoding="utf-8", timeout=90)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "percept: robot a: another process already runs as 'a' on this network" in proc.stderr
    assert not record.exists()
    assert rig.alive()
    rig.wait_healthy(10.0)


@pytest.mark.timeout(120)
def test_recording_keeps_every_message_written_before_each_fault(rig: Rig) -> None:
    from percept.runtime.record.reader import Recording, read_recording

    stopping = rig.stop()
    sent = rig.watch.world_stamps(before=stopping - 0.5)
    recording = Recording(rig.record)
    recorded = {w["stamp"] for kind, w in read_recording(rig.record, recording) if kind == "world"}
    assert not recording.truncated
    assert len(sent) >= 30
    missing = sorted(sent - recorded)
    assert not missing, f"{len(missing)} world models sent on Zenoh are not in the recording"
    for m in MEASURED:  # the second before each fault is there
        before = [s for s in recorded if m.began_wall - 1.0 <= s < m.began_wall]
        assert before, f"nothing recorded in the second before {m.fault}"


@pytest.mark.timeout(120)
def test_full_disk_is_reported_survived_and_recording_goes_on(tmp_path: Path) -> None:
    from percept.runtime.record.reader import Recording, read_recording

    rig = ProcessRig(tmp_path).start()
    try:
        deadline = time.monotonic() + 30.0  # something to lose
        while len(rig.watch.worlds) < 60 and time.monotonic() < deadline:
            time.sleep(0.05)
        m = disk_full(rig)
        alive = rig.alive()
        time.sleep(1.5)  # recorded in the continuation file
        stopping = time.monotonic()
        code = rig.stop()
    finally:
        rig.close()
    _check(m, alive, "exit code " + str(rig.proc.returncode if rig.proc else None))
    assert code == 0
    state = m.status["recording"]
    assert state["state"] == "failed" and state["error"] == "File too large", state
    flushed = state["flushed"]
    assert flushed >= m.began_wall - 1.0  # at most a flush interval (0.5 s) is lost
    first, cont = Recording(rig.record), Recording(tmp_path / "a.1.mcap")
    kept = {w["stamp"] for kind, w in read_recording(rig.record, first) if kind == "world"}
    went_on = {w["stamp"] for kind, w in read_recording(cont.path, cont) if kind == "world"}
    assert first.truncated and not cont.truncated
    assert cont.metadata["robot"] == "a" and "background.npz" in cont.attachments
    sent = rig.watch.world_stamps(before=stopping - 0.5)
    on_disk = {s for s in sent if s < flushed - 0.5}  # logged before the last good flush
    assert on_disk and on_disk <= kept
    resumed = m.ended_wall + (m.recovered or 0.0) + 0.5
    later = {s for s in sent if s > resumed}
    assert later and later <= went_on


@pytest.mark.timeout(240)
def test_a_background_path_of_any_length_keeps_the_status_going(tmp_path: Path) -> None:
    """``--background`` with a 330-character path: the first start calibrates and saves there,
    every later start loads it and says so in the status's ``background``, clipped to what the
    field holds (it used to fail the status's own check and end the publisher thread)."""
    folder = tmp_path / ("d" * 200)
    folder.mkdir()
    path = folder / ("background-" + "b" * 100 + ".npz")
    for start in ("calibrates", "loads"):
        rig = ProcessRig(tmp_path, extra=("--background", str(path))).start()
        try:
            said = rig.wait_healthy()["background"]
            later = rig.watch.first_status(time.monotonic() + 1.0, lambda s: True, 5.0)
            alive = rig.alive()
        finally:
            code = rig.stop()
            rig.close()
        assert alive and later is not None and code == 0, start
        # A background calibrated without camera poses knows all of every frame's view.
        assert later[1]["background_unknown"] == 0.0, start
        if start == "calibrates":
            assert said.startswith("calibrated on") and path.exists()
        else:
            assert said.startswith("loaded /") and said.endswith("b.npz") and len(said) == 256
            assert "..." in said and len(f"loaded {path}") > 256


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def _experiment(tmp: Path, profile: Path = PROFILE) -> str:
    text = EXPERIMENT.read_text(encoding="utf-8").replace(
        '"../robots/robotis-op3.toml"', json.dumps(str(profile))
    )
    return text.replace('"../', f'"{EXPERIMENT.parent.parent}/')


def _case(name: str, tmp: Path) -> tuple[Path, Path, str]:
    """(experiment to run, file the message must name, key it must name)."""
    good = _experiment(tmp)
    exp = tmp / "experiment.toml"
    if name == "missing key":
        return _write(exp, good.replace('name = "tabletop"\n', "", 1)), exp, "name"
    if name == "wrong type":
        bad = good.replace("world_rate = 0.0", 'world_rate = "fast"')
        return _write(exp, bad), exp, "daemon.world_rate"
    if name == "unknown key":
        bad = good.replace("world_rate = 0.0", "world_rate = 0.0\ncolour = 1")
        return _write(exp, bad), exp, "daemon.colour"
    if name == "unknown joint name":
        profile = _write(
            tmp / "robot.toml",
            PROFILE.read_text(encoding="utf-8").replace(
                'name = "head_pan"', 'name = "head_yaw"', 1
            ),
        )
        return _write(exp, _experiment(tmp, profile)), profile, "joints[0].name"
    if name == "wrong type in the profile":
        profile = _write(
            tmp / "robot.toml",
            PROFILE.read_text(encoding="utf-8").replace("rate = 100.0", 'rate = "x"'),
        )
        return _write(exp, _experiment(tmp, profile)), profile, "bus.rate"
    if name == "missing profile file":
        return _write(exp, _experiment(tmp, tmp / "nowhere.toml")), exp, "robots[0].profile"
    if name == "missing scaling file":
        bad = good.replace("scaling/tabletop.toml", "scaling/nowhere.toml")
        return _write(exp, bad), exp, "scaling"
    if name == "missing experiment file":
        return tmp / "nowhere.toml", tmp / "nowhere.toml", "file not found"
    raise AssertionError(name)


CASES = [
    "missing key",
    "wrong type",
    "unknown key",
    "unknown joint name",
    "wrong type in the profile",
    "missing profile file",
    "missing scaling file",
    "missing experiment file",
]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("name", CASES)
def test_bad_config_ends_with_code_2_naming_file_and_key(name: str, tmp_path: Path, capsys) -> None:
    from percept.runtime.cli import main

    experiment, file, key = _case(name, tmp_path)
    code = main(["run", "--experiment", str(experiment), "--name", "a", "--sim", SCENE])
    err = capsys.readouterr().err
    assert code == 2
    assert f"percept: {file}: {key}" in err, err


@pytest.mark.timeout(60)
def test_bad_config_exit_code_of_the_process(tmp_path: Path) -> None:
    experiment, file, key = _case("unknown key", tmp_path)
    cmd = [sys.executable, "-m", "percept.runtime.cli", "run", "--experiment", str(experiment)]
    cmd += ["--name", "a", "--sim", SCENE]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, encoding="utf-8", timeout=60)
    assert proc.returncode == 2
    assert f"percept: {file}: {key}: unknown key" in proc.stderr


def test_a_status_that_fails_its_check_goes_out_reduced_to_counts_and_faults() -> None:
    from percept.runtime.daemon.status.health import reduced

    status = Status(
        robot="a",
        stamp=time.time(),
        fps=30.0,
        dropped_frames=0,
        camera={"state": "connected"},
        servos={"state": "connected"},
        peers={},
        rejected_messages=3,
        background="loaded /" + "x" * 300,  # a bug: longer than the field holds
        faults=("own status messages fail their check, not sent: ..." + "y" * 300,),
    )
    with pytest.raises(MessageError, match=r"percept\.status/1\.background"):
        decode(json.dumps(document(status)).encode(), Status.SCHEMA)
    sent = decode(encode(reduced(status)), Status.SCHEMA)
    assert isinstance(sent, Status) and sent.rejected_messages == 3
    assert sent.faults[0].startswith("own status messages fail") and len(sent.faults[0]) == 240


@pytest.mark.timeout(60)
def test_an_unwritable_record_exits_2_before_any_device_opens(tmp_path: Path) -> None:
    """A ``--record`` in a folder where no file can be created: a clear message and exit 2
    before the servos or the camera open (it used to be exit 1 with a traceback after)."""
    if os.geteuid() == 0:  # root writes in a read-only folder: /proc takes no new file
        folder = Path("/proc")
    else:
        folder = tmp_path / "read-only"
        folder.mkdir(mode=0o555)
    experiment = write_config(tmp_path)
    cmd = [sys.executable, "-m", "percept.runtime.cli", "run", "--experiment", str(experiment)]
    cmd += ["--name", "a", "--sim", SCENE, "--record", str(folder / "a.mcap")]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, encoding="utf-8", timeout=60)
    assert proc.returncode == 2, proc.stderr[-2000:]
    said = f"percept: --record: {folder / 'a.mcap'}: no file can be created in {folder}: "
    assert said in proc.stderr
    assert "Traceback" not in proc.stderr
    assert "percept.devices" not in proc.stderr and "emulat" not in proc.stderr


@pytest.mark.timeout(180)
def test_a_recording_removed_while_recorded_goes_on_in_a_new_file(tmp_path: Path) -> None:
    """``rm a.mcap`` during a run: within a second the status and the log say so, recording
    goes on in ``a.1.mcap`` (metadata and background model included), and every world model
    sent from then on is in it; the daemon stops as always."""
    from percept.runtime.record.reader import Recording, read_recording

    words = "was removed while recorded"
    rig = ProcessRig(tmp_path).start()
    try:
        began = time.monotonic()
        rig.record.unlink()
        got = rig.watch.first_status(began, lambda s: any(words in f for f in s["faults"]), 5.0)
        logged = rig.logs.first(began, words, 1.0)
        noticed = time.time() - (time.monotonic() - got[0]) if got else math.inf
        deadline = time.monotonic() + 30.0  # world models sent since: in the continuation file
        while time.monotonic() < deadline:
            if len({s for s in rig.watch.world_stamps() if s > noticed + 0.5}) >= 10:
                break
            time.sleep(0.1)
        time.sleep(1.0)  # those of the last half second before the stop are not counted
        alive = rig.alive()
        stopping = time.monotonic()
        code = rig.stop()
    finally:
        rig.close()
    assert alive and code == 0
    assert got is not None and got[0] - began <= REPORT_WITHIN
    assert logged is not None and logged - began <= REPORT_WITHIN
    cont = tmp_path / "a.1.mcap"
    said = f"recording file {rig.record} {words} (what it held is lost with it); recording "
    assert said + f"goes on in {cont}" in got[1]["faults"]
    assert got[1]["recording"]["file"] == str(cont)
    assert not rig.record.exists()
    recording = Recording(cont)
    went_on = {w["stamp"] for kind, w in read_recording(cont, recording) if kind == "world"}
    assert not recording.truncated and recording.metadata["robot"] == "a"
    assert "background.npz" in recording.attachments
    # A status named it: it was noticed before (the frames' stamps are a little older).
    sent = {s for s in rig.watch.world_stamps(before=stopping - 0.5) if s > noticed + 0.5}
    assert len(sent) >= 10 and sent <= went_on
