#!/usr/bin/env python3
"""Checks the house layout (CONVENTIONS.md, issue 12) and exits 1 listing every violation:

- no file under algorithms/ includes gRPC, Protobuf, SQLite or PCL headers;
- includes between algorithm stages point down only (ALLOWED below, the CMake link graph);
- a stage's *_internal.h headers are included only from that stage (and tests);
- server/app (the application layer) includes no transport: no gRPC, Protobuf or httplib, and
  nothing of server/grpc, server/http or server/ops; the transports do not include each other,
  and server/ops includes neither of them (only forestmapd's main wires them together);
- no source file outside tests/ is longer than MAX_LINES.
"""
import pathlib
import re
import sys

MAX_LINES = 450
ALLOWED = {  # stage -> stages it may include (besides itself)
    "core": set(),
    "detection": {"core"},
    "relocalization": {"core"},
    "merging": {"core"},
    "simulation": {"core"},
    "mapping": {"core", "relocalization", "merging"},
    "evaluation": {"core", "relocalization"},
}
FORBIDDEN = re.compile(r'#include\s*[<"](grpc|google/protobuf|sqlite3|pcl/|[^">]*\.pb\.h)')
INCLUDE = re.compile(r'#include\s*"([^"]+)"')
SERVER_FORBIDDEN = {  # server/<folder> -> includes it may not have (server/CMakeLists.txt)
    "app": re.compile(r'#include\s*[<"](grpc|google/protobuf|httplib|[^">]*\.pb\.h|'
                      r'server/(grpc|http|ops)/)'),
    "grpc": re.compile(r'#include\s*[<"](httplib|server/http/)'),
    "http": re.compile(r'#include\s*[<"](grpc|google/protobuf|[^">]*\.pb\.h|server/(grpc|ops)/)'),
    "ops": re.compile(r'#include\s*[<"](httplib|server/(grpc|http)/)'),
}
SERVER_WIRING = pathlib.PurePath("server/ops/main.cc")  # forestmapd: includes every folder


def main(root: pathlib.Path) -> int:
    problems = []
    sources = [p for p in root.rglob("*") if p.suffix in (".h", ".cc") and p.is_file()
               and not any(part.startswith("build") or part == ".git"
                           for part in p.relative_to(root).parts)]
    for path in sources:
        rel = path.relative_to(root)
        text = path.read_text(errors="replace")
        top = rel.parts[0]
        if top != "tests" and text.count("\n") > MAX_LINES:
            problems.append(f"{rel}: {text.count(chr(10))} lines (> {MAX_LINES})")
        for number, line in enumerate(text.splitlines(), 1):
            if top == "algorithms" and FORBIDDEN.search(line):
                problems.append(f"{rel}:{number}: algorithms/ may not include {line.strip()}")
            layer = rel.parts[1] if top == "server" and len(rel.parts) > 2 else None
            if layer in SERVER_FORBIDDEN and rel != SERVER_WIRING and \
                    SERVER_FORBIDDEN[layer].search(line):
                problems.append(f"{rel}:{number}: server/{layer} may not include {line.strip()}")
            match = INCLUDE.search(line)
            if not match:
                continue
            target = pathlib.PurePath(match.group(1))
            if target.parts[0] != "algorithms" or len(target.parts) < 3:
                continue
            stage = target.parts[1]
            if target.name.endswith("_internal.h") and top != "tests" and \
                    rel.parts[:2] != target.parts[:2]:
                problems.append(f"{rel}:{number}: {target} is internal to algorithms/{stage}")
            if top == "algorithms" and len(rel.parts) > 2:
                own = rel.parts[1]
                if stage != own and stage not in ALLOWED.get(own, set()):
                    problems.append(f"{rel}:{number}: algorithms/{own} may not include "
                                    f"algorithms/{stage} (links point down only)")
    for problem in problems:
        print(problem)
    print(f"layout_check: {len(sources)} files, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()))
