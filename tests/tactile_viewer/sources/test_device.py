"""Device identity (tactile_viewer/sources/device.py): which device is at a serial URL, and reconnecting only to the
same one. The OS's port list (pyserial's comports()) is replaced by fake ports."""

import os
import tty

import pytest
from serial.tools import list_ports, list_ports_common

from tactile_viewer.sources.device import (
    SAME_DEVICE_RULE,
    DeviceCheck,
    DeviceIdentity,
    DeviceMismatch,
    Verdict,
    identify,
)


class FakePort:
    """What pyserial's ListPortInfo offers (device, serial_number, vid, pid, description, location, hwid)."""

    def __init__(self, device, serial_number=None, vid=None, pid=None, description="n/a", location=None,
                 hwid="n/a"):
        self.device, self.serial_number, self.vid, self.pid = device, serial_number, vid, pid
        self.description, self.location, self.hwid = description, location, hwid


def uno(device, serial_number="85735313233351F0E1D1", location="1-1.2:1.0"):
    return FakePort(device, serial_number, 0x2341, 0x0043, "Arduino Uno", location,
                    f"USB VID:PID=2341:0043 SER={serial_number} LOCATION={location}")


def ch340(device, location="1-1.3:1.0"):
    return FakePort(device, None, 0x1A86, 0x7523, "USB Serial", location, f"USB VID:PID=1A86:7523 LOCATION={location}")


class PortList(list):
    """The ports the OS lists (a test fills and changes it as boards come and go); ``calls`` counts the listings."""

    calls: list


@pytest.fixture
def ports(monkeypatch):
    listed = PortList()
    listed.calls = []

    def comports(include_links=False):
        listed.calls.append(include_links)
        return list(listed)

    monkeypatch.setattr(list_ports, "comports", comports)
    return listed


UNO = DeviceIdentity.from_port(uno("/dev/ttyACM0"))
OTHER_UNO = DeviceIdentity.from_port(uno("/dev/ttyACM0", serial_number="95530343834351D0D1A1"))


# -- DeviceIdentity ---------------------------------------------------------------------------------------

def test_label_names_vid_pid_serial_and_description():
    assert UNO.label == "USB VID:PID 2341:0043 serial 85735313233351F0E1D1 (Arduino Uno)"


def test_label_without_a_serial_number_names_the_location():
    assert DeviceIdentity.from_port(ch340("/dev/ttyUSB0")).label == "USB VID:PID 1a86:7523 at 1-1.3:1.0 (USB Serial)"


def test_label_without_usb_identity_names_the_path_and_skips_placeholders():
    assert DeviceIdentity.from_port(FakePort("/dev/ttyS0")).label == "/dev/ttyS0"
    assert DeviceIdentity().label == "a serial device without identity"
    assert DeviceIdentity(vid=0x0403).label == "USB VID:PID 0403:????"


def test_from_a_real_list_port_info():
    # pyserial's own class, filled as its Linux lister does for a USB device
    info = list_ports_common.ListPortInfo("/dev/ttyACM3", skip_link_detection=True)
    info.vid, info.pid, info.serial_number, info.location = 0x2341, 0x0043, "8573", "3-2:1.0"
    info.product = "Arduino Uno"
    info.apply_usb_info()
    identity = DeviceIdentity.from_port(info)
    assert identity == DeviceIdentity("8573", 0x2341, 0x0043, "Arduino Uno", "3-2:1.0",
                                      "USB VID:PID=2341:0043 SER=8573 LOCATION=3-2:1.0", "/dev/ttyACM3")
    assert identity.usb


@pytest.mark.parametrize("serial_number", ["", "   ", "n/a"])
def test_an_empty_serial_number_is_none(serial_number):
    identity = DeviceIdentity.from_port(uno("/dev/ttyACM0", serial_number=serial_number))
    assert identity.serial_number is None
    assert "serial" not in identity.label and "at 1-1.2:1.0" in identity.label


