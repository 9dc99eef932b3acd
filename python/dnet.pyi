"""The bench DeviceNet master for test scripts.

A :class:`Master` on ``bus="sim"`` (the simulated bus with the reference device, or the devices
of ``slave_config``), ``"socketcan:IFACE"`` or ``"slcan:PATH[@SERIALBAUD]"``: the bring-up of a
device, explicit get/set, polled I/O, the network scan and the monitor, every frame checked;
:func:`decode` reads a trace of any common format. See the guide's "Scripting" page.
"""

from os import PathLike
from types import TracebackType
from typing import Any, Dict, Iterator, List, Optional, Sequence, Type, Union

_Bytes = Union[bytes, bytearray]
_Path = Union[str, "PathLike[str]"]

class Error(Exception):
    """Every error of the package that is not a usage error (``ValueError``/``TypeError``)."""

class DeviceError(Error):
    """The device answered with an error response."""

    general: int
    """The general status code (0x14: attribute not supported, ...)."""
    additional: int
    """The additional code (0xFF: none)."""
    general_name: Optional[str]
    """The general status by name, None when the code has none."""
    additional_name: Optional[str]
    """The additional code by name, None when the code has none."""
    mac: int
    """The device."""
    request: str
    """What was asked."""

class Timeout(Error):
    """Nothing arrived in time."""

    mac: int
    """The device."""
    waiting_for: str
    """What the master waited for."""
    timeout: str
    """The name of the timeout that expired."""

class Master:
    """A DeviceNet master on a bus; a context manager that releases everything on exit.

    Every call waits on the bus with the GIL released. ``slave_config`` (a device description
    file) and ``slave_macs`` choose the simulated devices (``bus="sim"`` only; default: the
    reference device at its MAC, 5). ``timeout`` is the explicit response timeout in seconds;
    ``log`` writes every frame to a candump -L file.
    """

    def __init__(
        self,
        bus: str = "sim",
        master_mac: int = 0,
        bitrate: str = "250k",
        *,
        slave_config: Optional[_Path] = None,
        slave_macs: Optional[Sequence[int]] = None,
        timeout: float = 1.0,
        log: Optional[_Path] = None,
    ) -> None: ...
    def __enter__(self) -> "Master": ...
    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> bool: ...
    def close(self) -> List[int]:
        """Releases every connection held and closes the bus; returns the MAC IDs released."""
    def connect(self, mac: int, io: str = "poll", *, epr: int = 100) -> Dict[str, Any]:
        """The bring-up of ``mac`` with the I/O connection ``io`` (poll, strobe, cos, cyclic).

        Returns ``{"ok", "failures", "device", "frames"}``: ``frames`` lists every frame with
        ``direction``, ``frame``, ``meaning``, ``verdict`` (sent, ok, fail, info) and ``notes``.
        """
    def get(self, mac: int, cls: int, inst: int, attr: int) -> bytes:
        """Get_Attribute_Single: the value's bytes. Raises DeviceError on an error response."""
    def set(self, mac: int, cls: int, inst: int, attr: int, value: _Bytes) -> bytes:
        """Set_Attribute_Single of ``value``: the response data (usually empty)."""
    def poll(self, mac: int, output: Optional[_Bytes] = None) -> bytes:
        """One I/O cycle on the connection connect() left: ``output`` out, the input image back."""
    def scan(self, first: int = 0, last: int = 63) -> List[Dict[str, Any]]:
        """The devices at MAC IDs first..=last, each with its identity, poll sizes and status."""
    def monitor(
        self,
        mac: int,
        *,
        io: str = "poll",
        epr: int = 100,
        count: Optional[int] = None,
        duration: Optional[float] = None,
        output: Optional[_Bytes] = None,
        description: Optional[_Path] = None,
    ) -> "MonitorIter":
        """Samples of ``mac``, one every EPR, decoded by the device's profile."""

class MonitorIter(Iterator[Dict[str, Any]]):
    """The samples of Master.monitor: ``time_us``, ``fields``, ``link``, ``stale``, ``raw``, and
    ``note`` when the data is not decoded although a description was given."""

    def __iter__(self) -> "MonitorIter": ...
    def __next__(self) -> Dict[str, Any]: ...

class DecodeIter(Iterator[Dict[str, Any]]):
    """The messages of a trace, decoded."""

    format: str
    """The trace's format (candump, pcap, pcapng, trc, asc, blf, csv)."""
    skipped: int
    """Lines or records that were not DeviceNet frames."""
    def __iter__(self) -> "DecodeIter": ...
    def __next__(self) -> Dict[str, Any]:
        """``line``, ``time_us``, ``iface``, ``direction``, ``id``, ``data``, ``frame``, ``kind``,
        ``group``, ``mac``, ``meaning``, ``message``, ``protocol_error``."""

def decode(
    source: Union[str, _Bytes], *, format: Optional[str] = None, strict: bool = False
) -> DecodeIter:
    """Decodes a trace (text or bytes; its format detected unless ``format`` names it)."""
