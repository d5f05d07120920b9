"""Which device answers at a serial URL, and whether a reappearing one is the same. No Qt.

A USB serial board that is unplugged and plugged back in (or resets) comes
back at the same path, but so does any other board plugged into that port,
or given that path by a udev rule. :func:`identify` asks the operating
system (pyserial's ``serial.tools.list_ports.comports()``) which device is
at a URL now, and :class:`DeviceCheck` is the policy a live reader applies
on each (re)open: reconnect only to the device it started with.

The rule for "the same device" (:meth:`DeviceIdentity.same_device`): the
same USB vendor and product id (VID:PID) and

* when either reports a USB serial number: the same serial number (a device
  does not lose or gain its serial number; serial numbers are unique only
  per VID:PID, hence both are compared);
* when neither does: the same description (the product string) and the
  same location (the USB bus and hub port). Such a device is therefore
  recognised only when it comes back in the same USB port, and two devices
  of one model without a serial number are the same device when one
  replaces the other in the same port: the OS cannot tell them apart.

Without any USB identity (pyserial URLs such as ``loop://``, ``socket://``,
``rfc2217://``; pseudo-terminals, including the simulator's; built-in
UARTs, whose description is only their name; ports the OS does not list)
the identity is unknown (None), and the reader can only say so: a
reconnection may then be another device, so recordings end at a
reconnection (:attr:`DeviceCheck.notice`).
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

__all__ = ["DeviceIdentity", "identify", "DeviceCheck", "unknown_identity_notice",
           "DeviceMismatch", "Verdict", "SAME_DEVICE_RULE", "announce_board", "announced_boards",
           "forget_board"]

SAME_DEVICE_RULE = ("the same device has the same USB VID:PID and serial number, or, when it has no serial "
                    "number, the same VID:PID, description and USB location")

_PLACEHOLDER = "n/a"  # pyserial's description and hwid when the OS gives none


def _given(text) -> bool:
    return isinstance(text, str) and text.strip() not in ("", _PLACEHOLDER)


def _hex4(number) -> str:
    return "????" if number is None else f"{number:04x}"


@dataclass(frozen=True)
class DeviceIdentity:
    """What the OS says about a serial device, as pyserial's ``ListPortInfo`` gives it.

    Equality of two identities (``==``) compares every field, the path and
    hwid included; whether they are the same *device* is
    :meth:`same_device`.

    Attributes
    ----------
    serial_number : str or None
        The USB serial number (None when the device has none; an empty one is
        kept as None).
    vid, pid : int or None
        USB vendor and product id.
    description : str or None
        pyserial's description: for USB, the product string (and interface).
    location : str or None
        Where it is plugged in, e.g. ``"1-1.2:1.0"`` (bus, hub ports, interface).
    hwid : str or None
        pyserial's one-line summary (``"USB VID:PID=2341:0043 SER=... LOCATION=..."``).
    device : str or None
        The port's path as the OS lists it (``/dev/ttyACM0``, ``COM3``).
    """

    serial_number: str | None = None
    vid: int | None = None
    pid: int | None = None
    description: str | None = None
    location: str | None = None
    hwid: str | None = None
    device: str | None = None

    @classmethod
    def from_port(cls, port) -> DeviceIdentity:
        """The identity in a ``ListPortInfo`` (or any object with its attributes; missing ones are None)."""
        serial_number = getattr(port, "serial_number", None)
        return cls(serial_number=serial_number if _given(serial_number) else None,
                   vid=getattr(port, "vid", None), pid=getattr(port, "pid", None),
                   description=getattr(port, "description", None), location=getattr(port, "location", None),
                   hwid=getattr(port, "hwid", None), device=getattr(port, "device", None))

    @property
    def usb(self) -> bool:
        """Whether the OS gave a USB identity (a vendor/product id or a serial number)."""
        return self.vid is not None or self.pid is not None or _given(self.serial_number)

    @property
    def label(self) -> str:
        """For people: ``"USB VID:PID 2341:0043 serial 85735313233351F0E1D1 (Arduino Uno)"``.

        Without a serial number the location takes its place (``"... at 1-1.2:1.0 (USB Serial)"``);
        without a USB identity, the device path.
        """
        parts = []
        if self.vid is not None or self.pid is not None:
            parts.append(f"USB VID:PID {_hex4(self.vid)}:{_hex4(self.pid)}")
        if _given(self.serial_number):
            parts.append(f"serial {self.serial_number}")
        elif _given(self.location):
            parts.append(f"at {self.location}")
        text = " ".join(parts) or (self.device or "a serial device without identity")
        if _given(self.description):
            text += f" ({self.description})"
        return text

    def same_device(self, other: DeviceIdentity) -> bool:
        """Whether ``other`` is this device by the module's rule (:data:`SAME_DEVICE_RULE`).

        Parameters
        ----------
        other : DeviceIdentity

        Raises
        ------
        TypeError
            When ``other`` is not a DeviceIdentity (None included: an unknown
            identity is never the same device).
        """
        if not isinstance(other, DeviceIdentity):
            raise TypeError(f"same_device compares two DeviceIdentity, got {type(other).__name__}: {other!r}")
        if (self.vid, self.pid) != (other.vid, other.pid):
            return False
        mine = self.serial_number if _given(self.serial_number) else None
        theirs = other.serial_number if _given(other.serial_number) else None
        if mine is not None or theirs is not None:
            return mine == theirs
        return (self.description, self.location) == (other.description, other.location)


def _is_url(url: str) -> bool:
    # pyserial's serial_for_url treats anything with "://" as a URL (loop://, socket://, rfc2217://,
    # hwgrep://, spy://, alt://): no path to look up; hwgrep:// picks a port by pattern, anew each time
    return "://" in url


def _key(path: str) -> str:
    return os.path.normcase(os.path.realpath(path))


def identify(url: str) -> DeviceIdentity | None:
    """The device at ``url`` now, as the OS lists it; None when the OS gives no identity.

    A device path is resolved first (``os.path.realpath``: a udev
    ``/dev/serial/by-id/...`` link or the simulator's ``--link`` symlink
    leads to the tty it points at) and looked up among
    ``serial.tools.list_ports.comports()``.

    Parameters
    ----------
    url : str
        A device path or a pyserial URL, as given to ``serial_for_url``.

    Returns
    -------
    DeviceIdentity or None
        None for pyserial URLs (``loop://``, ``socket://...``,
        ``rfc2217://...``), for paths the OS does not list (pseudo-terminals,
        a device that is gone), for ports without a USB identity (built-in
        UARTs), and when the ports cannot be listed (an OSError from the OS).

    Raises
    ------
    ValueError
        When ``url`` is not a non-empty string.
    """
    if not isinstance(url, str) or not url:
        raise ValueError(f"url must be a device path or a pyserial URL (a non-empty string), got {url!r}")
    if _is_url(url):
        return None
    from serial.tools import list_ports  # pyserial; imported here as the reader imports serial

    try:
        ports = list_ports.comports()
    except OSError:
        return None  # the OS could not say which ports there are: no identity to go by
    target = _key(url)
    for port in ports:
        device = getattr(port, "device", None)
        if isinstance(device, str) and device and _key(device) == target:
            identity = DeviceIdentity.from_port(port)
            return identity if identity.usb else None
    return None


def unknown_identity_notice(url: str) -> str:
    """What a port without device identity means for a live session, in one sentence."""
    return (f"device identity unknown for {url}: a reconnection may be another device; "
            "recordings end at a reconnection")


class Verdict(NamedTuple):
    """:meth:`DeviceCheck.verify`'s answer: reconnect or not, and why (``""``: nothing to say)."""

    ok: bool
    reason: str


