"""The serial board (tactile_viewer/sources/serial_reader.py): the reader on a pty and on a socket, its
reconnection only to the same device, and the backlog dropped on opening."""

import os
import threading
import time
import tty

import numpy as np
import pytest
import serial

from tactile_viewer.io import files
from tactile_viewer.io.layout import SensorLayout
from tactile_viewer.sources import serial_reader
from tactile_viewer.sources.device import SAME_DEVICE_RULE, DeviceIdentity
from tactile_viewer.sources.live import NOT_A_STRESS, Calibration
from tactile_viewer.sources.protocol import encode_binary
from tactile_viewer.sources.serial_reader import SerialReader
from tests.tactile_viewer.skins import grid32, wait_for
from tests.tactile_viewer.sources.test_live import values

# -- SerialReader on a pseudo-terminal ------------------------------------------------------------

@pytest.fixture
def pty():
    """A raw pseudo-terminal: (master fd to write the board's bytes to, slave device path)."""
    master, slave = os.openpty()
    tty.setraw(slave)  # no echo, no newline translation
    yield master, os.ttyname(slave)
    os.close(master)
    os.close(slave)


@pytest.fixture
def make_reader(pty):
    readers = []

    def make(**kwargs):
        layout = SensorLayout(grid32(), "kPa")
        reader = SerialReader(pty[1], layout, **kwargs)
        readers.append(reader)
        return reader

    yield make
    for reader in readers:
        reader.stop()  # always: the worker thread must not outlive the test


def write_all(fd, data):
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def test_reader_calibrates_to_pascals_and_keeps_the_newest(pty, make_reader):
    reader = make_reader()
    reader.start()
    assert reader.state == "connected"
    write_all(pty[0], b"".join(encode_binary(s, values(s)) for s in (0, 1, 2)))
    wait_for(lambda: reader.stats.received == 3, what="three frames")
    frame = reader.take_latest()
    assert frame.index == 2 and frame.t >= 0
    np.testing.assert_array_equal(frame.stress, values(2) * 1000)  # kPa -> Pa
    assert reader.take_latest() is None  # taken: nothing new since
    assert reader.stats.lost == 0 and reader.rejected() == {}


def test_frame_arrived_fires_once_until_taken(pty, make_reader):
    calls = []
    reader = make_reader()
    reader.frame_arrived.connect(lambda: calls.append(threading.current_thread().name))
    reader.start()
    write_all(pty[0], encode_binary(0, values(0)))
    wait_for(lambda: len(calls) == 1, what="the first notification")
    assert calls[0].startswith("source ")  # called from the reader thread, not ours
    write_all(pty[0], encode_binary(1, values(1)))
    wait_for(lambda: reader.stats.received == 2, what="the second frame")
    write_all(pty[0], encode_binary(2, values(2)))
    wait_for(lambda: reader.stats.received == 3, what="the third frame")
    assert len(calls) == 1  # the GUI has not taken the first yet: no second notification
    # a frame is published just after it is counted: wait for it before taking, without re-arming
    wait_for(lambda: reader._latest is not None and reader._latest.index == 2, what="the third frame published")
    assert len(calls) == 1
    assert reader.take_latest().index == 2  # the newest; the ones before it were skipped, as the GUI may
    write_all(pty[0], encode_binary(3, values(3)))
    wait_for(lambda: len(calls) == 2, what="the notification after taking")
    assert reader.take_latest().index == 3


def test_reader_skips_garbage(pty, make_reader):
    reader = make_reader()
    reader.start()
    rng = np.random.default_rng(4)  # fixed seed
    garbage = bytes(b for b in rng.integers(0, 256, 300, dtype=np.uint8).tobytes() if b != 0xA5)  # no sync
    write_all(pty[0], garbage + encode_binary(0, values(0)) + garbage[:50] + encode_binary(1, values(1)))
    wait_for(lambda: reader.stats.received == 2, what="both frames past the garbage")
    assert reader.decoder.skipped_bytes == len(garbage) + 50
    assert reader.take_latest().index == 1


