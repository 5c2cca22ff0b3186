"""Hostile clients against a running forestmapd (driven by tests/bench/attack.sh), for a duration:

  methods    unknown gRPC methods whose names carry quotes, braces, newlines and a fresh number
             each (the metrics page must stay parseable, small, without forged lines);
  streams    rounds of silent UploadTrees, ExportTrees and Track streams (a never-yielding request
             iterator; an export never read), without a token and with a read token, held while an
             admin upload and an admin export are timed (bar: each within 1 s);
  replay     a request id used on map alpha, then by the same caller on map beta and by another
             caller on alpha (bar: applied or refused, never the first call's answer);
  halfopen   rounds of 50 silent TCP connections from 127.0.0.2 to the web and metrics ports,
             held 3 s, while 127.0.0.1 asks both (bar: answered within 1 s).

Prints one JSON report; exit status 1 when a bar was missed. Needs python3-grpcio and the
generated stubs of the Python client (BUILD/python on PYTHONPATH).
  attack.py --grpc HOST:PORT --http PORT --metrics PORT --admin T --writer T --reader T
            --shared MAP --duration S
"""

import argparse
import json
import socket
import threading
import time
import urllib.request

import grpc

from forestmap.v1 import maps_pb2, tracking_pb2
from forestmap.v1 import forestmap_service_pb2_grpc as service_grpc

WITHIN_S = 1.0  # bar: an admin call beside the attacks, and the web ports beside half-open ones
SILENT = 24  # silent streams of each kind per round and token


class Report:
    def __init__(self):
        self.lock = threading.Lock()
        self.counts = {}
        self.violations = []
        self.slowest = {}

    def count(self, key, n=1):
        with self.lock:
            self.counts[key] = self.counts.get(key, 0) + n

    def violation(self, text):
        with self.lock:
            if len(self.violations) < 50:
                self.violations.append(text)
            self.counts["violations"] = self.counts.get("violations", 0) + 1

    def seconds(self, key, value):
        with self.lock:
            self.slowest[key] = max(self.slowest.get(key, 0.0), value)


def metadata(token):
    return (("authorization", "Bearer " + token),) if token else ()


def code_name(error):
    return error.code().name if isinstance(error, grpc.Call) else type(error).__name__


def unknown_methods(channel, stop, report):
    n = 0
    while not stop.is_set():
        n += 1
        name = '/x"} %d\nfake_metric 42\n#{le="%d"}\\' % (n, n)
        call = channel.unary_unary(name)
        try:
            call(b"", timeout=2)
            report.violation("unknown method %r answered OK" % name)
        except grpc.RpcError as e:
            report.count("methods_" + code_name(e))


def upload_request(name, trees, request_id="", replace=False):
    yield maps_pb2.UploadTreesRequest(
        header=maps_pb2.UploadTreesHeader(name=name, replace=replace, request_id=request_id))
    yield maps_pb2.UploadTreesRequest(chunk=maps_pb2.TreeChunk(trees=trees))


def trees_at(offset, count=5):
    return [maps_pb2.Tree(x=offset + 3.0 * i, y=offset, dbh=0.3) for i in range(count)]


def silent_streams(stub, shared, token, release, report, tag):
    """Opens SILENT silent streams of each kind with `token`; returns the calls to cancel."""
    def never():
        release.wait()
        return
        yield  # a generator that yields nothing until released

    calls = []
    for _ in range(SILENT):
        calls.append(("upload_" + tag, stub.UploadTrees.future(
            never(), metadata=metadata(token), timeout=600)))
        calls.append(("export_" + tag, stub.ExportTrees(
            maps_pb2.ExportTreesRequest(name=shared), metadata=metadata(token), timeout=600)))
        calls.append(("track_" + tag, stub.Track(never(), metadata=metadata(token), timeout=600)))
    return calls


def timed_admin_calls(stub, admin, shared, n, report):
    start = time.monotonic()
    try:
        stub.UploadTrees(upload_request("attack-probe", trees_at(n % 1000), replace=True),
                         metadata=metadata(admin), timeout=10)
        upload_s = time.monotonic() - start
        start = time.monotonic()
        received = sum(len(m.trees) for m in stub.ExportTrees(
            maps_pb2.ExportTreesRequest(name=shared), metadata=metadata(admin), timeout=10))
        export_s = time.monotonic() - start
    except grpc.RpcError as e:
        report.violation("admin call beside silent streams failed: %s %s" %
                         (code_name(e), e.details()))
        return
    report.count("admin_probes")
    report.seconds("admin_upload_s", upload_s)
    report.seconds("admin_export_s", export_s)
    if upload_s > WITHIN_S or export_s > WITHIN_S:
        report.violation("admin upload %.2f s, export %.2f s (%d trees) beside silent streams" %
                         (upload_s, export_s, received))