class DeviceMismatch(ValueError):
    """A reconnection refused by :meth:`DeviceCheck.require`: the message names both devices and the rule."""


class DeviceCheck:
    """Reconnect only to the device a connection started with: the policy a live reader applies on each open.

    The reader calls :meth:`first` with the identity found on its first open
    and :meth:`verify` (or :meth:`require`) on every reopen. A known device
    is reconnected only when the same device is back (:data:`SAME_DEVICE_RULE`);
    a different one, or one without identity, is refused, with a reason
    naming both. When the first identity is unknown every reconnection is
    let through, and :attr:`notice` says what that means: the reader must
    end its recording at a reconnection, so that two devices never share a
    file.

    Parameters
    ----------
    url : str
        The URL the reader connects to (named in every sentence).

    Attributes
    ----------
    identity : DeviceIdentity or None
        The identity of the first open (None: unknown, or :meth:`first` not called yet).
    """

    def __init__(self, url: str):
        if not isinstance(url, str) or not url:
            raise ValueError(f"url must be a device path or a pyserial URL (a non-empty string), got {url!r}")
        self.url = url
        self.identity: DeviceIdentity | None = None
        self._started = False

    def first(self, identity: DeviceIdentity | None) -> None:
        """Record the identity found on the first open (None: the OS gave none).

        Raises
        ------
        TypeError
            When ``identity`` is neither a DeviceIdentity nor None.
        RuntimeError
            When the first identity was already recorded (a connection has one first device).
        """
        _check_identity(identity, "first")
        if self._started:
            raise RuntimeError(f"{self.url}: the first device is already recorded "
                               f"({self._describe(self.identity)}); first() is called once, on the first "
                               f"open")
        self.identity, self._started = identity, True

    @property
    def started(self) -> bool:
        """Whether :meth:`first` was called."""
        return self._started

    @property
    def known(self) -> bool:
        """Whether the first device's identity is known (False until :meth:`first` records one)."""
        return self.identity is not None

    @property
    def notice(self) -> str:
        """For the live panel: a sentence when the identity is unknown (``""`` when known or not started)."""
        if not self._started or self.known:
            return ""
        return unknown_identity_notice(self.url)

    def verify(self, identity: DeviceIdentity | None) -> Verdict:
        """Whether to reconnect to the device found at the URL now.

        Parameters
        ----------
        identity : DeviceIdentity or None
            What :func:`identify` found now (None: no identity, or no device).

        Returns
        -------
        Verdict
            ``(True, "")`` for the same device; ``(True, notice)`` when the
            first identity is unknown (whatever is there now);
            ``(False, reason)`` for another device or, after a known one, a
            device without identity.

        Raises
        ------
        TypeError
            When ``identity`` is neither a DeviceIdentity nor None.
        RuntimeError
            Before :meth:`first`.
        """
        _check_identity(identity, "verify")
        if not self._started:
            raise RuntimeError(f"{self.url}: verify() needs the first device's identity: call first() on "
                               f"the first open")
        first = self.identity
        if first is None:
            return Verdict(True, self.notice)
        if identity is None:
            return Verdict(False, f"not reconnecting {self.url}: this connection started with {first.label}, "
                                  f"and the port now is absent or gives no device identity; "
                                  f"{SAME_DEVICE_RULE}")
        if not first.same_device(identity):
            return Verdict(False, f"not reconnecting {self.url}: this connection started with {first.label}, "
                                  f"and the device there now is {identity.label}; {SAME_DEVICE_RULE}")
        return Verdict(True, "")

    def require(self, identity: DeviceIdentity | None) -> None:
        """:meth:`verify`, raising :class:`DeviceMismatch` with the reason when it refuses."""
        ok, reason = self.verify(identity)
        if not ok:
            raise DeviceMismatch(reason)

    def _describe(self, identity: DeviceIdentity | None) -> str:
        return identity.label if identity is not None else "identity unknown"


