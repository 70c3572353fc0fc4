"""An existing scheduler named by ``--scheduler`` or ``--scheduler-file``: checked for its form
at once and for an answer before a Dask client exists, each refusal one line and exit 2, a
listener that accepts and never answers ended within the connect and answer timeouts.

The listeners are real sockets on 127.0.0.1; the silent one runs under a real ``twin sweep``
child process, so a traceback at its exit (a half-made Client's) would show on its stderr.
"""

from __future__ import annotations

import contextlib
import json
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.sweep.helpers import run_sweep_cli, write_spec
from twin.cli import main as twin
from twin.pipeline.cluster import SCHEDULER_ANSWER_S, SCHEDULER_CONNECT_S

SPEC = (
    'design = "lhs"\nsamples = 2\n[problem]\nnames = ["input.thermal.t_room.rise"]\nbounds = [[0.0, 1.0]]\n'
)


def main(args: list[str]) -> int:
    """``twin sweep ARGS``."""
    return twin(["sweep", *args])


@contextlib.contextmanager
def listener(reply: bytes | None) -> Iterator[int]:
    """A TCP listener on 127.0.0.1 that accepts every connection and sends ``reply`` (then
    closes it), or (None) holds it open without a word; yields its port."""
    server = socket.create_server(("127.0.0.1", 0))
    held: list[socket.socket] = []
    stop = threading.Event()

    def serve() -> None:
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            if reply is None:
                held.append(conn)
            else:
                with contextlib.suppress(OSError):
                    conn.sendall(reply)
                conn.close()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield server.getsockname()[1]
    finally:
        stop.set()
        thread.join(5)
        server.close()
        for conn in held:
            conn.close()


@pytest.fixture
def spec(tmp_path: Path) -> Path:
    return write_spec(tmp_path / "s.toml", SPEC)


def _one_line(code: int, err: str, start: str) -> None:
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith(start), lines[0]
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("address", "expected"),
    [
        ("localhost", "twin: --scheduler: 'localhost': expected host:port"),
        ("host:notaport", "twin: --scheduler: 'host:notaport': expected host:port"),
        ("tcp://host:99999", "twin: --scheduler: 'tcp://host:99999': expected host:port"),
        ("not a url", "twin: --scheduler: 'not a url': expected host:port"),
        ("http://host:8786", "twin: --scheduler: 'http://host:8786': expected tcp://host:port"),
        ("/tmp/scheduler.json", "twin: --scheduler: '/tmp/scheduler.json' is a file, not an address"),
    ],
)
def test_a_malformed_address_is_one_line_at_once(
    spec: Path, tmp_path: Path, address: str, expected: str, capsys: pytest.CaptureFixture
) -> None:
    start = time.monotonic()
    code = main([str(spec), "--out", str(tmp_path / "out"), "--scheduler", address])
    _one_line(code, capsys.readouterr().err, expected)
    assert time.monotonic() - start < 2.0  # before the sweep file is even read
    assert not (tmp_path / "out").exists()


def test_a_closed_port_is_one_line(spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    with socket.create_server(("127.0.0.1", 0)) as s:
        port = s.getsockname()[1]  # bound, then closed: nothing listens there
    code = main([str(spec), "--out", str(tmp_path / "out"), "--scheduler", f"tcp://127.0.0.1:{port}"])
    _one_line(
        code, capsys.readouterr().err, "twin: --scheduler: cannot reach the scheduler at tcp://127.0.0.1:"
    )
    assert not (tmp_path / "out").exists()


def test_a_listener_that_is_not_dask_is_one_line(
    spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    with listener(b"HTTP/1.1 400 Bad Request\r\n\r\n") as port:
        code = main([str(spec), "--out", str(tmp_path / "out"), "--scheduler", f"127.0.0.1:{port}"])
    _one_line(code, capsys.readouterr().err, "twin: --scheduler: ")


def test_a_listener_that_never_answers_ends_within_35_s(spec: Path, tmp_path: Path) -> None:
    assert SCHEDULER_CONNECT_S + SCHEDULER_ANSWER_S < 30
    with listener(None) as port:
        start = time.monotonic()
        done = run_sweep_cli(spec, tmp_path / "out", "--scheduler", f"tcp://127.0.0.1:{port}", timeout=60)
        took = time.monotonic() - start
    _one_line(done.returncode, done.stderr, "twin: --scheduler: ")
    assert took < 35, took
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (None, "not a Dask scheduler file (FileNotFoundError"),
        ("{", "not a Dask scheduler file (JSONDecodeError"),
        ('{"type": "Scheduler"}', 'not a Dask scheduler file (no "address")'),
        ('{"address": "localhost"}', "'localhost': expected host:port"),
    ],
)
def test_a_bad_scheduler_file_is_one_line(
    spec: Path, tmp_path: Path, content: str | None, expected: str, capsys: pytest.CaptureFixture
) -> None:
    path = tmp_path / "scheduler.json"
    if content is not None:
        path.write_text(content)
    code = main([str(spec), "--out", str(tmp_path / "out"), "--scheduler-file", str(path)])
    _one_line(code, capsys.readouterr().err, f"twin: --scheduler-file {path}: {expected}")


def test_a_scheduler_file_naming_a_silent_listener_is_one_line(
    spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    import twin.pipeline.cluster as cluster

    monkeypatch.setattr(cluster, "SCHEDULER_ANSWER_S", 1.0)  # the 35 s case is the child above
    monkeypatch.setattr(cluster, "SCHEDULER_CONNECT_S", 1.0)
    path = tmp_path / "scheduler.json"
    with listener(None) as port:
        path.write_text(json.dumps({"type": "Scheduler", "address": f"tcp://127.0.0.1:{port}"}))
        code = main([str(spec), "--out", str(tmp_path / "out"), "--scheduler-file", str(path)])
    _one_line(code, capsys.readouterr().err, f"twin: --scheduler-file {path}: tcp://127.0.0.1:{port} ")


def test_scheduler_and_scheduler_file_together_are_refused(
    spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    code = main([str(spec), "--scheduler", "tcp://a:1", "--scheduler-file", str(tmp_path / "f.json")])
    _one_line(code, capsys.readouterr().err, "twin: --scheduler-file: give one of")
