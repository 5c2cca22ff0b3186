"""Trees are read by column name: detect's column order, mappings, CSV paths and declared
columns give the same answer; plain arrays are refused. create_map is atomic; exports come as
structured arrays in bounded memory."""

import os
import tracemalloc

import grpc
import numpy as np
import pytest

from forest_data import V02_FRAME, detections, map_array
from forestmap import TREE_DTYPE, Client, ForestMapError, Tree, read_csv

DETECT_ORDER = ("x", "y", "z", "dbh", "score", "axis_x", "axis_y", "axis_z")  # forestmap detect


@pytest.fixture(scope="module")
def client(server, data_root):
    client = Client(server)
    client.create_map("tables", map_array(os.path.join(data_root, "sequences", "Wild_V01")))
    return client


@pytest.fixture(scope="module")
def frame(data_root):
    return detections(os.path.join(data_root, "sequences", "Wild_V02"), V02_FRAME)


def test_detect_column_order_gives_the_same_answer(client, frame, tmp_path):
    trees, text = frame
    reference = client.relocalize("tables", trees)
    assert reference.localized and reference.inliers > 150
    plain = np.column_stack([trees[name] for name in DETECT_ORDER])
    # The old client read this by position (x,y,z,dbh,axis...,score): NOT_FOUND, 41 inliers.
    with pytest.raises(ValueError, match="no column names"):
        client.relocalize("tables", plain)
    path = tmp_path / "frame.csv"
    path.write_text(text)
    shuffled = trees[list(reversed(trees.dtype.names))]
    for same in (client.relocalize("tables", plain, columns=DETECT_ORDER),
                 client.relocalize("tables", {name: trees[name] for name in DETECT_ORDER}),
                 client.relocalize("tables", str(path)),
                 client.relocalize("tables", np.ascontiguousarray(shuffled))):
        assert (same.status, same.x, same.y, same.quaternion, same.inliers) == (
            reference.status, reference.x, reference.y, reference.quaternion,
            reference.inliers)


def test_names_are_matched_as_the_cli_matches_headers(client, frame):
    trees = frame[0]
    upper = {"X_m": trees["x"], "Y_m": trees["y"], "Z": trees["z"], "DBH_m": trees["dbh"]}
    reference = client.relocalize("tables", {"x": trees["x"], "y": trees["y"],
                                             "z": trees["z"], "dbh": trees["dbh"]})
    assert client.relocalize("tables", upper).x == reference.x
    with pytest.raises(ValueError, match="no column x or x_m"):
        client.relocalize("tables", {"east": trees["x"], "y": trees["y"]})
    with pytest.raises(ValueError, match="both mean 'x'"):
        client.relocalize("tables", {"x": trees["x"], "x_m": trees["x"], "y": trees["y"]})
    with pytest.raises(ValueError, match="columns of different lengths"):
        client.relocalize("tables", {"x": trees["x"], "y": trees["y"][:-1]})
    with pytest.raises(ValueError, match="axis"):
        client.relocalize("tables", {"x": trees["x"], "y": trees["y"],
                                     "axis_x": trees["axis_x"]})
    with pytest.raises(ValueError, match=r"trees\[2\].x is inf"):
        client.relocalize("tables", {"x": [0.0, 1.0, np.inf], "y": [0.0, 1.0, 2.0]})
    with pytest.raises(ValueError, match="columns= names 3 columns"):
        client.relocalize("tables", np.zeros((5, 4)), columns=("x", "y", "z"))


