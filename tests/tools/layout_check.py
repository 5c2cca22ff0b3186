#!/usr/bin/env python3
"""Checks the house layout (docs/conventions.md) and exits 1 listing every violation:

- no file under algorithms/ includes gRPC, Protobuf, SQLite, PCL or a header of another folder
  of the house; includes between algorithm stages point down only (STAGES, the CMake link graph);
- a stage's *_internal.h headers are included only from that stage (and tests);
- the folders' rules (RULES): the client never includes the server or the storage, the storage
  never includes the server or the client, SQLite and PostgreSQL code never include each other,
  the server's application layer speaks no transport, the client library carries no CLI;
- tests mirror the folders: every folder under tests/algorithms, tests/storage, tests/server and
  tests/client names a folder of the code;
- no source file outside tests/ is longer than MAX_LINES.

A rule about a folder applies once the folder exists.
"""
import pathlib
import re
import sys

MAX_LINES = 450
STAGES = {  # algorithm stage -> stages it may include (besides itself)
    "core": set(),
    "detection": {"core"},
    "relocalization": {"core"},
    "merging": {"core"},
    "simulation": {"core"},
    "mapping": {"core", "relocalization", "merging"},
    "evaluation": {"core", "relocalization"},
}
THIRD_PARTY_SERVICES = r"grpc|grpcpp/|google/protobuf|[^\">]*\.pb\.h"
# (folder the including file is in, pattern of forbidden includes, why)
RULES = [
    ("algorithms/", rf"{THIRD_PARTY_SERVICES}|sqlite3|pcl/|libpq|httplib|cairo|proj\.h|gdal",
     "algorithms/ is a pure library (Eigen and nanoflann only)"),
    ("algorithms/", r"(storage|server|client|geo|proto)/",
     "algorithms/ is the bottom of the house"),
    ("geo/", r"(storage|server|client)/", "geo/ is below the server and the client"),
    ("storage/", r"(server|client)/", "the storage never includes the server or the client"),
    ("storage/sqlite/", r"storage/postgres/|libpq", "SQLite and PostgreSQL code stay apart"),
    ("storage/postgres/", r"storage/sqlite/|sqlite3", "SQLite and PostgreSQL code stay apart"),
    ("client/", r"(server|storage)/", "the client never includes the server or the storage"),
    ("client/io/", rf"{THIRD_PARTY_SERVICES}|client/(lib|cli|lab)/",
     "client/io/ reads and writes files: no gRPC, no commands"),
    ("client/lib/", r"cairo|CLI/|client/(cli|lab)/",
     "the client library is embeddable: no CLI, no pictures"),
    ("client/cli/", r"client/lab/|algorithms/simulation/",
     "the user's command does not ship the lab"),
    ("server/app/", rf"{THIRD_PARTY_SERVICES}|httplib|server/(grpc|http|ops)/",
     "the application layer speaks no transport"),
    ("server/grpc/", r"httplib|server/http/", "the gRPC and HTTP transports stay apart"),
    ("server/http/", rf"{THIRD_PARTY_SERVICES}|server/(grpc|ops)/",
     "the gRPC and HTTP transports stay apart, and apart from operations"),
    ("server/ops/", r"httplib|server/(grpc|http)/",
     "operations (daemon, TLS, tokens, logs, metrics) include no transport"),
]
WIRING = {"server/ops/main.cc"}  # forestmapd's main joins the folders; no folder rule applies
MIRRORED = ["algorithms", "storage", "server", "client"]  # tests/<x>/<sub>/ mirrors <x>/<sub>/
# Test folders that are projects of their own, not mirrors: a program outside the tree built
# against the installed client library.
OUTSIDE_PROJECTS = {"tests/client/package"}
INCLUDE = re.compile(r'#include\s*[<"]([^">]+)[">]')


def sources(root):
    return [p for p in root.rglob("*") if p.suffix in (".h", ".cc") and p.is_file()
            and not any(part.startswith("build") or part == ".git"
                        for part in p.relative_to(root).parts)]


def stage_problems(rel, number, target):
    """Internal headers and the direction of includes between algorithm stages."""
    if target.parts[0] != "algorithms" or len(target.parts) < 3:
        return []
    stage = target.parts[1]
    problems = []
    if target.name.endswith("_internal.h") and rel.parts[0] != "tests" and \
            rel.parts[:2] != target.parts[:2]:
        problems.append(f"{rel}:{number}: {target} is internal to algorithms/{stage}")
    if rel.parts[0] == "algorithms" and len(rel.parts) > 2:
        own = rel.parts[1]
        if stage != own and stage not in STAGES.get(own, set()):
            problems.append(f"{rel}:{number}: algorithms/{own} may not include "
                            f"algorithms/{stage} (links point down only)")
    return problems


def file_problems(root, path, rules):
    rel = path.relative_to(root)
    text = path.read_text(errors="replace")
    problems = []
    if rel.parts[0] != "tests" and text.count("\n") > MAX_LINES:
        problems.append(f"{rel}: {text.count(chr(10))} lines (> {MAX_LINES})")
    posix = rel.as_posix()
    applicable = [(pattern, why) for folder, pattern, why in rules
                  if posix.startswith(folder) and posix not in WIRING]
    for number, line in enumerate(text.splitlines(), 1):
        match = INCLUDE.match(line.strip())
        if not match:
            continue
        target = match.group(1)
        for pattern, why in applicable:
            if re.match(pattern, target):
                problems.append(f"{rel}:{number}: includes {target}: {why}")
        problems += stage_problems(rel, number, pathlib.PurePosixPath(target))
    return problems


def mirror_problems(root):
    problems = []
    for top in MIRRORED:
        tests = root / "tests" / top
        if not tests.is_dir():
            continue
        for folder in sorted(p for p in tests.rglob("*") if p.is_dir()):
            rel = folder.relative_to(tests)
            if any(folder.relative_to(root).as_posix().startswith(p) for p in OUTSIDE_PROJECTS):
                continue
            if not (root / top / rel).is_dir():
                problems.append(f"tests/{top}/{rel.as_posix()}/: no folder {top}/"
                                f"{rel.as_posix()}/ to mirror (tests mirror the code's folders)")
    return problems


def main(root: pathlib.Path) -> int:
    rules = [(f, p, w) for f, p, w in RULES if (root / f).is_dir()]
    files = sources(root)
    problems = [p for path in files for p in file_problems(root, path, rules)]
    problems += mirror_problems(root)
    for problem in problems:
        print(problem)
    print(f"layout_check: {len(files)} files, {len(rules)} folder rules, "
          f"{len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()))