def test_a_frame_that_is_no_stress_once_calibrated_is_rejected_and_counted(pty, make_reader, tmp_path):
    # a text board's 1e308 is a float, but 1e308 kPa is inf Pa: it was recorded, and failed every solve
    reader = make_reader(fmt="text")
    reader.start()
    recorder = reader.start_recording(tmp_path / "rec.mcap", flush_interval=0.05)
    rows = [values(0), [1e308, *values(1)[1:]], [1e98, *values(2)[1:]], values(3)]  # 1e101 Pa: beyond
    lines = [", ".join(repr(float(v)) for v in row) for row in rows]
    write_all(pty[0], ("\n".join(lines) + "\n").encode())
    wait_for(lambda: reader.published == 2, what="the two stresses")
    assert reader.rejected() == {NOT_A_STRESS: 2} and reader.failures == 0
    np.testing.assert_array_equal(reader.take_latest().stress, values(3) * 1000)
    assert recorder is reader.recorder
    loaded = files.load(reader.stop_recording())
    np.testing.assert_allclose(loaded.frames[:], [values(0) * 1000, values(3) * 1000], rtol=1e-12)
    # nor is such a frame averaged into a tare
    calibration = Calibration(SensorLayout(grid32(), "kPa"))
    calibration.tare(2)
    assert calibration(np.array([1e308, *values(0)[1:]])) is None and calibration.taring
    calibration(values(0))
    calibration(values(0))
    np.testing.assert_array_equal(calibration(values(0)), np.zeros(6))


def test_frames_that_do_not_fit_the_layout_say_what_they_hold_against_it(pty, make_reader):
    # "wrong value count 3" alone did not say that the board sends 4 values for a 6-taxel layout
    reader = make_reader(fmt="text")
    reader.start()
    assert reader.size_mismatch() == ""
    write_all(pty[0], b"1, 2, 3, 4\n1, 2, 3, 4\n1, 2, 3, 4, 5, 6, 7\n" + b", ".join(b"1" for _ in range(6)) + b"\n")
    wait_for(lambda: reader.stats.received == 1, what="the one frame that fits")
    assert reader.rejected() == {"wrong value count": 3}
    assert reader.size_mismatch("board.json") == ("frames of 4 values (2 frames), 7 values (1 frames); the layout "
                                                  "board.json describes 6 taxels")


def test_reader_records_every_frame(pty, make_reader, tmp_path):
    reader = make_reader()
    reader.start()
    recorder = reader.start_recording(tmp_path / "rec.mcap", flush_interval=0.05)
    assert reader.recorder is recorder
    for start in range(0, 300, 50):  # bursts, so that the reader sees many reads
        write_all(pty[0], b"".join(encode_binary(s, values(s % 7)) for s in range(start, start + 50)))
        time.sleep(0.01)
    wait_for(lambda: reader.published == 300, what="300 frames handed to the recorder")
    path = reader.stop_recording()
    assert path == tmp_path / "rec.mcap" and reader.recorder is None
    loaded = files.load(path)
    np.testing.assert_array_equal(loaded.sequence(), np.arange(300))  # every frame, no gap
    np.testing.assert_allclose(loaded.frames[:], np.array([values(s % 7) for s in range(300)]) * 1000, rtol=1e-8)
    # the raw values as the board sent them (kPa, float32), the conversion beside them
    np.testing.assert_array_equal(loaded.frames.raw(slice(None)), np.float32([values(s % 7) for s in range(300)]))
    assert loaded.calibration.units == "kPa" and loaded.frames.raw_dtype == np.float32
    assert np.all(np.diff(loaded.t) >= 0)
    assert reader.stats.lost == 0


def test_a_frame_arriving_while_the_reader_waits_is_read_in_one_pass(pty):
    # the reader's loop decodes what one read returns: a frame that arrives while the read waits
    # comes back whole, not as its first byte and then the rest in a second pass (two passes a
    # frame cost a 1 kHz board's reader a tenth of its CPU)
    master, path = pty
    reader = SerialReader(path, SensorLayout(grid32(), "kPa"))
    port = serial.serial_for_url(path, timeout=5.0)
    frame = encode_binary(7, values(1))
    got = []
    try:
        waiting = threading.Thread(target=lambda: got.append(reader._read(port)))
        waiting.start()
        time.sleep(0.05)  # the read is waiting for a first byte (nothing to wait on: there is no byte)
        write_all(master, frame)
        waiting.join(5.0)
        assert got == [frame]
    finally:
        port.close()


@pytest.mark.parametrize("baudrate", [0, -9600, 2**31, 2**40, 9600.0, "9600", True])
def test_a_baud_rate_no_port_takes_is_refused_when_the_reader_is_made(baudrate):
    # 2^31 and more raised OverflowError on the reader's thread ("Unexpected error" in the window)
    with pytest.raises(ValueError, match=r"baud rate must be a whole number from 1 to 2147483647, got "):
        SerialReader("loop://", SensorLayout(grid32()), baudrate=baudrate)


