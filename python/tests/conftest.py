"""Test equipment: the soft slave on an SLCAN pseudo-terminal pair, as tests/pty-rig sets it up.

Two socat pty pairs: the simulated breaker (dnet-sim-breaker) on one end of the serial pair,
dnet-soft-slave between the other end and the CAN pair (SLCAN), the master at the CAN pair's far
end. The programs are taken from DNET_BIN_DIR (python/run-tests sets it).
"""

import os
import re
import subprocess
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _bin(name: str) -> str:
    folder = os.environ.get("DNET_BIN_DIR")
    if not folder:
        pytest.fail("DNET_BIN_DIR is not set: run python/run-tests")
    path = Path(folder) / name
    if not path.is_file():
        pytest.fail(f"{path} is not built: cargo build -p soft-slave")
    return str(path)


class _Proc:
    """A child process, its stderr in a file of the scratch folder, stopped by SIGTERM."""

    def __init__(self, args, log: Path):
        self.log = log
        self._err = open(log, "wb")
        self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=self._err)

    def text(self) -> str:
        return self.log.read_text(errors="replace")

    def wait_for(self, needle: str, seconds: float) -> bool:
        end = time.monotonic() + seconds
        while needle not in self.text():
            if time.monotonic() > end or self.proc.poll() is not None:
                return needle in self.text()
            time.sleep(0.01)
        return True

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._err.close()


def _pty_pair(tmp: Path, name: str):
    """socat joining two ptys (raw, no echo); returns the process and the two paths."""
    p = _Proc(["socat", "-d", "-d", "pty,raw,echo=0", "pty,raw,echo=0"], tmp / f"{name}.log")
    if not p.wait_for("starting data transfer loop", 5):
        p.stop()
        pytest.fail(f"socat did not start:\n{p.text()}")
    ptys = re.findall(r"PTY is (\S+)", p.text())
    assert len(ptys) == 2, p.text()
    return p, ptys[0], ptys[1]


@pytest.fixture
def soft_slave(tmp_path):
    """The soft slave (the reference converter, MAC 5) on SLCAN; yields the master's bus string."""
    procs = []
    try:
        serial, serial_a, serial_b = _pty_pair(tmp_path, "socat-serial")
        procs.append(serial)
        can, can_a, can_b = _pty_pair(tmp_path, "socat-can")
        procs.append(can)
        breaker = _Proc([_bin("dnet-sim-breaker"), "--serial", serial_a], tmp_path / "breaker.log")
        procs.append(breaker)
        slave = _Proc(
            [_bin("dnet-soft-slave"), "--bus", f"slcan:{can_a}", "--serial", serial_b],
            tmp_path / "soft-slave.log",
        )
        procs.append(slave)
        # Ready once it reports its start (its bus open): a master before that would race it.
        if not slave.wait_for("started on", 10):
            pytest.fail(f"dnet-soft-slave did not start:\n{slave.text()}")
        yield f"slcan:{can_b}"
    finally:
        for p in reversed(procs):
            p.stop()
