"""Client: the blocking client of forestmapd (see api.Methods for its calls)."""

from __future__ import annotations

from typing import Iterable, Iterator, Optional, Sequence

import grpc

from forestmap import answers, tracking
from forestmap.api import Methods
from forestmap.connection import READ, Connection, Export, Unary, Upload
from forestmap.errors import ForestMapError
from forestmap.v1 import forestmap_service_pb2_grpc


class ClientBase(Methods):
    """The settings, replicas and channels of Client and AsyncClient."""

    def __init__(self, address: Optional[str] = None, timeout: float = 30.0, *,
                 token: Optional[str] = None, tls: bool = False, tls_ca: Optional[str] = None,
                 tls_cert: Optional[str] = None, tls_key: Optional[str] = None,
                 stream_timeout: float = 600.0, write_attempts: int = 3):
        self._connection = Connection(address, token, tls, tls_ca, tls_cert, tls_key, timeout,
                                      stream_timeout, write_attempts)
        self._channels = {}

    @property
    def addresses(self):
        return self._connection.addresses

    @property
    def current_address(self) -> str:
        """The replica calls go to now."""
        return self._connection.address

    @property
    def retries(self) -> int:
        """Tries repeated (on another replica, or a write with its request id) so far."""
        return self._connection.retries

    def _stub(self, module=grpc):
        """The stub of the current replica, over a channel of `module` (grpc or grpc.aio)."""
        address = self._connection.address
        if address not in self._channels:
            channel = self._connection.channel(module, address)
            self._channels[address] = (channel, forestmap_service_pb2_grpc.ForestMapStub(channel))
        return self._channels[address][1]


class Client(ClientBase):
    """One forestmapd, or several replicas of one service ("a:1,b:2": calls go to the first that
    answers).

    address: "host:port[,host:port...]"; default FORESTMAP_SERVER, else 127.0.0.1:50051.
    token: access token (forestmapd token create); default FORESTMAP_TOKEN.
    tls: TLS with the system's root certificates. tls_ca: PEM file of the CA of the server's
    certificate, implies TLS; default FORESTMAP_TLS_CA. tls_cert, tls_key: a client
    certificate (PEM files), for servers started with --tls-client-ca.
    timeout: deadline of each unary call (s). stream_timeout: deadline of a whole upload,
    export or tracking session (s).
    write_attempts: tries of a write that timed out or found its replica down, all with one
    request id (the server applies it at most once).

    Reads (get, list, export, relocalize, track) move to the next replica when one cannot be
    reached (UNAVAILABLE) or does not answer in time; writes too, with their request id. Every
    method raises ForestMapError (with the gRPC status) when the call fails, ValueError for bad
    arguments before anything is sent.
    """

    def close(self) -> None:
        for channel, _ in self._channels.values():
            channel.close()
        self._channels.clear()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _run(self, plan):
        response = None
        try:
            while True:
                response = self._perform(plan.send(response))
        except StopIteration as done:
            return done.value

    def _perform(self, call):
        connection = self._connection
        connection.begin(call)
        for attempt in range(connection.attempts(call.kind)):
            try:
                return self._once(self._stub(), call, connection.deadline(call))
            except (grpc.RpcError, ForestMapError) as error:
                connection.failed(call, error, attempt)
        raise AssertionError("unreachable")

    def _once(self, stub, call, timeout: float):
        metadata = self._connection.metadata
        if isinstance(call, Unary):
            return getattr(stub, call.rpc)(call.request, timeout=timeout, metadata=metadata)
        if isinstance(call, Upload):
            return stub.UploadTrees(call.requests(), timeout=timeout, metadata=metadata)
        assert isinstance(call, Export)
        call.gather.reset()
        for response in stub.ExportTrees(call.request, timeout=timeout, metadata=metadata):
            call.gather.add(response)
        return call.gather.result()

    def track(self, name: Optional[str], frames: Iterable, *,
              columns: Optional[Sequence[str]] = None, timeout: Optional[float] = None,
              maps: Optional[Sequence[str]] = None, maps_matching: Optional[str] = None,
              all_maps: bool = False) -> Iterator[answers.TrackAnswer]:
        """A tracking session: yields one answer per frame, in order.

        frames: tracking.Frame (trees with frame_id, stamp_ns, gravity, odometry), or trees, or
        (frame_id, trees) tuples; read lazily, so a live generator works. timeout: deadline of
        the whole session (s; default stream_timeout). When the replica fails (cannot be
        reached, or stalls past the deadline) the session goes on at the next replica with the
        frames not answered yet (a new session there: it starts by a search).

        Instead of one map (name None): a set, ``maps``, ``maps_matching`` or ``all_maps`` as
        for relocalize; the session crosses from one map into the next, and each answer's
        answer.map_name names its map."""
        pending = tracking.Pending(name, frames, columns, (maps, maps_matching, all_maps))
        deadline = timeout or self._connection.stream_timeout
        failures = 0
        while True:
            responses = self._stub().Track(pending.requests(), timeout=deadline,
                                           metadata=self._connection.metadata)
            try:
                for response in responses:
                    pending.answered()
                    failures = 0
                    yield answers.track_answer(response)
                break
            except grpc.RpcError as error:
                self._connection.failed(Unary("Track", None, READ), error, failures)
                failures += 1
            finally:
                responses.cancel()  # a no-op after the end; else the caller stopped early
        if pending.error is not None:
            raise pending.error
