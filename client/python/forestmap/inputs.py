"""Named tree tables -> request messages.

A table is found by its column NAMES, never by position (a frame in `forestmap detect`'s column
order x,y,z,dbh,score,axis_... read positionally as x,y,z,dbh,axis_...,score would be a silent
wrong answer). Accepted: a numpy structured array (e.g. forestmap.detect's answer), a mapping
of column name -> 1-D array (a dict, a pandas DataFrame), a path of a CSV file with a header
row (`forestmap detect --out`'s file, a map.csv), or a plain N x k array WITH `columns=` naming
its k columns. Names are matched as the CLI matches CSV headers: case-insensitively, with the
same aliases (x_m, dbh_m, tree_id, ...). Columns the call does not use are ignored for
detections and kept as text attributes for map trees.
"""

from __future__ import annotations

import csv
import math
import os
from typing import Callable, Dict, Iterator, List, Optional, Sequence

import numpy as np

from forestmap.v1 import maps_pb2, relocalization_pb2

# canonical name -> accepted spellings (lower case), as client/io/tree_csv.h.
_ALIASES = {"x": ("x", "x_m"), "y": ("y", "y_m"), "z": ("z", "z_m"), "dbh": ("dbh", "dbh_m"),
            "id": ("id", "tree_id"), "score": ("score",), "axis_x": ("axis_x",),
            "axis_y": ("axis_y",), "axis_z": ("axis_z",)}
DETECTION_COLUMNS = ("x", "y", "z", "dbh", "score", "axis_x", "axis_y", "axis_z")
MAP_COLUMNS = ("id", "x", "y", "z", "dbh")
_NA = ("", "na", "nan")


def read_csv(path) -> np.ndarray:
    """A CSV file with a header row as a structured array: numeric columns float64 (empty, NA
    and NaN read as NaN), any other column text (object; empty or NA read as None)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise ValueError(f"{path}: empty file (want a header row)")
    names = [n.strip() for n in rows[0]]
    body = [r for r in rows[1:] if any(v.strip() for v in r)]
    for number, row in enumerate(body, start=2):
        if len(row) != len(names):
            raise ValueError(f"{path}:{number}: {len(row)} fields, the header has {len(names)}")
    columns = list(zip(*body)) if body else [()] * len(names)
    dtype, values = [], []
    for name, column in zip(names, columns):
        try:
            value = np.array([math.nan if v.strip().lower() in _NA else float(v)
                              for v in column], dtype=np.float64)
        except ValueError:
            value = np.array([None if v.strip().lower() in ("", "na") else v for v in column],
                             dtype=object)
        dtype.append((name, value.dtype))
        values.append(value)
    out = np.empty(len(body), dtype=dtype)
    for (name, _), value in zip(dtype, values):
        out[name] = value
    return out


def named_columns(trees, columns: Optional[Sequence[str]] = None,
                  what: str = "trees") -> Dict[str, np.ndarray]:
    """The columns of `trees` by name (names as given), each a 1-D array of one length."""
    if isinstance(trees, (str, os.PathLike)):
        trees = read_csv(trees)
    if columns is not None:
        array = np.asarray(trees)
        if array.dtype.names is not None or array.ndim != 2 or array.shape[1] != len(columns):
            raise ValueError(f"{what}: columns= names {len(columns)} columns; want a plain "
                             f"N x {len(columns)} array, got shape {array.shape}")
        table = {str(name): array[:, i] for i, name in enumerate(columns)}
    elif isinstance(trees, np.ndarray) and trees.dtype.names is not None:
        table = {name: trees[name] for name in trees.dtype.names}
    elif hasattr(trees, "keys") and hasattr(trees, "__getitem__"):  # dict, pandas DataFrame
        table = {str(name): np.asarray(trees[name]) for name in trees.keys()}
    else:
        shape = np.shape(trees) if not isinstance(trees, (set, dict)) else "?"
        raise ValueError(
            f"{what}: a plain array (shape {shape}) has no column names, and reading it by "
            "position gives wrong answers silently when its order differs (forestmap detect "
            "writes x,y,z,dbh,score,axis_x,...). Pass a structured array, a mapping of column "
            "name -> array (e.g. a pandas DataFrame), a CSV path, or name the columns: "
            "columns=(\"x\", \"y\", \"z\", \"dbh\")")
    lengths = {len(np.atleast_1d(v)) for v in table.values()}
    if len(lengths) > 1:
        raise ValueError(f"{what}: columns of different lengths {sorted(lengths)}")
    return {k: np.atleast_1d(v) for k, v in table.items()}


def _canonical(table: Dict[str, np.ndarray], wanted: Sequence[str],
               what: str) -> Dict[str, str]:
    """canonical name -> the name in `table`, of the `wanted` columns it has; x and y are
    required."""
    lower = {}
    for name in table:
        key = name.strip().lower()
        if key in lower:
            raise ValueError(f"{what}: two columns named {key!r}")
        lower[key] = name
    out = {}
    for canonical in wanted:
        found = [lower[a] for a in _ALIASES[canonical] if a in lower]
        if len(found) > 1:
            raise ValueError(f"{what}: columns {found} both mean {canonical!r}")
        if found:
            out[canonical] = found[0]
    missing = [c for c in ("x", "y") if c not in out]
    if missing:
        raise ValueError(f"{what}: no column {' or '.join(_ALIASES[missing[0]])} (columns: "
                         f"{', '.join(table) or 'none'})")
    return out


def _floats(column: np.ndarray, what: str, name: str, required: bool) -> np.ndarray:
    try:
        values = np.asarray(column, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: column {name!r} is not numeric") from None
    bad = np.flatnonzero(~np.isfinite(values) if required else np.isinf(values))
    if bad.size:
        raise ValueError(f"{what}[{bad[0]}].{name} is {values[bad[0]]} (want a finite number"
                         f"{'' if required else ', or NaN for unknown'})")
    return values


def detected_trees(trees, columns: Optional[Sequence[str]] = None,
                   what: str = "trees") -> List[relocalization_pb2.DetectedTree]:
    """Detections (sensor frame, m) as the CLI sends them: an unknown z is 0, an unknown dbh or
    score is left out, the axis (all three components or none) is normalised, a zero one left
    out."""
    table = named_columns(trees, columns, what)
    v = {name: _floats(table[original], what, name, name in ("x", "y"))
         for name, original in _canonical(table, DETECTION_COLUMNS, what).items()}
    n = len(v["x"])
    z = np.nan_to_num(v["z"], nan=0.0) if "z" in v else np.zeros(n)
    axes = [a for a in ("axis_x", "axis_y", "axis_z") if a in v]
    if axes and len(axes) != 3:
        raise ValueError(f"{what}: the stem axis needs all of axis_x, axis_y, axis_z")
    out = []
    for i in range(n):
        tree = relocalization_pb2.DetectedTree()
        tree.position.x, tree.position.y, tree.position.z = v["x"][i], v["y"][i], z[i]
        if "dbh" in v and not math.isnan(v["dbh"][i]):
            tree.dbh = v["dbh"][i]
        if "score" in v and not math.isnan(v["score"][i]):
            tree.score = v["score"][i]
        if axes:
            a = [0.0 if math.isnan(v[k][i]) else float(v[k][i]) for k in axes]
            norm = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
            if norm > 1e-9:
                tree.axis.x, tree.axis.y, tree.axis.z = (value / norm for value in a)
        out.append(tree)
    return out


def _attribute(value) -> Optional[str]:
    """A survey column's value as text; None (unknown) for None and NaN."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    if isinstance(value, (np.floating, float)):
        return None if math.isnan(value) else repr(float(value))
    return str(value.item() if isinstance(value, np.generic) else value)


