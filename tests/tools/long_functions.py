#!/usr/bin/env python3
"""Lists functions longer than a limit (default 60 lines) in .cc/.h files outside tests/.

A function is a definition whose body opens with '{' at the end of its signature line and
closes with '}' at the signature's indentation; lambdas and classes are not counted. Prints
`file:line: N lines: signature` and exits 0 (a report; the closing note says why any remain).
"""
import pathlib
import re
import sys

SIGNATURE = re.compile(r"^( *)(?!if\b|for\b|while\b|switch\b|else\b|do\b|class\b|struct\b|"
                       r"namespace\b|enum\b|union\b|return\b)[A-Za-z_~][^;=]*\)[^;]*\{\s*$")


def long_functions(path, limit):
    lines = path.read_text(errors="replace").splitlines()
    found = []
    for start, line in enumerate(lines):
        if not line.rstrip().endswith("{") or ")" not in line or "[" in line:
            continue
        # The signature may start on earlier lines (a wrapped parameter list).
        first = start
        while first > 0 and lines[first - 1].rstrip().endswith((",", "(")):
            first -= 1
        match = SIGNATURE.match(lines[first] if first < start else line)
        if first < start:
            match = re.match(r"^( *)[A-Za-z_~][\w:<>,&*~ ]*\(", lines[first])
        if not match or re.match(r"^\s*(if|for|while|switch|else|do|return)\b", lines[first]) \
                or re.search(r"&&|\|\|| [<>=!]=? ", lines[first]):  # a wrapped condition
            continue
        indent = match.group(1)
        for end in range(start + 1, len(lines)):
            if lines[end] == indent + "}" or lines[end].startswith(indent + "};"):
                length = end - first + 1
                if length > limit:
                    found.append((first + 1, length, lines[first].strip()))
                break
    return found


def main():
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".")
    limit = int(sys.argv[2]) if len(sys.argv) > 2 else 60
    for path in sorted(root.rglob("*")):
        rel = path.relative_to(root)
        if path.suffix not in (".cc", ".h") or rel.parts[0] in ("tests", ".git") or \
                rel.parts[0].startswith("build"):
            continue
        for line, length, text in long_functions(path, limit):
            print(f"{rel}:{line}: {length} lines: {text[:80]}")


if __name__ == "__main__":
    main()
