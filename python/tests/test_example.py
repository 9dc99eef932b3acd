"""The guide's example (python/examples/parameter_sweep.py), run as a user runs it, so that the
"Scripting" page cannot rot."""

import csv
import subprocess
import sys
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "parameter_sweep.py"


def run(tmp_path: Path, *args: str):
    out = tmp_path / "sweep.csv"
    p = subprocess.run([sys.executable, str(EXAMPLE), "--out", str(out), *args],
                       capture_output=True, text=True, timeout=60)
    rows = list(csv.DictReader(out.open())) if out.exists() else []
    return p, rows


def test_sweep_on_the_simulated_bus(tmp_path: Path):
    p, rows = run(tmp_path, "--values", "100,4000,65535")
    assert p.returncode == 0, p.stdout + p.stderr
    assert [(r["value"], r["read_back"], r["ok"]) for r in rows] == [
        ("100", "100", "True"), ("4000", "4000", "True"), ("65535", "65535", "True")]
    assert "3 value(s) swept, 0 not confirmed" in p.stdout


def test_sweep_reports_what_it_could_not_confirm(tmp_path: Path):
    # One poll is too few for the breaker to answer: nothing is confirmed, and the run says so.
    p, rows = run(tmp_path, "--values", "100,200", "--max-polls", "1")
    assert p.returncode == 1, p.stdout + p.stderr
    assert [r["ok"] for r in rows] == ["False", "False"]


def test_sweep_on_the_soft_slave(tmp_path: Path, soft_slave):
    p, rows = run(tmp_path, "--bus", soft_slave, "--parameter", "2", "--values", "1234,77")
    assert p.returncode == 0, p.stdout + p.stderr
    assert [(r["value"], r["read_back"]) for r in rows] == [("1234", "1234"), ("77", "77")]