def map_tree_chunks(trees, columns: Optional[Sequence[str]], chunk: int,
                    what: str = "trees") -> Callable[[], Iterator[List[maps_pb2.Tree]]]:
    """Checks a map table (x, y finite; z, dbh finite or NaN; ids whole numbers >= 0, NaN for
    none) and returns a function making its messages chunk by chunk: only one chunk of
    messages exists at a time, and the upload can be replayed (retries)."""
    table = named_columns(trees, columns, what)
    c = _canonical(table, MAP_COLUMNS, what)
    v = {name: _floats(table[original], what, name, name in ("x", "y"))
         for name, original in c.items()}
    if "id" in v:
        ids = v["id"]
        bad = np.flatnonzero(~np.isnan(ids) & ((ids < 0) | (ids != np.floor(ids))))
        if bad.size:
            raise ValueError(f"{what}[{bad[0]}].id is {ids[bad[0]]} (want a whole number >= 0)")
    extra = {name: col for name, col in table.items() if name not in c.values()}
    n = len(v["x"])

    def chunks() -> Iterator[List[maps_pb2.Tree]]:
        for begin in range(0, n, chunk):
            out = []
            for i in range(begin, min(n, begin + chunk)):
                tree = maps_pb2.Tree(x=v["x"][i], y=v["y"][i])
                for name in ("z", "dbh"):
                    if name in v and not math.isnan(v[name][i]):
                        setattr(tree, name, v[name][i])
                if "id" in v and not math.isnan(v["id"][i]):
                    tree.id = int(v["id"][i])
                for name, col in extra.items():
                    text = _attribute(col[i])
                    if text is None:
                        tree.null_attributes.append(name)
                    else:
                        tree.attributes[name] = text
                out.append(tree)
            yield out
    chunks.attribute_columns = list(extra)  # the table's order, kept on export
    return chunks
