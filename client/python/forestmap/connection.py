"""What the blocking and the asyncio client share about the connection: the replica list, TLS
and the token (arguments or the CLI's environment variables), deadlines, the retry policy and
the calls a method is made of (Unary, Upload, Export)."""

from __future__ import annotations

import os
import secrets
from dataclasses import dataclass
from typing import Callable, Iterator, List, Optional

import grpc

from forestmap.errors import ForestMapError
from forestmap.v1 import maps_pb2

DEFAULT_SERVER = "127.0.0.1:50051"  # as `forestmap --server`
READ, WRITE, ONCE = "read", "write", "once"  # how a call may be retried

# A call may go to another replica after these codes (the replica was unreachable or stalled);
# a write is retried with the SAME request id, so the server applies it at most once.
_RETRIABLE = (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.DEADLINE_EXCEEDED)


@dataclass
class Unary:
    rpc: str       # method name on the stub, e.g. "GetMap"
    request: object
    kind: str      # READ, WRITE (request.request_id is set per logical write) or ONCE


@dataclass
class Upload:
    """An UploadTrees stream: the header (request_id set per logical write), then chunks."""
    header: maps_pb2.UploadTreesHeader
    chunks: Callable[[], Iterator[list]]  # fresh chunk iterator per try
    rpc: str = "UploadTrees"
    kind: str = WRITE

    def requests(self) -> Iterator[maps_pb2.UploadTreesRequest]:
        yield maps_pb2.UploadTreesRequest(header=self.header)
        for trees in self.chunks():
            yield maps_pb2.UploadTreesRequest(chunk=maps_pb2.TreeChunk(trees=trees))


@dataclass
class Export:
    """An ExportTrees stream, gathered by `gather` (exports.Gather)."""
    request: maps_pb2.ExportTreesRequest
    gather: object
    rpc: str = "ExportTrees"
    kind: str = READ


def _pem(path: str, what: str) -> bytes:
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as error:
        raise ValueError(f"{what} {path}: cannot read ({error.strerror})") from None
    if b"-----BEGIN " not in data:
        raise ValueError(f"{what} {path} is not a PEM file")
    return data


class Connection:
    """Settings and replica state of one client (see Client for the arguments)."""

    def __init__(self, address: Optional[str], token: Optional[str], tls: bool,
                 tls_ca: Optional[str], tls_cert: Optional[str], tls_key: Optional[str],
                 timeout: float, stream_timeout: float, write_attempts: int):
        address = address or os.environ.get("FORESTMAP_SERVER") or DEFAULT_SERVER
        self.addresses: List[str] = [a.strip() for a in address.split(",") if a.strip()]
        if not self.addresses:
            raise ValueError(f"no server address in {address!r} (want host:port[,...])")
        for name, value in (("timeout", timeout), ("stream_timeout", stream_timeout)):
            if not (isinstance(value, (int, float)) and value > 0):
                raise ValueError(f"{name} must be > 0 s, got {value!r}")
        if not (isinstance(write_attempts, int) and write_attempts >= 1):
            raise ValueError(f"write_attempts must be >= 1, got {write_attempts!r}")
        self.timeout, self.stream_timeout = float(timeout), float(stream_timeout)
        self.write_attempts = write_attempts
        token = token if token is not None else os.environ.get("FORESTMAP_TOKEN", "")
        if "\n" in token or "\r" in token:
            raise ValueError("the token must be one line (token= or FORESTMAP_TOKEN)")
        self.metadata = (("authorization", f"Bearer {token}"),) if token else ()
        self.credentials = self._credentials(tls, tls_ca, tls_cert, tls_key)
        self.current = 0
        self.retries = 0  # calls moved to another replica or retried with their request id

    @staticmethod
    def _credentials(tls, tls_ca, tls_cert, tls_key) -> Optional[grpc.ChannelCredentials]:
        """None (plaintext), or TLS: on when tls or a CA (tls_ca, else FORESTMAP_TLS_CA)."""
        tls_ca = tls_ca if tls_ca is not None else os.environ.get("FORESTMAP_TLS_CA", "")
        if bool(tls_cert) != bool(tls_key):
            raise ValueError("a client certificate needs both tls_cert and tls_key")
        if not (tls or tls_ca or tls_cert):
            return None
        return grpc.ssl_channel_credentials(
            root_certificates=_pem(tls_ca, "tls_ca (FORESTMAP_TLS_CA)") if tls_ca else None,
            private_key=_pem(tls_key, "tls_key") if tls_key else None,
            certificate_chain=_pem(tls_cert, "tls_cert") if tls_cert else None)

    def channel(self, module, address: str):
        """A channel of `module` (grpc or grpc.aio) to `address`."""
        options = [("grpc.max_receive_message_length", 64 << 20)]
        if self.credentials is None:
            return module.insecure_channel(address, options=options)
        return module.secure_channel(address, self.credentials, options=options)

    @property
    def address(self) -> str:
        """The replica calls currently go to."""
        return self.addresses[self.current]

    def attempts(self, kind: str) -> int:
        if kind == WRITE:
            return max(self.write_attempts, len(self.addresses))
        return len(self.addresses) if kind == READ else 1

    def deadline(self, call) -> float:
        return self.timeout if isinstance(call, Unary) else self.stream_timeout

    def failed(self, call, error, attempt: int) -> None:
        """After a failed try: raises ForestMapError unless the call goes on (then moves to the
        next replica)."""
        if isinstance(error, ForestMapError):
            raise error
        if error.code() not in _RETRIABLE or attempt + 1 >= self.attempts(call.kind):
            raise ForestMapError.of(call.rpc, error, self.address) from None
        self.current = (self.current + 1) % len(self.addresses)
        self.retries += 1

    @staticmethod
    def begin(call) -> None:
        """Before the first try: a write gets its request id (the same on every try)."""
        if call.kind != WRITE:
            return
        request_id = new_request_id()
        if isinstance(call, Upload):
            call.header.request_id = request_id
        else:
            call.request.request_id = request_id


def new_request_id() -> str:
    """A fresh request id: 128 random bits (exactly-once writes, one id per logical write)."""
    return "fm-py-" + secrets.token_hex(16)
