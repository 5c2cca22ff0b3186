"""Track sessions, shared by the blocking and the asyncio client: frames -> TrackRequests, and the
frames sent but not yet answered, which a session resumed on another replica sends again."""

from __future__ import annotations

import asyncio
import collections
import threading
from dataclasses import dataclass
from typing import Any, Optional, Sequence

import numpy as np

from forestmap import geometry, inputs
from forestmap.v1 import tracking_pb2


@dataclass
class Frame:
    """One frame of a tracking session.

    trees: the detections, sensor frame (a named table, see forestmap.inputs; may be empty).
    frame_id: echoed in the answer (default: the frame's number in the session).
    stamp_ns: your time stamp of the detections, echoed in the answer (answer.stamp_ns).
    gravity: direction of gravity (down) in the sensor frame, e.g. from the IMU.
    odometry: 4 x 4 previous_sensor_from_sensor, the motion since the previous frame from the
      drone's odometry (without it the server predicts with the last frame-to-frame motion).
    """
    trees: Any
    frame_id: Optional[int] = None
    stamp_ns: Optional[int] = None
    gravity: Optional[Sequence[float]] = None
    odometry: Optional[np.ndarray] = None


def frame_message(frame, number: int, columns) -> tracking_pb2.TrackRequest:
    """A Frame, a (frame_id, trees) tuple or bare trees -> the request of frame `number`."""
    if not isinstance(frame, Frame):
        frame = Frame(frame[1], frame_id=frame[0]) if isinstance(frame, tuple) else Frame(frame)
    what = f"frames[{number}]"
    empty = frame.trees is None or (isinstance(frame.trees, (list, tuple)) and not frame.trees)
    message = tracking_pb2.TrackFrame(
        trees=[] if empty else inputs.detected_trees(frame.trees, columns, what + ".trees"),
        frame_id=number if frame.frame_id is None else int(frame.frame_id))
    if frame.stamp_ns is not None:
        message.client_stamp_ns = int(frame.stamp_ns)
    if frame.gravity is not None:
        message.gravity.CopyFrom(geometry.vector3(frame.gravity, what + ".gravity"))
    if frame.odometry is not None:
        message.odometry.CopyFrom(geometry.to_pose(frame.odometry, what + ".odometry"))
    return tracking_pb2.TrackRequest(frame=message)


class Pending:
    """The frames of one logical session: each is converted when gRPC asks for it and kept
    until its answer arrives (answers come in order). A session moved to another replica
    (`restart`) starts with a header and the unanswered frames, then goes on with the source.

    Blocking client: gRPC reads the requests on its own thread; the lock, held while the next
    frame is taken, keeps a stale stream from taking a frame after a restart. asyncio: the next
    frame is awaited in a shielded task that a stale stream leaves to the current one. A frame
    that cannot be converted ends the stream; `error` keeps the reason, raised by the client
    after the answers of the frames before it."""

    _END = object()

    def __init__(self, name: Optional[str], frames, columns, map_set=(None, None, False)):
        header = tracking_pb2.TrackHeader(name=name or "")
        names, pattern, every = map_set  # a session over a set of maps (Client.track)
        if names or pattern or every:
            header.maps.names.extend(names or ())
            header.maps.name_pattern = pattern or ""
            header.maps.all_readable = bool(every)
        self.header = tracking_pb2.TrackRequest(header=header)
        self.frames, self.columns = frames, columns
        self.source = None
        self.unanswered = collections.deque()
        self.number = 0
        self.generation = 0
        self.lock = threading.Lock()
        self.next_task = None
        self.error: Optional[Exception] = None

    def restart(self):
        """A new stream: (its generation, its first requests: header and unanswered frames)."""
        with self.lock:
            self.generation += 1
            return self.generation, [self.header] + list(self.unanswered)

    def answered(self) -> None:
        self.unanswered.popleft()

    def _record(self, frame):
        """The request of `frame`, kept until answered; None (and `error`) when it is bad."""
        try:
            message = frame_message(frame, self.number, self.columns)
        except (ValueError, TypeError, IndexError) as error:
            self.error = error
            return None
        self.number += 1
        self.unanswered.append(message)
        return message

    def requests(self):
        """Blocking: the requests of a new stream."""
        generation, first = self.restart()
        yield from first
        while True:
            with self.lock:
                if generation != self.generation or self.error is not None:
                    return
                if self.source is None:
                    self.source = iter(self.frames)
                frame = next(self.source, self._END)
                message = None if frame is self._END else self._record(frame)
            if message is None:
                return
            yield message

    async def _pull(self):
        if self.source is None:
            self.source = (self.frames.__aiter__() if hasattr(self.frames, "__aiter__")
                           else iter(self.frames))
        if hasattr(self.source, "__anext__"):
            try:
                return await self.source.__anext__()
            except StopAsyncIteration:
                return self._END
        return next(self.source, self._END)

    async def arequests(self):
        """asyncio: the requests of a new stream (frames: an iterable or an async iterable)."""
        generation, first = self.restart()
        for message in first:
            yield message
        while self.error is None:
            if self.next_task is None:
                self.next_task = asyncio.ensure_future(self._pull())
            frame = await asyncio.shield(self.next_task)
            if generation != self.generation:
                return  # the task's frame stays for the current stream
            self.next_task = None
            message = None if frame is self._END else self._record(frame)
            if message is None:
                return
            yield message