def test_reader_start_fails_at_once_on_a_missing_device(tmp_path):
    reader = SerialReader(str(tmp_path / "no-such-tty"), SensorLayout(grid32()))
    try:
        with pytest.raises(serial.SerialException) as info:
            reader.start()
        assert isinstance(info.value, OSError)
        assert reader._thread is None  # no worker left retrying behind the caller's back
    finally:
        reader.stop()


def test_reader_rejects_an_unknown_format():
    with pytest.raises(ValueError, match=r"fmt must be one of .*'hex'"):
        SerialReader("loop://", SensorLayout(grid32()), fmt="hex")


def test_reader_reads_a_socket_url_and_reconnects_to_it():
    import socket

    # a board behind TCP (pyserial's socket:// URL), dropped and reaccepted
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    layout = SensorLayout(grid32(), "kPa")
    accepted = []
    thread = threading.Thread(target=lambda: accepted.append(server.accept()[0]), daemon=True)
    thread.start()
    reader = SerialReader(f"socket://127.0.0.1:{port}", layout, reconnect_interval=0.05)
    try:
        reader.start()
        thread.join(5)
        accepted[0].sendall(b"".join(encode_binary(s, values(s)) for s in range(5)))
        wait_for(lambda: reader.stats.received == 5, what="five frames over TCP")
        np.testing.assert_array_equal(reader.take_latest().stress, values(4) * 1000)
        thread = threading.Thread(target=lambda: accepted.append(server.accept()[0]), daemon=True)
        thread.start()
        accepted[0].close()  # the board goes away ...
        thread.join(5)  # ... and the reader is back as soon as the server takes it again
        wait_for(lambda: reader.reconnects == 1 and reader.state == "connected", what="reconnection")
        accepted[1].sendall(encode_binary(0, values(7)))
        wait_for(lambda: reader.stats.received == 6, what="a frame after reconnecting")
        assert reader.stats.lost == 0 and reader.failures == 0
    finally:
        reader.stop()
        for connection in accepted:
            connection.close()
        server.close()


@pytest.mark.parametrize("after", ["another board", "the same board"])
def test_a_reconnection_reaches_only_the_device_it_started_with(pty, make_reader, tmp_path, monkeypatch, after):
    from tactile_viewer.sources import serial_reader
    from tactile_viewer.sources.device import DeviceIdentity

    first = DeviceIdentity(serial_number="85735313", vid=0x2341, pid=0x0043, description="Arduino Uno")
    other = DeviceIdentity(serial_number="11111111", vid=0x2341, pid=0x0043, description="Arduino Uno")
    present = [first]
    monkeypatch.setattr(serial_reader, "identify", lambda url: present[0])
    reader = make_reader(reconnect_interval=0.02)
    reader.start()
    recorder = reader.start_recording(tmp_path / "one.mcap", flush_interval=0.0)
    write_all(pty[0], b"".join(encode_binary(s, values(s)) for s in range(3)))
    wait_for(lambda: reader.stats.received == 3, what="three frames")
    assert reader.same_device_known and reader.device.notice == ""
    present[0] = other if after == "another board" else first
    reader._close, close = (lambda port: None), reader._close  # the next read fails as if unplugged
    original_read = reader._read
    dropped = []

    def unplugged(port):
        if not dropped:
            dropped.append(True)
            close(port)
            raise serial.SerialException("device reports readiness to read but returned no data")
        return original_read(port)
    reader._read = unplugged
    if after == "another board":
        wait_for(lambda: "not reconnecting" in reader.error, what="the refusal")
        assert "85735313" in reader.error and "11111111" in reader.error and reader.state == "reconnecting"
        assert reader.recorder is recorder  # the recording waits for its own device
    else:
        wait_for(lambda: reader.reconnects == 1 and reader.state == "connected", what="reconnection")
        assert reader.recorder is recorder  # the same board: the recording goes on



def test_a_read_only_target_is_refused_and_the_reader_goes_on(pty, make_reader, tmp_path, monkeypatch):
    import errno

    from tactile_viewer.io import mcap_writer as container

    def read_only(name, mode, **options):
        if "w" in mode:  # a folder turned read-only (root ignores chmod, so the refusal is injected)
            raise PermissionError(errno.EACCES, "Permission denied", str(name))
        return open(name, mode, **options)
    monkeypatch.setattr(container, "open", read_only, raising=False)
    reader = make_reader()
    reader.start()
    with pytest.raises(PermissionError, match="Permission denied"):
        reader.start_recording(tmp_path / "locked" / "take.mcap")
    assert reader.recorder is None
    write_all(pty[0], b"".join(encode_binary(s, values(s)) for s in range(5)))
    wait_for(lambda: reader.stats.received == 5, what="frames after the refusal")
    assert reader.state == "connected" and reader.failures == 0