def stream_rounds(channel, args, stop, report):
    stub = service_grpc.ForestMapStub(channel)
    n = 0
    while not stop.is_set():
        n += 1
        release = threading.Event()
        calls = silent_streams(stub, args.shared, "", release, report, "no_token")
        calls += silent_streams(stub, args.shared, args.reader, release, report, "read_token")
        time.sleep(0.5)  # the streams are open (or refused) by now
        timed_admin_calls(stub, args.admin, args.shared, n, report)
        stop.wait(3)
        for kind, call in calls:  # how the server answered each: refused, or still held
            report.count("silent_%s_%s" % (kind, call.code().name if call.done() else "held"))
        release.set()
        for _, call in calls:
            call.cancel()


def replay(channel, args, stop, report):
    stub = service_grpc.ForestMapStub(channel)
    n = 0
    while not stop.is_set():
        n += 1
        request_id = "attack-%d-%d" % (int(time.time()), n)
        try:
            first = stub.UploadTrees(upload_request("alpha", trees_at(n, 2), request_id),
                                     metadata=metadata(args.admin), timeout=10)
        except grpc.RpcError as e:
            report.violation("first upload with a request id failed: %s" % code_name(e))
            continue
        attempts = (("beta", args.admin, "other_map"), ("alpha", args.writer, "other_caller"))
        for name, token, kind in attempts:
            try:
                answer = stub.UploadTrees(upload_request(name, trees_at(n + 5000, 3), request_id),
                                          metadata=metadata(token), timeout=10)
            except grpc.RpcError as e:
                report.count("replay_%s_refused_%s" % (kind, code_name(e)))
                continue
            if answer.map.name != name or answer.map.version == first.map.version:
                report.violation("request id %s on %s (%s) got the first call's answer: %s v%d" %
                                 (request_id, name, kind, answer.map.name, answer.map.version))
            else:
                report.count("replay_%s_applied" % kind)
        stop.wait(0.2)


def half_open(args, stop, report):
    n = 0
    while not stop.is_set():
        n += 1
        held = []
        for port in (args.http, args.metrics):
            for _ in range(50):
                sock = socket.socket()
                sock.bind(("127.0.0.2", 0))
                try:
                    sock.connect(("127.0.0.1", port))
                    held.append(sock)
                except OSError:
                    sock.close()
        report.count("halfopen_connections", len(held))
        time.sleep(0.3)
        for url, token in ((f"http://127.0.0.1:{args.http}/api/maps", args.reader),
                           (f"http://127.0.0.1:{args.metrics}/healthz", "")):
            request = urllib.request.Request(url)
            if token:
                request.add_header("Authorization", "Bearer " + token)
            start = time.monotonic()
            try:
                with urllib.request.urlopen(request, timeout=10) as answer:
                    answer.read()
                    ok = answer.status == 200
            except OSError as e:
                ok = False
                report.violation("%s beside half-open connections: %s" % (url, e))
            elapsed = time.monotonic() - start
            report.seconds("web_beside_halfopen_s", elapsed)
            if ok and elapsed > WITHIN_S:
                report.violation("%s answered in %.2f s beside half-open connections" %
                                 (url, elapsed))
            report.count("web_probes")
        stop.wait(2.7)
        for sock in held:
            sock.close()


def main():
    parser = argparse.ArgumentParser()
    for flag in ("--grpc", "--admin", "--writer", "--reader", "--shared"):
        parser.add_argument(flag, required=True)
    parser.add_argument("--http", type=int, required=True)
    parser.add_argument("--metrics", type=int, required=True)
    parser.add_argument("--duration", type=float, required=True)
    args = parser.parse_args()
    report = Report()
    stop = threading.Event()
    def guarded(body, *body_args):
        try:
            body(*body_args)
        except Exception as e:  # a broken attack is a missed bar, not a quiet pass
            report.violation("%s stopped: %s: %s" % (body.__name__, type(e).__name__, e))

    runs = [(unknown_methods, grpc.insecure_channel(args.grpc), stop, report),
            (stream_rounds, grpc.insecure_channel(args.grpc), args, stop, report),
            (replay, grpc.insecure_channel(args.grpc), args, stop, report),
            (half_open, args, stop, report)]
    workers = [threading.Thread(target=guarded, args=run, daemon=True) for run in runs]
    for worker in workers:
        worker.start()
    time.sleep(args.duration)
    stop.set()
    for worker in workers:
        worker.join(timeout=30)
    print(json.dumps({"counts": report.counts, "slowest_s": report.slowest,
                      "violations": report.violations}, indent=1, sort_keys=True))
    return 1 if report.violations else 0


if __name__ == "__main__":
    raise SystemExit(main())