def test_create_map_is_atomic(client):
    good = {"x": [1.0, 2.0, 3.0], "y": [1.0, 2.0, 3.0], "dbh": [0.2, -0.3, 0.25]}
    # A tree the server rejects: the old client left an empty map "atomic" behind.
    with pytest.raises(ForestMapError) as error:
        client.create_map("atomic", good)
    assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert [v.field for v in error.value.violations] == ["trees[1].dbh"]
    with pytest.raises(ForestMapError) as missing:
        client.get_map("atomic")
    assert missing.value.code == grpc.StatusCode.NOT_FOUND
    # A tree the client rejects: nothing is sent.
    with pytest.raises(ValueError, match=r"trees\[1\].y is nan"):
        client.create_map("atomic", {"x": [1.0, 2.0], "y": [1.0, np.nan]})
    with pytest.raises(ForestMapError):
        client.get_map("atomic")
    info = client.create_map("atomic", {"x": [1.0, 2.0], "y": [1.0, 2.0], "species": ["a", None]})
    assert info.tree_count == 2
    exported = client.export("atomic")
    assert [t.attributes for t in exported] == [{"species": "a"}, {"species": None}]
    client.delete_map("atomic")


def test_export_as_a_structured_array(client, server):
    rng = np.random.default_rng(11)
    n = 100_000
    trees = np.zeros(n, dtype=[("id", np.int64), ("x", np.float64), ("y", np.float64),
                                ("z", np.float64), ("dbh", np.float64)])
    trees["id"] = np.arange(n) * 3 + 7
    trees["x"], trees["y"] = rng.uniform(-3000, 3000, n), rng.uniform(-3000, 3000, n)
    trees["z"] = rng.uniform(0, 50, n)
    trees["dbh"] = np.where(np.arange(n) % 10 == 0, np.nan, rng.uniform(0.05, 0.9, n))
    client.create_map("big", trees)
    tracemalloc.start()
    exported = client.export("big", as_array=True)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert exported.dtype == TREE_DTYPE and len(exported) == n
    for name in ("id", "x", "y", "z"):
        assert np.array_equal(exported[name], trees[name]), name
    assert np.array_equal(exported["dbh"], trees["dbh"], equal_nan=True)
    assert exported["confirmed"].all() and np.isnan(exported["position_sigma_m"]).all()
    # Bounded: the array, the chunks it is gathered from, and a few chunks of messages.
    assert peak < 2.5 * exported.nbytes + (8 << 20), (peak, exported.nbytes)
    box = client.export("big", box=(0, 0, 1000, 1000), as_array=True)
    inside = (trees["x"] >= 0) & (trees["x"] <= 1000) & (trees["y"] >= 0) & (trees["y"] <= 1000)
    assert np.array_equal(box["id"], trees["id"][inside])
    as_list = client.export("big", box=(0, 0, 1000, 1000))
    assert [t.id for t in as_list] == list(box["id"]) and isinstance(as_list[0], Tree)
    client.delete_map("big")


def test_export_attributes_and_a_map_csv(client, data_root, tmp_path):
    path = tmp_path / "plot.csv"
    path.write_text("tree_id,x_m,y_m,dbh_m,species\n1,0.5,1.5,0.31,Picea\n2,3.5,1.0,NA,\n")
    client.create_map("plot-csv", str(path))
    exported = client.export("plot-csv", as_array=True, attributes=("species",))
    assert list(exported["id"]) == [1, 2] and list(exported["species"]) == ["Picea", None]
    assert exported["dbh"][0] == 0.31 and np.isnan(exported["dbh"][1])
    assert read_csv(str(path)).dtype.names == ("tree_id", "x_m", "y_m", "dbh_m", "species")
    client.delete_map("plot-csv")


def test_a_tables_attribute_order_is_the_maps(client):
    table = {"x": np.array([0.5, 3.5]), "y": np.array([1.5, 1.0]),
             "species": np.array(["Picea", "Abies"]), "height": np.array([21.0, 18.5]),
             "crown": np.array(["A", "B"])}
    info = client.create_map("ordered", table)
    assert client.attribute_columns("ordered") == ["species", "height", "crown"]
    assert not info.has_boundary
    client.upload("ordered", {"x": np.array([9.0]), "y": np.array([9.0]),
                              "plot_id": np.array(["p1"])})
    assert client.attribute_columns("ordered") == ["species", "height", "crown", "plot_id"]
    assert client.attribute_columns("ordered", version=info.version) == [
        "species", "height", "crown"]
    client.delete_map("ordered")
