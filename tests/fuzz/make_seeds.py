#!/usr/bin/env python3
"""Writes the hand-made seed corpus of the fuzz targets (tests/fuzz/corpus/<target>/).

Each seed is a tiny valid (or nearly valid) file of its format, so that libFuzzer starts from
inputs that reach deep into the readers. Run once after changing a format; the output is
committed. Usage: make_seeds.py CORPUS_DIR [PROTO_DIR] (PROTO_DIR: proto/, for the requests).
"""
import os
import struct
import subprocess
import sys
import tempfile


def write(corpus, target, name, data):
    os.makedirs(os.path.join(corpus, target), exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(corpus, target, name), "wb") as f:
        f.write(data)


def tree_csv(c):
    t = "fuzz_tree_csv"
    write(c, t, "map.csv", "id,x,y,z,dbh,species\n0,1.5,2.5,0.1,0.31,pine\n1,-3,4e1,NA,,\"a,\"\"b\"\n")
    write(c, t, "map_mapped.csv", "\ufeffE;N;BHD\r\n1;2;31\r\n3;4;NA\r\n")
    write(c, t, "map_cols.csv", "E,N,BHD,Art\n10,20,31.5,Fi\n11,21,\"\",\"NA\"\n")
    write(c, t, "detections.csv", "x,y,z,dbh,score,axis_x,axis_y,axis_z\n1,2,0,0.3,0.9,0,0,1\n-1,0.5,,NaN,,,,\n")
    write(c, t, "frames.csv", "frame,x,y,z,dbh\n0,1,2,0,0.2\n0,3,1,0,0.3\n1,2,2,0,0.25\n")
    write(c, t, "poses.csv", "frame,timestamp,x,y,z,qx,qy,qz,qw\n0,0.0,1,2,3,0,0,0,1\n1,0.1,1.1,2,3,0,0,0.7071068,0.7071068\n")


