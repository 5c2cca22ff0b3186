"""Tokens and TLS (arguments and the CLI's environment variables), deadlines on every call and
stream against a server that never answers, failover over replicas for reads, exports,
tracking and writes (these with one request id)."""

import os
import subprocess
import threading
from concurrent import futures

import grpc
import numpy as np
import pytest

from conftest import FORESTMAPD, start_forestmapd, stop
from forestmap import Client, ForestMapError
from forestmap.v1 import forestmap_service_pb2_grpc, maps_pb2

TREES = {"x": [0.0, 5.0, 9.0, 2.0], "y": [0.0, 1.0, 7.0, 8.0]}


@pytest.fixture(scope="module")
def secured(tmp_path_factory):
    """A forestmapd with TLS and tokens: (address, CA file = its certificate, admin token)."""
    directory = tmp_path_factory.mktemp("secured")
    key, cert, db = directory / "key.pem", directory / "cert.pem", directory / "maps.db"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
                    "-subj", "/CN=test", "-addext", "subjectAltName=IP:127.0.0.1",
                    "-keyout", str(key), "-out", str(cert)], check=True, capture_output=True)
    token = subprocess.run([FORESTMAPD, "token", "create", "--db", str(db), "--role", "admin"],
                           check=True, capture_output=True, text=True).stdout.split()[0]
    process, address = start_forestmapd(db, "--tls-cert", str(cert), "--tls-key", str(key))
    yield address, str(cert), token
    stop(process)


def test_token_and_tls_from_arguments_and_environment(secured, monkeypatch, tmp_path):
    address, ca, token = secured
    monkeypatch.delenv("FORESTMAP_TOKEN", raising=False)
    monkeypatch.delenv("FORESTMAP_TLS_CA", raising=False)
    with pytest.raises(ForestMapError) as plain:
        Client(address, timeout=5).list_maps()  # plaintext to a TLS server
    assert plain.value.code == grpc.StatusCode.UNAVAILABLE
    assert f"cannot reach forestmapd at {address}" in str(plain.value)
    with pytest.raises(ForestMapError) as anonymous:
        Client(address, tls_ca=ca).list_maps()
    assert anonymous.value.code == grpc.StatusCode.UNAUTHENTICATED
    assert "FORESTMAP_TOKEN" in str(anonymous.value)
    Client(address, tls_ca=ca, token=token).create_map("secure", TREES)
    monkeypatch.setenv("FORESTMAP_TOKEN", token)
    monkeypatch.setenv("FORESTMAP_TLS_CA", ca)
    monkeypatch.setenv("FORESTMAP_SERVER", address)
    assert Client().get_map("secure").tree_count == 4  # all three from the environment
    with pytest.raises(ForestMapError) as wrong:
        Client(token="fmt_" + "0" * 64).get_map("secure")  # the argument wins
    assert wrong.value.code == grpc.StatusCode.UNAUTHENTICATED


def test_bad_security_settings_are_clear_errors(tmp_path, monkeypatch):
    monkeypatch.delenv("FORESTMAP_TLS_CA", raising=False)
    with pytest.raises(ValueError, match=r"tls_ca .*nowhere.pem: cannot read"):
        Client("127.0.0.1:1", tls_ca=str(tmp_path / "nowhere.pem"))
    text = tmp_path / "ca.txt"
    text.write_text("not a certificate")
    monkeypatch.setenv("FORESTMAP_TLS_CA", str(text))
    with pytest.raises(ValueError, match=r"FORESTMAP_TLS_CA\) .*ca.txt is not a PEM file"):
        Client("127.0.0.1:1")
    with pytest.raises(ValueError, match="needs both tls_cert and tls_key"):
        Client("127.0.0.1:1", tls_cert=str(text))
    with pytest.raises(ValueError, match="one line"):
        Client("127.0.0.1:1", token="a\nb")
    with pytest.raises(ValueError, match="timeout must be > 0"):
        Client("127.0.0.1:1", timeout=0)


class Stalled(forestmap_service_pb2_grpc.ForestMapServicer):
    """A server that accepts every call and answers none until released; or, with `down`,
    answers every call UNAVAILABLE and remembers the request ids it saw."""

    def __init__(self, down=False):
        self.release, self.down, self.request_ids = threading.Event(), down, []

    def _stall(self, request, context):
        self.request_ids.append(getattr(request, "request_id", ""))
        if self.down:
            context.abort(grpc.StatusCode.UNAVAILABLE, "replica going down")
        self.release.wait(30)
        context.abort(grpc.StatusCode.INTERNAL, "released")

    GetMap = ListMaps = CreateMap = Relocalize = _stall

    def ExportTrees(self, request, context):
        self._stall(request, context)
        yield maps_pb2.ExportTreesResponse()

    def UploadTrees(self, requests, context):
        return self._stall(next(requests).header, context)

    def Track(self, requests, context):
        next(requests)
        self._stall(None, context)
        yield from ()


