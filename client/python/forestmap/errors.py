"""ForestMapError: every failed call, with the gRPC status and the fields the server named."""

from __future__ import annotations

from dataclasses import dataclass
from typing import List, Sequence

import grpc

from forestmap._googleapis.google.rpc import error_details_pb2, status_pb2


@dataclass
class FieldViolation:
    """One bad field of a request (google.rpc.BadRequest): its path and what is wrong."""
    field: str        # e.g. "trees[12].position.x"
    description: str


def _violations(error) -> List[FieldViolation]:
    """The google.rpc.BadRequest field violations in the status details of `error`, if any."""
    metadata = error.trailing_metadata() if hasattr(error, "trailing_metadata") else None
    out = []
    for key, value in metadata or ():
        if key != "grpc-status-details-bin":
            continue
        status = status_pb2.Status()
        status.ParseFromString(value)
        for detail in status.details:
            bad_request = error_details_pb2.BadRequest()
            if detail.Unpack(bad_request):
                out += [FieldViolation(v.field, v.description)
                        for v in bad_request.field_violations]
    return out


class ForestMapError(Exception):
    """Every failed call: `code` is the grpc.StatusCode, `details` the server's message,
    `violations` the bad fields the server named in its error details (INVALID_ARGUMENT) and
    `address` the replica that answered (or could not be reached)."""

    def __init__(self, call: str, code: grpc.StatusCode, details: str,
                 violations: Sequence[FieldViolation] = (), address: str = ""):
        fields = ", ".join(v.field for v in violations)
        shown = f" ({'fields' if len(violations) > 1 else 'field'}: {fields})" if fields else ""
        super().__init__(_message(call, code, details, address) + shown)
        self.call = call
        self.code = code
        self.details = details
        self.violations = list(violations)
        self.address = address

    @classmethod
    def of(cls, call: str, error, address: str = "") -> "ForestMapError":
        """From a grpc.RpcError (or grpc.aio.AioRpcError)."""
        return cls(call, error.code(), error.details() or "", _violations(error), address)


def _message(call: str, code: grpc.StatusCode, details: str, address: str) -> str:
    if code == grpc.StatusCode.UNAVAILABLE and not details.startswith("database unavailable"):
        return (f"{call}: UNAVAILABLE: cannot reach forestmapd at {address or '?'}: {details} "
                "(is it running? TLS on one side only?)")
    if code == grpc.StatusCode.UNAUTHENTICATED:
        return (f"{call}: UNAUTHENTICATED: {details} (pass Client(token=...) or set "
                "FORESTMAP_TOKEN)")
    return f"{call}: {code.name}: {details}"