SAME_DEVICE_CASES = [
    # (first, now, same?, why)
    (uno("/dev/ttyACM0"), uno("/dev/ttyACM1", location="2-4:1.0"), True,
     "same VID:PID and serial: replugged elsewhere, another tty name, still the same board"),
    (uno("/dev/ttyACM0"), uno("/dev/ttyACM0", serial_number="95530343834351D0D1A1"), False,
     "another serial number in the same port"),
    (uno("/dev/ttyACM0"), uno("/dev/ttyACM0", serial_number=None), False,
     "a serial number does not disappear: a board without one in the same port is another board"),
    (uno("/dev/ttyACM0", serial_number=None), uno("/dev/ttyACM0"), False, "nor appear"),
    (uno("/dev/ttyACM0"), FakePort("/dev/ttyACM0", "85735313233351F0E1D1", 0x2341, 0x0001, "Arduino Mega",
                                   "1-1.2:1.0"), False,
     "serial numbers are unique per VID:PID only: the same serial on another product is another device"),
    (ch340("/dev/ttyUSB0"), ch340("/dev/ttyUSB1"), True, "no serial: same VID:PID, description, location"),
    (ch340("/dev/ttyUSB0"), ch340("/dev/ttyUSB0", location="1-1.4:1.0"), False,
     "no serial: another USB port is another device"),
    (ch340("/dev/ttyUSB0"), FakePort("/dev/ttyUSB0", None, 0x1A86, 0x7523, "USB2.0-Serial", "1-1.3:1.0"), False,
     "no serial: another description"),
    (ch340("/dev/ttyUSB0"), FakePort("/dev/ttyUSB0", None, 0x0403, 0x6001, "USB Serial", "1-1.3:1.0"), False,
     "no serial: another VID:PID"),
]


@pytest.mark.parametrize("first, now, same, why", SAME_DEVICE_CASES, ids=[case[3] for case in SAME_DEVICE_CASES])
def test_the_same_device_rule(first, now, same, why):
    a, b = DeviceIdentity.from_port(first), DeviceIdentity.from_port(now)
    assert a.same_device(b) is same, why
    assert b.same_device(a) is same  # symmetric


@pytest.mark.parametrize("other", [None, "85735313233351F0E1D1", uno("/dev/ttyACM0")])
def test_same_device_compares_identities_only(other):
    with pytest.raises(TypeError, match=r"same_device compares two DeviceIdentity, got (NoneType|str|FakePort)"):
        UNO.same_device(other)


# -- identify ---------------------------------------------------------------------------------------------

def test_identify_finds_the_listed_port(ports, tmp_path):
    device = tmp_path / "ttyACM0"
    device.touch()
    ports.extend([ch340(str(tmp_path / "ttyUSB0")), uno(str(device))])
    assert identify(str(device)) == DeviceIdentity.from_port(uno(str(device)))


def test_identify_follows_a_symlink_to_the_tty(ports, tmp_path):
    # a udev by-id link, or the simulator's --link: the path given points at the tty the OS lists
    device = tmp_path / "ttyACM0"
    device.touch()
    by_id = tmp_path / "serial" / "by-id"
    by_id.mkdir(parents=True)
    link = by_id / "usb-Arduino_Uno_85735313233351F0E1D1-if00"
    link.symlink_to(os.path.join("..", "..", "ttyACM0"))  # relative, as udev makes them
    board = tmp_path / "board"
    board.symlink_to(link)  # and a link to the link
    ports.append(uno(str(device)))
    assert identify(str(link)) == identify(str(board)) == DeviceIdentity.from_port(uno(str(device)))
    # the board comes back as ttyACM1 and the link follows it
    device.unlink()
    (tmp_path / "ttyACM1").touch()
    link.unlink()
    link.symlink_to(os.path.join("..", "..", "ttyACM1"))
    ports[:] = [uno(str(tmp_path / "ttyACM1"))]
    assert identify(str(board)).device == str(tmp_path / "ttyACM1")
    assert identify(str(board)).same_device(UNO)


def test_identify_matches_a_port_listed_by_its_link(ports, tmp_path):
    # comports(include_links=True) lists links too: both sides are resolved
    device = tmp_path / "ttyUSB0"
    device.touch()
    (tmp_path / "alias").symlink_to(device)
    ports.append(ch340(str(tmp_path / "alias")))
    assert identify(str(device)).label == "USB VID:PID 1a86:7523 at 1-1.3:1.0 (USB Serial)"


