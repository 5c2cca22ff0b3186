"""Trunk detection from Python: runs the installed `forestmap detect` (the C++ detector of the
CLI) on a scan file and returns its tree list as a structured array, ready for
Client.relocalize (columns by name: x, y, z, dbh, score, axis_x, axis_y, axis_z, then the
detector's diagnostics bh_x, bh_y, bh_z, ground_known, points, slices, residual, arc_coverage,
range). The cost over the detector itself is one process start and a CSV parse."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from typing import Optional, Sequence

import numpy as np

from forestmap.inputs import read_csv


def find_cli(cli: Optional[str] = None) -> str:
    """`cli`, else FORESTMAP_CLI, else `forestmap` on PATH."""
    path = cli or os.environ.get("FORESTMAP_CLI") or shutil.which("forestmap")
    if not path or not os.access(path, os.X_OK):
        raise FileNotFoundError(
            f"no forestmap CLI{' at ' + path if path else ' on PATH'}: install the forestmap "
            "package (it ships `forestmap detect`), or pass cli= or set FORESTMAP_CLI")
    return path


def detect(scan, *, multi_view: bool = False, beam_divergence: float = 0.0,
           extra_args: Sequence[str] = (), cli: Optional[str] = None,
           timeout: Optional[float] = 600.0) -> np.ndarray:
    """Trunks in one scan (.pcd .ply .las .csv .xyz .txt), as `forestmap detect SCAN` finds
    them: positions (stem-ground intersection) in the scan's frame, DBH at 1.3 m (m).

    multi_view: the cloud is merged from many viewpoints (no sensor at the origin).
    beam_divergence: rad, for the DBH edge-bias compensation (Ouster OS1: 0.0031).
    extra_args: more `forestmap detect` flags (e.g. ("--min-height", "0.5")).
    Raises RuntimeError with the CLI's message when detection fails."""
    if not os.path.isfile(scan):
        raise FileNotFoundError(f"scan {scan}: no such file")
    command = [find_cli(cli), "detect", os.fspath(scan)]
    if multi_view:
        command.append("--multi-view")
    if beam_divergence:
        command += ["--beam-divergence", repr(float(beam_divergence))]
    command += list(extra_args)
    with tempfile.TemporaryDirectory(prefix="forestmap-detect-") as directory:
        out = os.path.join(directory, "trees.csv")
        run = subprocess.run(command + ["--out", out], capture_output=True, text=True,
                             timeout=timeout)
        if run.returncode != 0:
            message = run.stderr.strip().splitlines()
            raise RuntimeError(f"forestmap detect {scan} failed: "
                               f"{message[-1] if message else 'exit ' + str(run.returncode)}")
        return read_csv(out)