def test_a_tare_taken_while_recording_is_recorded_from_its_frame_and_a_loaded_one_warns(pty, make_reader,
                                                                                       tmp_path):
    reader = make_reader()
    messages = []
    reader.message.connect(lambda *m: messages.append(m))
    reader.start()
    recorder = reader.start_recording(tmp_path / "tared.mcap", flush_interval=0.05)
    write_all(pty[0], b"".join(encode_binary(s, values(0)) for s in range(10)))
    wait_for(lambda: reader.stats.received == 10, what="ten frames")
    reader.calibration.tare(5)
    loaded = values(0) + np.where(np.arange(6) == 2, 50.0, 0.0)  # a press on taxel 2 while taring
    rng = np.random.default_rng(3)  # fixed seed: the noise of the tared frames
    write_all(pty[0], b"".join(encode_binary(s, loaded + rng.normal(0, 0.01, 6)) for s in range(10, 20)))
    wait_for(lambda: reader.published == 20, what="twenty frames handed to the recorder")
    path = reader.stop_recording()
    saved = files.load(path)
    [tare] = saved.calibration.tares
    assert tare.from_frame == 14 and tare.frames == 5 and recorder.added == 20  # the frame completing it
    np.testing.assert_allclose(saved.frames[:10], np.tile(values(0), (10, 1)) * 1e3, rtol=1e-6)
    assert np.all(saved.frames[10:14, 2] > 50e3)  # pressed and not yet tared
    np.testing.assert_allclose(saved.frames[14:].mean(axis=0), 0, atol=20)  # tared from there on
    (level, title, text), = [m for m in messages if m[0] == "warning"]
    assert title == "Tare taken under load?" and "taxel 2 stood" in text


# -- reconnecting only to the same device (tactile_viewer/sources/device.py), on loop:// --------------------------

UNO = DeviceIdentity("85735313233351F0E1D1", 0x2341, 0x0043, "Arduino Uno", "1-1.2:1.0")
OTHER = DeviceIdentity("95530343834351D0D1A1", 0x2341, 0x0043, "Arduino Uno", "1-1.2:1.0")


@pytest.fixture
def board(monkeypatch):
    """A SerialReader on loop:// with the device identity the test says is there now.

    ``board.identities`` is what identify() answers, one per call (the last repeats; None: unknown, as for
    loop:// itself); ``board.ports`` every connection the reader opened (refused ones too), to write a
    board's bytes into and to close as an unplugged board would; ``board.messages`` what the reader said.
    """
    made = []

    class Board:
        def __init__(self):
            self.identities, self.ports, self.messages, self.asked = [None], [], [], 0

        def identify(self, url):
            assert url == "loop://"
            self.asked += 1
            return self.identities.pop(0) if len(self.identities) > 1 else self.identities[0]

        def reader(self):
            reader = SerialReader("loop://", SensorLayout(grid32(), "kPa"), reconnect_interval=0.01)
            reader.message.connect(lambda *m: self.messages.append(m))
            made.append(reader)
            return reader

        def send(self, seqs):
            self.ports[-1].write(b"".join(encode_binary(s, values(s)) for s in seqs))

    fake = Board()
    serial_for_url = serial.serial_for_url

    def open_and_keep(*args, **kwargs):
        port = serial_for_url(*args, **kwargs)
        fake.ports.append(port)
        return port

    monkeypatch.setattr(serial_reader, "identify", fake.identify)
    monkeypatch.setattr(serial, "serial_for_url", open_and_keep)
    yield fake
    for reader in made:
        reader.stop()


def unplug(board, reader):
    """Close the port under the reader, as a board unplugged: the reader loses the connection."""
    board.ports[-1].close()
    wait_for(lambda: reader.state == "reconnecting" or reader.reconnects, what="the loss noticed")


def test_another_device_is_refused_unopened_until_the_first_comes_back(board, tmp_path):
    board.identities = [UNO]
    reader = board.reader()
    reader.start()
    reader.start_recording(tmp_path / "rec.mcap", flush_interval=0.0)
    board.send(range(2))
    wait_for(lambda: reader.stats.received == 2, what="two frames")
    board.identities = [OTHER]  # another board at the same path
    unplug(board, reader)
    asked = board.asked
    wait_for(lambda: board.asked > asked + 3, what="the reader retrying")  # refused, and tried again later
    assert reader.state == "reconnecting" and reader.reconnects == 0
    assert len(board.ports) == 1  # the other board was never opened (opening resets many boards)
    assert reader.error == ("not reconnecting loop://: this connection started with "
                            "USB VID:PID 2341:0043 serial 85735313233351F0E1D1 (Arduino Uno), and the device "
                            "there now is USB VID:PID 2341:0043 serial 95530343834351D0D1A1 (Arduino Uno); "
                            + SAME_DEVICE_RULE)
    board.identities = [UNO]
    wait_for(lambda: reader.reconnects == 1 and reader.state == "connected", what="the first board back")
    assert reader.error == "" and len(board.ports) == 2
    board.send(range(2, 4))
    wait_for(lambda: reader.published == 4, what="the first board's frames handed on")
    path = reader.stop_recording()
    assert list(files.load(path).sequence()) == [0, 1, 2, 3]  # one device, one file
    assert board.messages == [("info", "recording saved", str(path))]