@pytest.mark.parametrize("url", ["loop://", "LOOP://", "socket://127.0.0.1:7777", "rfc2217://lab:2217",
                                 "hwgrep://2341:0043", "spy:///dev/ttyACM0"])
def test_pyserial_urls_have_no_identity_and_do_not_list_ports(url, ports):
    assert identify(url) is None
    assert ports.calls == []


def test_a_pseudo_terminal_has_no_identity():
    # the real port list: a pty (what the simulator makes) is never a listed serial port
    master, slave = os.openpty()
    try:
        tty.setraw(slave)
        assert identify(os.ttyname(slave)) is None
    finally:
        os.close(master)
        os.close(slave)


def test_a_link_to_a_pseudo_terminal_has_no_identity(tmp_path):
    master, slave = os.openpty()
    try:
        link = tmp_path / "board"
        link.symlink_to(os.ttyname(slave))  # as tactile-sim --link does
        assert identify(str(link)) is None
    finally:
        os.close(master)
        os.close(slave)


def test_an_unlisted_path_has_no_identity(ports, tmp_path):
    ports.append(uno(str(tmp_path / "ttyACM0")))
    assert identify(str(tmp_path / "ttyACM9")) is None
    assert identify(str(tmp_path / "gone")) is None  # a dangling link or no file at all
    assert ports.calls == [False, False]


def test_a_port_without_usb_identity_has_none(ports):
    # a built-in UART: pyserial gives its name as description and a bus id (or "n/a") as hwid, nothing
    # that tells what is wired to it
    ports.extend([FakePort("/dev/ttyS0", description="ttyS0", hwid="PNP0501"), FakePort("/dev/ttyAMA0")])
    assert identify("/dev/ttyS0") is None
    assert identify("/dev/ttyAMA0") is None


def test_a_serial_number_alone_is_an_identity(ports):
    ports.append(FakePort("/dev/ttyACM0", serial_number="ABC123"))
    assert identify("/dev/ttyACM0") == DeviceIdentity.from_port(ports[0])
    assert identify("/dev/ttyACM0").label == "serial ABC123"


def test_when_the_ports_cannot_be_listed_the_identity_is_unknown(monkeypatch):
    def comports(include_links=False):
        raise PermissionError(13, "Permission denied", "/sys/class/tty")

    monkeypatch.setattr(list_ports, "comports", comports)
    assert identify("/dev/ttyACM0") is None


def test_other_errors_from_the_port_list_are_not_hidden(monkeypatch):
    def comports(include_links=False):
        raise RuntimeError("a bug in the lister")

    monkeypatch.setattr(list_ports, "comports", comports)
    with pytest.raises(RuntimeError, match="a bug in the lister"):
        identify("/dev/ttyACM0")


@pytest.mark.parametrize("url", ["", None, 3, b"/dev/ttyACM0"])
def test_identify_needs_a_url(url):
    with pytest.raises(ValueError, match=r"url must be a device path or a pyserial URL \(a non-empty string\), got "):
        identify(url)


# -- DeviceCheck ------------------------------------------------------------------------------------------

def test_the_same_device_reconnects():
    check = DeviceCheck("/dev/serial/by-id/usb-Arduino")
    check.first(UNO)
    assert check.known and check.started and check.identity == UNO and check.notice == ""
    moved = DeviceIdentity.from_port(uno("/dev/ttyACM1", location="2-4:1.0"))
    assert check.verify(moved) == Verdict(True, "")
    assert check.verify(UNO) == (True, "")
    check.require(moved)  # does not raise


def test_another_device_is_refused_naming_both():
    check = DeviceCheck("/dev/ttyACM0")
    check.first(UNO)
    ok, reason = check.verify(OTHER_UNO)
    assert not ok
    assert reason == ("not reconnecting /dev/ttyACM0: this connection started with "
                      "USB VID:PID 2341:0043 serial 85735313233351F0E1D1 (Arduino Uno), and the device there now is "
                      "USB VID:PID 2341:0043 serial 95530343834351D0D1A1 (Arduino Uno); " + SAME_DEVICE_RULE)
    with pytest.raises(DeviceMismatch) as info:
        check.require(OTHER_UNO)
    assert str(info.value) == reason
    assert isinstance(info.value, ValueError)  # what a live reader's reconnection loop retries on
    assert check.identity == UNO  # a refusal changes nothing: the first device is still the one expected


