"""AsyncClient: the asyncio client (grpc.aio). The same methods as Client, each a coroutine
(`await client.get_map("plot")`), and track() an async generator; the plans, checks and answers
are Client's (api.Methods)."""

from __future__ import annotations

from typing import AsyncIterator, Optional, Sequence

import grpc
import grpc.aio

from forestmap import answers, tracking
from forestmap.client import ClientBase
from forestmap.connection import READ, Export, Unary, Upload
from forestmap.errors import ForestMapError


class AsyncClient(ClientBase):
    """As Client (same arguments); use `async with AsyncClient(...) as client:` or
    `await client.close()`. Create it inside the event loop that uses it."""

    def _stub(self, module=grpc.aio):
        return super()._stub(module)

    async def close(self) -> None:
        for channel, _ in self._channels.values():
            await channel.close()
        self._channels.clear()

    async def __aenter__(self) -> "AsyncClient":
        return self

    async def __aexit__(self, *exc) -> None:
        await self.close()

    async def _run(self, plan):
        response = None
        try:
            while True:
                response = await self._perform(plan.send(response))
        except StopIteration as done:
            return done.value

    async def _perform(self, call):
        connection = self._connection
        connection.begin(call)
        for attempt in range(connection.attempts(call.kind)):
            try:
                return await self._once(self._stub(), call, connection.deadline(call))
            except (grpc.RpcError, ForestMapError) as error:
                connection.failed(call, error, attempt)
        raise AssertionError("unreachable")

    async def _once(self, stub, call, timeout: float):
        metadata = self._connection.metadata
        if isinstance(call, Unary):
            return await getattr(stub, call.rpc)(call.request, timeout=timeout,
                                                 metadata=metadata)
        if isinstance(call, Upload):
            return await stub.UploadTrees(call.requests(), timeout=timeout, metadata=metadata)
        assert isinstance(call, Export)
        call.gather.reset()
        async for response in stub.ExportTrees(call.request, timeout=timeout,
                                               metadata=metadata):
            call.gather.add(response)
        return call.gather.result()

    async def track(self, name: Optional[str], frames, *,
                    columns: Optional[Sequence[str]] = None, timeout: Optional[float] = None,
                    maps: Optional[Sequence[str]] = None, maps_matching: Optional[str] = None,
                    all_maps: bool = False) -> AsyncIterator[answers.TrackAnswer]:
        """As Client.track; frames may also be an async iterable."""
        pending = tracking.Pending(name, frames, columns, (maps, maps_matching, all_maps))
        deadline = timeout or self._connection.stream_timeout
        failures = 0
        while True:
            call = self._stub().Track(pending.arequests(), timeout=deadline,
                                      metadata=self._connection.metadata)
            try:
                async for response in call:
                    pending.answered()
                    failures = 0
                    yield answers.track_answer(response)
                break
            except grpc.RpcError as error:
                self._connection.failed(Unary("Track", None, READ), error, failures)
                failures += 1
            finally:
                call.cancel()
        if pending.error is not None:
            raise pending.error


__all__ = ["AsyncClient"]