def _check_identity(identity, method: str) -> None:
    if identity is not None and not isinstance(identity, DeviceIdentity):
        raise TypeError(f"{method}() takes a DeviceIdentity or None (unknown), "
                        f"got {type(identity).__name__}: {identity!r}")


# -- simulated boards running on this machine ---------------------------------------------------------
# A pseudo-terminal is in no list of serial ports, and tactile-sim's links can be anywhere: each
# running tactile-sim leaves a small note (its device, link, layout file, format) where the Connect
# dialog looks, and takes it away when it ends. A note whose process is gone is ignored.


def _boards_folder() -> Path:
    chosen = os.environ.get("TACTILE_VIEWER_CONFIG")  # the settings folder, when one is chosen
    if chosen:
        return Path(chosen) / "boards"
    runtime = os.environ.get("XDG_RUNTIME_DIR") or tempfile.gettempdir()
    return Path(runtime) / f"tactile-sim-{os.getuid()}"


def announce_board(**facts) -> Path | None:
    """Note a simulated board as running (its ``device``, ``link``, ``layout``, ``format``, ``scene``).

    Returns the note's path (remove it when the board stops), or None when it could not be
    written (the board runs all the same; only the Connect dialog's list misses it).
    """
    folder = _boards_folder()
    note = folder / f"sim-{os.getpid()}.json"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        note.write_text(json.dumps({**facts, "pid": os.getpid()}))
    except OSError:
        return None
    return note


def announced_boards() -> list[dict]:
    """The notes of the simulated boards running now (their process alive, their device there)."""
    boards = []
    for note in sorted(_boards_folder().glob("sim-*.json")):
        try:
            facts = json.loads(note.read_text())
            os.kill(int(facts["pid"]), 0)  # raises when the process is gone
        except (OSError, ValueError, KeyError, TypeError, RecursionError):
            continue
        if isinstance(facts.get("device"), str) and os.path.exists(facts["device"]):
            boards.append(facts)
    return boards


def forget_board(note: Path | None) -> None:
    """Remove a note made by :func:`announce_board` (the board stopped)."""
    if note is not None:
        with contextlib.suppress(OSError):
            note.unlink()