def test_a_known_device_is_not_replaced_by_one_without_identity():
    check = DeviceCheck("/dev/ttyACM0")
    check.first(UNO)
    ok, reason = check.verify(None)
    assert not ok
    assert reason.startswith("not reconnecting /dev/ttyACM0: this connection started with "
                             "USB VID:PID 2341:0043 serial 85735313233351F0E1D1 (Arduino Uno), and the port now "
                             "is absent or gives no device identity; ")
    assert reason.endswith(SAME_DEVICE_RULE)
    with pytest.raises(DeviceMismatch, match="absent or gives no device identity"):
        check.require(None)


def test_an_unknown_first_identity_says_so_and_lets_reconnections_through():
    check = DeviceCheck("loop://")
    assert check.notice == "" and not check.known and not check.started  # nothing to say before the first open
    check.first(None)
    assert check.started and not check.known
    sentence = ("device identity unknown for loop://: a reconnection may be another device; "
                "recordings end at a reconnection")
    assert check.notice == sentence
    assert check.verify(None) == (True, sentence)
    assert check.verify(UNO) == (True, sentence)  # known later changes nothing: the first cannot be compared
    check.require(OTHER_UNO)  # does not raise
    assert not check.known


def test_verify_needs_the_first_identity():
    check = DeviceCheck("/dev/ttyACM0")
    with pytest.raises(RuntimeError, match=r"/dev/ttyACM0: verify\(\) needs the first device's identity"):
        check.verify(UNO)
    with pytest.raises(RuntimeError, match="verify"):
        check.require(None)


@pytest.mark.parametrize("first, described", [(UNO, UNO.label), (None, "identity unknown")])
def test_the_first_identity_is_recorded_once(first, described):
    check = DeviceCheck("/dev/ttyACM0")
    check.first(first)
    with pytest.raises(RuntimeError) as info:
        check.first(OTHER_UNO)
    assert str(info.value) == (f"/dev/ttyACM0: the first device is already recorded ({described}); "
                               f"first() is called once, on the first open")
    assert check.identity == first


@pytest.mark.parametrize("method", ["first", "verify", "require"])
@pytest.mark.parametrize("identity", ["85735313233351F0E1D1", uno("/dev/ttyACM0")])
def test_identities_must_be_device_identities(method, identity):
    check = DeviceCheck("/dev/ttyACM0")
    if method != "first":
        check.first(UNO)
    with pytest.raises(TypeError, match=rf"{method if method != 'require' else 'verify'}\(\) takes a DeviceIdentity "
                                        rf"or None \(unknown\), got (str|FakePort)"):
        getattr(check, method)(identity)


@pytest.mark.parametrize("url", ["", None, 0])
def test_a_check_needs_a_url(url):
    with pytest.raises(ValueError, match="url must be a device path or a pyserial URL"):
        DeviceCheck(url)


def test_a_board_unplugged_and_another_plugged_in_at_the_same_link(ports, tmp_path):
    # the whole story at one stable path: identify + DeviceCheck as a reader uses them on each open
    def plug(name, port):
        (tmp_path / name).touch()
        link = tmp_path / "board"
        link.unlink(missing_ok=True)
        link.symlink_to(tmp_path / name)
        ports[:] = [port(str(tmp_path / name))]

    url = str(tmp_path / "board")
    plug("ttyACM0", uno)
    check = DeviceCheck(url)
    check.first(identify(url))
    assert check.known
    ports.clear()  # unplugged: the port is gone from the list
    assert not check.verify(identify(url)).ok
    plug("ttyUSB0", ch340)  # another board takes the path
    ok, reason = check.verify(identify(url))
    assert not ok and "serial 85735313233351F0E1D1 (Arduino Uno)" in reason
    assert "USB VID:PID 1a86:7523 at 1-1.3:1.0 (USB Serial)" in reason
    plug("ttyACM1", uno)  # the first board is back, under another tty name
    assert check.verify(identify(url)) == (True, "")