def pcd_header(fields, sizes, types, n, data, comment=""):
    return (f"# .PCD v0.7{comment}\nVERSION 0.7\nFIELDS {' '.join(fields)}\nSIZE {' '.join(map(str, sizes))}\n"
            f"TYPE {' '.join(types)}\nCOUNT {' '.join('1' for _ in fields)}\nWIDTH {n}\nHEIGHT 1\n"
            f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {data}\n")


def lzf_literal(raw):
    out = b""
    for i in range(0, len(raw), 32):
        chunk = raw[i:i + 32]
        out += bytes([len(chunk) - 1]) + chunk
    return out


def pcd(c):
    t = "fuzz_pcd"
    write(c, t, "ascii.pcd", pcd_header(["x", "y", "z", "intensity"], [4, 4, 4, 4], "FFFF", 3, "ascii",
                                        " offset subtracted: 470627.0 3810222.0 2278.0")
          + "1 2 3 10\n4 5 6 20\nnan nan nan 0\n")
    pts = [(1.0, 2.0, 3.0, 7), (4.0, 5.0, 6.0, 9)]
    body = b"".join(struct.pack("<fffH", *p) for p in pts)
    write(c, t, "binary.pcd", pcd_header(["x", "y", "z", "ring"], [4, 4, 4, 2], "FFFU", 2, "binary").encode() + body)
    body = b"".join(struct.pack("<ddd", *p[:3]) for p in pts)
    write(c, t, "binary_f8.pcd", pcd_header(["x", "y", "z"], [8, 8, 8], "FFF", 2, "binary").encode() + body)
    # binary_compressed: field-major data, LZF (literal runs only), preceded by the two sizes.
    raw = b"".join(struct.pack("<%df" % len(pts), *[p[a] for p in pts]) for a in range(3))
    comp = lzf_literal(raw)
    write(c, t, "compressed.pcd", pcd_header(["x", "y", "z"], [4, 4, 4], "FFF", 2, "binary_compressed").encode()
          + struct.pack("<II", len(comp), len(raw)) + comp)


def ply(c):
    t = "fuzz_ply"
    write(c, t, "ascii.ply", "ply\nformat ascii 1.0\ncomment offset subtracted: 10 20 0\ncomment organised: 2 2\n"
          "element vertex 4\nproperty float x\nproperty float y\nproperty double z\nproperty uchar intensity\n"
          "property ushort ring\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
          "1 2 3 4 0\n2 3 4 5 0\nnan nan nan 0 1\n4 5 6 7 1\n3 0 1 2\n")
    hdr = ("ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
           "property float z\nproperty float scalar_intensity\nend_header\n")
    write(c, t, "binary_le.ply", hdr.encode() + struct.pack("<8f", 1, 2, 3, 0.5, 4, 5, 6, 0.25))
    hdr = ("ply\nformat binary_big_endian 1.0\nelement camera 1\nproperty int id\nelement vertex 2\n"
           "property double x\nproperty double y\nproperty double z\nproperty short ring\nend_header\n")
    write(c, t, "binary_be.ply", hdr.encode() + struct.pack(">i", 1) + struct.pack(">dddhdddh", 1, 2, 3, 0, 4, 5, 6, 1))


def las_file(minor, fmt, points, vlrs=b"", nvlr=0, extra=0):
    header_size = {2: 227, 3: 235, 4: 375}[minor]
    rec = [20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67][fmt] + extra
    h = bytearray(header_size)
    h[0:4] = b"LASF"
    h[24], h[25] = 1, minor
    struct.pack_into("<H", h, 94, header_size)
    struct.pack_into("<I", h, 96, header_size + len(vlrs))
    struct.pack_into("<I", h, 100, nvlr)
    h[104] = fmt
    struct.pack_into("<H", h, 105, rec)
    struct.pack_into("<I", h, 107, len(points) if fmt < 6 else 0)
    struct.pack_into("<3d", h, 131, 0.01, 0.01, 0.001)
    struct.pack_into("<3d", h, 155, 1000.0, 2000.0, 0.0)
    if minor == 4:
        struct.pack_into("<Q", h, 247, len(points))
    body = b""
    for (x, y, z, i, ring) in points:
        r = bytearray(rec)
        struct.pack_into("<iiiH", r, 0, x, y, z, i)
        if extra:
            struct.pack_into("<H", r, rec - extra, ring)
        body += bytes(r)
    return bytes(h) + vlrs + body


def las(c):
    t = "fuzz_las"
    pts = [(100, 200, 300, 5, 0), (-100, 50, 1000, 9, 1), (0, 0, 0, 0, 2)]
    write(c, t, "v12_f0.las", las_file(2, 0, pts))
    write(c, t, "v13_f1.las", las_file(3, 1, pts[:2]))
    desc = bytearray(192)
    desc[2] = 3  # unsigned short
    desc[3] = 0
    desc[4:8] = b"Ring"
    vlr = bytearray(54)
    vlr[2:11] = b"LASF_Spec"
    struct.pack_into("<HH", vlr, 18, 4, 192)
    write(c, t, "v14_f6_ring.las", las_file(4, 6, pts, bytes(vlr) + bytes(desc), 1, extra=2))


def text_scan(c):
    t = "fuzz_text_scan"
    write(c, t, "header.csv", "# offset subtracted: 1 2 3\nx,y,z,intensity,ring\n1,2,3,4,0\n5,6,7,8,1\n")
    write(c, t, "plain.csv", "1 2 3\n4\t5\t6 7\n\n# comment\nnan inf -inf\n")
    write(c, t, "cloudcompare.csv", "//X,Y,Z,scalar_intensity\n0.5,1.5,2.5,10\n")
    write(c, t, "organised.csv", "# organised: 2 2\nx,y,z\n1,1,1\n2,2,2\nnan,nan,nan\n3,3,3\n")
    write(c, t, "planar.csv", "angle_rad,range_m\n0,1.5\n0.01,nan\n0.02,inf\n")


def validation(c, proto_dir):
    t = "fuzz_validation"
    with tempfile.TemporaryDirectory() as out:
        protos = [os.path.join("forestmap/v1", p) for p in ("geometry.proto", "maps.proto",
                  "relocalization.proto", "observations.proto", "tracking.proto")]
        subprocess.run(["protoc", f"--proto_path={proto_dir}", f"--python_out={out}"] + protos, check=True)
        sys.path.insert(0, out)
        from forestmap.v1 import maps_pb2, observations_pb2, relocalization_pb2, tracking_pb2

        def det(x, y):
            d = relocalization_pb2.DetectedTree(dbh=0.3, score=0.8)
            d.position.x, d.position.y, d.position.z = x, y, 0.0
            d.axis.z = 1.0
            return d

        def pose(m):
            m.translation.x, m.translation.y, m.translation.z = 1.0, 2.0, 0.0
            m.rotation.w = 1.0

        create = maps_pb2.CreateMapRequest(name="forest", description="a test", crs="EPSG:32633")
        reloc = relocalization_pb2.RelocalizeRequest(map_name="forest", trees=[det(1, 2), det(3, 1), det(0, 4)])
        pose(reloc.prior.map_from_sensor)
        reloc.prior.radius_m = 5.0
        reloc.gravity.z = -1.0
        track = tracking_pb2.TrackRequest(map_name="forest", trees=[det(1, 2), det(3, 1), det(0, 4)], frame_id=7)
        pose(track.odometry)
        observe = observations_pb2.ObserveRequest(map_name="forest", source="drone-1", base_version=3)
        frame = observe.frames.add(frame_id=1, trees=[det(1, 2)])
        pose(frame.map_from_sensor)
        upload = maps_pb2.UploadTreesRequest(map_name="forest", replace=True)
        tree = upload.trees.add(id=1, x=1.0, y=2.0, z=0.0, dbh=0.3)
        tree.attributes["species"] = "pine"
        upload.trees.add(x=-5.0, y=1e6)
        seeds = [(0, create), (1, maps_pb2.GetMapRequest(name="forest")),
                 (2, maps_pb2.DeleteMapRequest(name="forest")),
                 (3, maps_pb2.ExportTreesRequest(map_name="forest")), (4, reloc), (5, track),
                 (6, observe), (7, observations_pb2.ListVersionsRequest(map_name="forest")),
                 (8, observations_pb2.RestoreVersionRequest(map_name="forest", version=2)),
                 (9, observations_pb2.RemoveSourceRequest(map_name="forest", source="drone-1")),
                 (10, upload)]
        for kind, message in seeds:
            write(c, t, f"{kind:02d}_{type(message).__name__}.bin", bytes([kind]) + message.SerializeToString())


def http_routes(c):
    t = "fuzz_http_routes"
    token = "fmt_" + "0123456789abcdef" * 4
    write(c, t, "page.txt", "GET / HTTP/1.1\r\nHost: forest\r\n\r\n")
    write(c, t, "first_visit.txt", f"GET /?token={token} HTTP/1.1\r\nHost: forest\r\n\r\n")
    write(c, t, "trees_bearer.txt", "GET /api/maps/plot-1/trees HTTP/1.1\r\nHost: forest\r\n"
          f"Authorization: Bearer {token}\r\n\r\n")
    write(c, t, "versions_cookie.txt", "GET /api/maps/plot_2.v1/versions HTTP/1.1\r\nHost: forest\r\n"
          f"Cookie: theme=dark; forestmap_token={token}\r\n\r\n")
    write(c, t, "keep_alive.txt", "GET /api/maps HTTP/1.1\r\nHost: forest\r\n\r\n"
          "HEAD /api/relocalizations?token=x%0d%0ay HTTP/1.1\r\nHost: forest\r\n\r\n"
          "GET /metrics HTTP/1.1\r\nHost: forest\r\nConnection: close\r\n\r\n")
    write(c, t, "metrics.txt", "GET /metrics HTTP/1.1\r\n\r\nGET /readyz HTTP/1.1\r\n\r\n"
          "GET /healthz HTTP/1.1\r\n\r\nGET /x%22%7D%201%0Afake%2042 HTTP/1.1\r\n\r\n")
    write(c, t, "post_body.txt", "POST /api/maps HTTP/1.1\r\nContent-Length: 5\r\n\r\nhello")
    write(c, t, "chunked.txt", "POST /metrics HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n"
          "5\r\nhello\r\n0\r\n\r\n")
    write(c, t, "range.txt", "GET / HTTP/1.1\r\nRange: bytes=0-10,20-\r\n\r\n")


def metrics(c):
    t = "fuzz_metrics"
    write(c, t, "known.bin", b"CreateMap\0Relocalize\0grpc.health.v1.Health/Check\0unknown")
    write(c, t, "forged.bin", b'/x"} 1\nfake_metric 42\n#\0\\\\"\0\xff\xfe\x01\x7f')
    write(c, t, "values.bin", struct.pack("<d", float("nan")) + b"\0" + struct.pack("<d", float("inf"))
          + b"\0" + struct.pack("<d", 1e-310) + b"\0" + struct.pack("<d", 2.5e-3))
    write(c, t, "long.bin", b"A" * 300 + b"\0" + "é".encode() * 100)


def main():
    corpus = sys.argv[1]
    http_routes(corpus)
    metrics(corpus)
    tree_csv(corpus)
    pcd(corpus)
    ply(corpus)
    las(corpus)
    text_scan(corpus)
    if len(sys.argv) > 2:
        validation(corpus, sys.argv[2])


if __name__ == "__main__":
    main()