@pytest.fixture()
def fake():
    """Start a fake replica: fake(down=False) -> (address, servicer)."""
    servers = []

    def start(down=False):
        servicer = Stalled(down)
        server = grpc.server(futures.ThreadPoolExecutor(max_workers=4))
        forestmap_service_pb2_grpc.add_ForestMapServicer_to_server(servicer, server)
        port = server.add_insecure_port("127.0.0.1:0")
        server.start()
        servers.append((server, servicer))
        return f"127.0.0.1:{port}", servicer
    yield start
    for server, servicer in servers:
        servicer.release.set()
        server.stop(0)


def finishes(call, seconds=20):
    """Runs call() in a thread: its exception, or None; fails if it is still running after
    `seconds` (it would block forever without a deadline)."""
    outcome = []

    def run():
        try:
            call()
            outcome.append(None)
        except Exception as error:  # noqa: BLE001 (the test inspects it)
            outcome.append(error)
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), "the call did not end: no deadline"
    return outcome[0]


def test_every_call_has_a_deadline(fake):
    address, _ = fake()
    client = Client(address, timeout=0.5, stream_timeout=1.0)
    frames = [{"x": [0.0, 1.0, 2.0], "y": [0.0, 1.0, 0.0]}] * 3
    for call in (lambda: client.get_map("x"), lambda: client.export("x"),
                 lambda: client.relocalize("x", frames[0]),
                 lambda: list(client.track("x", frames)),
                 lambda: list(client.track("x", frames, timeout=0.5))):
        error = finishes(call)
        assert isinstance(error, ForestMapError) and error.code == \
            grpc.StatusCode.DEADLINE_EXCEEDED, error


def test_reads_exports_and_tracks_fail_over(server, fake, data_dir):
    stalled, _ = fake()
    client = Client(server)
    client.create_map("failover", TREES)
    for first in ("127.0.0.1:1", stalled):  # a dead replica, then one that stalls
        replicas = Client(f"{first},{server}", timeout=1.0, stream_timeout=2.0)
        assert replicas.get_map("failover").tree_count == 4
        assert len(replicas.export("failover", as_array=True)) == 4
        frame = {"x": np.array(TREES["x"]), "y": np.array(TREES["y"])}
        answers = list(Client(f"{first},{server}", stream_timeout=2.0).track(
            "failover", [frame] * 3))
        assert [a.frame_id for a in answers] == [0, 1, 2]
        assert replicas.retries == 1 and replicas.current_address == server


def test_writes_fail_over_with_one_request_id(server, fake):
    down, servicer = fake(down=True)
    client = Client(f"{down},{server}")
    info = client.create_map("once")
    assert client.retries == 1 and len(servicer.request_ids) == 1
    request_id = servicer.request_ids[0]
    assert request_id.startswith("fm-py-")
    # The live server got the same id: a retry with it is answered, not applied again.
    with grpc.insecure_channel(server) as channel:
        stub = forestmap_service_pb2_grpc.ForestMapStub(channel)
        again = stub.CreateMap(maps_pb2.CreateMapRequest(name="once", request_id=request_id))
        assert again.version == info.version
        with pytest.raises(grpc.RpcError) as fresh:
            stub.CreateMap(maps_pb2.CreateMapRequest(name="once", request_id="another-id"))
        assert fresh.value.code() == grpc.StatusCode.ALREADY_EXISTS
    # An upload too (a new client: the live replica stays the current one): added once.
    client = Client(f"{down},{server}")
    assert client.upload("once", TREES).tree_count == 4
    assert client.retries == 1 and servicer.request_ids[1].startswith("fm-py-")
    assert Client(server).get_map("once").tree_count == 4


def test_writes_never_move_on_after_a_rejection(server):
    client = Client(f"{server},127.0.0.1:1")
    with pytest.raises(ForestMapError) as error:
        client.create_map("bad name!")
    assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT and client.retries == 0
    assert os.environ.get("FORESTMAP_TOKEN") is None  # the tests run without one
