"""Python client of forestmapd, the ForestMap server (maps of trees, relocalization).

    from forestmap import Client
    client = Client("127.0.0.1:50051")
    client.create_map("plot", trees=np.array([[x, y, z, dbh], ...]))
    answer = client.relocalize("plot", detections)   # detections: N x 3 (x, y, z) or more
    if answer.localized:
        print(answer.x, answer.y, answer.yaw_deg)

The gRPC stubs (forestmap.v1.*_pb2) are generated from proto/ at build time into the build tree
(BUILD/python); put that directory on PYTHONPATH.
"""

from forestmap.client import (Answer, Client, FieldViolation, ForestMapError, MapInfo,
                              ObserveResult, Tree, TrackAnswer)

__all__ = ["Answer", "Client", "FieldViolation", "ForestMapError", "MapInfo", "ObserveResult",
           "Tree", "TrackAnswer"]