def test_a_device_changed_while_opening_is_closed_again(board):
    # checked before opening and again after: the port opened in between is closed, and retried later
    board.identities = [UNO, UNO, OTHER, UNO]  # first open; reopen: before (same), after (another), then same
    reader = board.reader()
    reader.start()
    unplug(board, reader)
    wait_for(lambda: reader.reconnects == 1 and reader.state == "connected", what="reconnection")
    assert len(board.ports) == 3 and not board.ports[1].is_open  # the refused one was closed
    assert board.ports[2].is_open


def test_a_known_device_is_not_replaced_by_one_without_identity(board):
    board.identities = [UNO]
    reader = board.reader()
    reader.start()
    board.identities = [None]  # gone, or something the OS gives no identity for
    unplug(board, reader)
    wait_for(lambda: reader.error.startswith("not reconnecting loop://"), what="the refusal")
    assert "started with USB VID:PID 2341:0043 serial 85735313233351F0E1D1 (Arduino Uno)" in reader.error
    assert "absent or gives no device identity" in reader.error
    assert reader.state == "reconnecting" and reader.reconnects == 0 and len(board.ports) == 1


def test_without_a_device_identity_a_reconnection_ends_the_recording(board, tmp_path):
    reader = board.reader()  # loop:// as it is: no identity
    reader.start()
    assert not reader.same_device_known
    assert reader.device.notice == ("device identity unknown for loop://: a reconnection may be another "
                                    "device; recordings end at a reconnection")
    reader.start_recording(tmp_path / "rec.mcap", flush_interval=0.0)
    states = []  # on the reader thread, as the state changes: (state, recording still running)
    reader.state_changed.connect(lambda: states.append((reader.state, reader.recorder is not None)))
    board.send(range(3))
    wait_for(lambda: reader.stats.received == 3, what="three frames")
    unplug(board, reader)
    wait_for(lambda: reader.reconnects == 1 and reader.state == "connected", what="reconnection")
    # ended before the state said "connected" (a recording started from then on is the new device's)
    assert states == [("reconnecting", True), ("connected", False)]
    board.send(range(3, 5))
    wait_for(lambda: reader.stats.received == 5, what="frames after reconnecting")
    path = tmp_path / "rec.mcap"
    assert list(files.load(path).sequence()) == [0, 1, 2]  # only the first connection's frames
    assert board.messages[0] == ("info", "recording saved", str(path))
    assert board.messages[1][:2] == ("warning", "Recording ended at a reconnection")
    assert board.messages[1][2].startswith("loop:// reconnected and cannot be identified as the same device")
    assert len(board.messages) == 2


def test_without_a_device_identity_a_reconnection_without_recording_says_nothing(board):
    reader = board.reader()
    reader.start()
    unplug(board, reader)
    wait_for(lambda: reader.reconnects == 1 and reader.state == "connected", what="reconnection")
    board.send(range(2))
    wait_for(lambda: reader.stats.received == 2, what="frames after reconnecting")
    assert board.messages == [] and reader.error == ""


# -- dropping what a port held before it was opened --------------------------------------------------

def test_draining_a_backlog_takes_what_is_there_and_stops_when_nothing_more_comes():
    class Port:  # a backlog in three pushes, then a board's frame 20 ms later
        def __init__(self):
            self.pushes, self.later = [b"x" * 4095, b"y" * 4095, b"z" * 100], time.monotonic() + 0.02
            self.read_bytes = 0

        @property
        def in_waiting(self):
            return len(self.pushes[0]) if self.pushes else (80 if time.monotonic() > self.later else 0)

        def read(self, n):
            return self.pushes.pop(0) if self.pushes else b"f" * n

    from tactile_viewer.sources.serial_reader import drain_backlog

    port = Port()
    assert drain_backlog(port) == 4095 * 2 + 100  # the board's frame is left for the reader
    assert port.in_waiting == 0  # (it comes later)
