"""``sort --address``: a Ray address is checked in seconds, in one line, before any game."""

from __future__ import annotations

import socket
import threading
import time

import pytest

from sieve_mi.cascade.games import check_address
from sieve_mi.errors import SieveError


def _server(answer: bytes):
    """A one-connection TCP server on localhost that reads the client's hello and sends ``answer``."""
    srv = socket.create_server(("127.0.0.1", 0))
    srv.settimeout(10)

    def serve():
        try:
            conn, _ = srv.accept()
            with conn:
                conn.recv(64)
                conn.sendall(answer)
                time.sleep(0.5)
        except OSError:
            pass
        finally:
            srv.close()

    threading.Thread(target=serve, daemon=True).start()
    return srv.getsockname()[1]


HTTP1 = b"HTTP/1.0 400 Bad Request\r\n\r\n"


def test_a_grpc_server_is_taken_for_a_cluster():
    settings = bytes([0, 0, 6, 4, 0, 0, 0, 0, 0]) + bytes(6)  # an HTTP/2 SETTINGS frame
    check_address(f"127.0.0.1:{_server(settings)}")
    check_address(f"ray://127.0.0.1:{_server(settings)}")


@pytest.mark.parametrize(
    "address, needle",
    [
        ("web", "not a Ray cluster"),  # a port that answers, but HTTP/1 (hung >= 120 s in ray.init)
        ("silent", "not a Ray cluster"),  # accepts and says nothing
        ("ray://nohost.invalid", "nothing is listening there"),
        ("x" * 300 + ":6379", "expected host:port"),
        ("127.0.0.1:0", "expected host:port"),
        ("127.0.0.1:99999", "expected host:port"),
        ("10.0.0.5", "expected host:port"),
    ],
)
def test_bad_addresses_are_one_line_in_seconds(address, needle):
    if address == "web":
        address = f"127.0.0.1:{_server(HTTP1)}"
    elif address == "silent":
        address = f"127.0.0.1:{_server(b'')}"
    t0 = time.perf_counter()
    with pytest.raises(SieveError) as e:
        check_address(address, timeout=1.0)
    assert needle in str(e.value) and "\n" not in str(e.value)
    assert len(str(e.value)) < 300  # a huge host is not echoed whole
    assert time.perf_counter() - t0 < 5.0
