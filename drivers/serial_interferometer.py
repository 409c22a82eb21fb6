"""A laser interferometer on a serial line, read with pyserial.

Stream mode: the instrument sends readings on its own; `poll()` takes whatever bytes are waiting
without blocking, returns the complete lines as readings and keeps a trailing partial line for the
next call. Query mode: `poll()` sends `fmt.request` and waits up to `timeout_s` for the answer.

Lines that are not valid readings (garbage, partial, bad checksum) are counted in `skipped_lines`
and never returned. Beam loss is not an error: it gives a reading with `signal_ok` False.
"""

from __future__ import annotations

import serial

from protocols.hardware import InstrumentError, Reading
from protocols.serial_line import LineError, LineFormat, parse_line

_TermiosError: type[Exception]
try:
    from termios import error as _TermiosError  # pyserial lets tcflush errors through on POSIX
except ImportError:  # Windows
    _TermiosError = OSError

_CHUNK_BYTES = 4096
_PORT_ERRORS = (OSError, serial.SerialException, _TermiosError)
MAX_LINE_BYTES = 1024
"""A longer run of bytes without a line end is dropped as one skipped line."""


class SerialInterferometer:
    """The Interferometer protocol over a serial port (a device path or a pyserial URL).

    baudrate: bit/s. timeout_s: how long a query waits for its answer, s.
    Raises InstrumentError when the port cannot be opened.
    """

    def __init__(
        self,
        port: str,
        baudrate: int = 115200,
        fmt: LineFormat | None = None,
        mode: str = "stream",
        timeout_s: float = 1.0,
    ):
        if mode not in ("stream", "query"):
            raise ValueError(f"mode must be 'stream' or 'query', not {mode!r}")
        self.fmt = fmt or LineFormat()
        self.mode = mode
        self.timeout_s = timeout_s
        self.skipped_lines = 0
        self._terminator = self.fmt.terminator.encode("ascii")
        self._buffer = b""
        try:
            read_timeout_s = 0 if mode == "stream" else timeout_s  # 0: never wait
            self._port = serial.serial_for_url(port, baudrate=baudrate, timeout=read_timeout_s)
        except (OSError, serial.SerialException) as e:
            raise InstrumentError(f"cannot open interferometer port {port}: {e}") from e
        self.port_name = port

    def poll(self) -> list[Reading]:
        """Stream mode: the readings that arrived since the last call (possibly none).
        Query mode: one fresh reading, or none when the answer was not a valid line.
        Raises InstrumentError when the port is gone or a query goes unanswered."""
        try:
            if self.mode == "stream":
                return self._poll_stream()
            return self._poll_query()
        except _PORT_ERRORS as e:
            raise InstrumentError(f"interferometer port {self.port_name} failed: {e}") from e

    def _poll_stream(self) -> list[Reading]:
        # until a read finds nothing: a pty hands over what was written in pieces, so a short read does
        # not mean the rest has not arrived (one read per poll lost readings to the next poll)
        while chunk := self._port.read(_CHUNK_BYTES):
            self._buffer += chunk
        *lines, self._buffer = self._buffer.split(self._terminator)
        if len(self._buffer) > MAX_LINE_BYTES:
            self._buffer = b""
            self.skipped_lines += 1
        return [reading for line in lines if (reading := self._parse(line)) is not None]

    def _poll_query(self) -> list[Reading]:
        self._port.reset_input_buffer()
        self._port.write(self.fmt.request.encode("ascii"))
        answer = self._port.read_until(self._terminator, MAX_LINE_BYTES)
        if len(answer) == MAX_LINE_BYTES and not answer.endswith(self._terminator):
            self.skipped_lines += 1
            return []
        if not answer.endswith(self._terminator):
            raise InstrumentError(
                f"interferometer on {self.port_name} did not answer within {self.timeout_s} s"
            )
        reading = self._parse(answer)
        return [] if reading is None else [reading]

    def _parse(self, line: bytes) -> Reading | None:
        """The reading on line, or None (counted as skipped unless the line is blank)."""
        if not line.strip(b"\r\n"):
            return None
        try:
            return parse_line(line.decode("latin-1"), self.fmt)
        except LineError:
            self.skipped_lines += 1
            return None

    def drain(self) -> None:
        """Discard every byte received and not yet returned, including a partial line."""
        self._buffer = b""
        try:
            self._port.reset_input_buffer()
        except _PORT_ERRORS as e:
            raise InstrumentError(f"interferometer port {self.port_name} failed: {e}") from e

    def close(self) -> None:
        """Release the port. Safe to call twice."""
        self._port.close()
