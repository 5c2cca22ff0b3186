#!/usr/bin/env python3
"""Keeps README.md and docs/ true to the code. Python 3 standard library only.

  docs_check.py cli-reference (--write | --check) [--build DIR | --forestmap B --forestmapd B
                [--lab B]] [--root DIR]
      Runs `--help` of every command and subcommand of the built binaries and writes
      docs/cli.md (--write), or fails when docs/cli.md differs from what they print (--check).
  docs_check.py coverage [binaries as above] [--root DIR]
      Every flag and subcommand of forestmapd appears in docs/operations.md; every command of
      forestmap (and its global flags) in docs/user-guide.md; every lab command in
      docs/development.md or docs/performance.md.
  docs_check.py links [--root DIR]
      Every relative link of README.md and docs/*.md resolves (file, folder, #anchor by GitHub's
      rules); README.md links every page of docs/ and stays under 200 lines; a page with three or
      more sections links each from its contents; no page cites a tracker number ("issue 12").

Exits 0 when all is well, else 1 with one line per finding (2 for a bad command line).
"""

import argparse
import concurrent.futures
import difflib
import os
import re
import subprocess
import sys
import unicodedata

README_MAX_LINES = 200
# Commands of the lab (benchmarks, simulator, demo data): documented for developers, not users.
# When a separate lab binary is given, its commands are the lab's instead.
LAB_COMMANDS = {"bench-reloc", "bench-server", "bench-load", "bench-mapping", "simulate",
                "demo-data"}
BINARY_NAMES = {"forestmap": "forestmap", "forestmapd": "forestmapd", "lab": "forestmap-lab"}
TRACKER_NUMBER = re.compile(r"\bissues?[\s#-]*\d+", re.IGNORECASE)


# ---------------------------------------------------------------------------------------------
# Running the binaries


def run_help(binary, path):
    """The --help text of `binary path...`, with trailing blanks removed from every line."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("FORESTMAP")}
    env["LC_ALL"] = "C"
    result = subprocess.run([binary, *path, "--help"], capture_output=True, text=True, env=env,
                            timeout=60, check=False)
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join([binary, *path, '--help'])} exited {result.returncode}: "
                           f"{result.stderr.strip()}")
    # A program that names itself after argv[0] would print the build directory.
    text = result.stdout.replace(binary, os.path.basename(binary))
    return "\n".join(line.rstrip() for line in text.rstrip().split("\n"))


def section(help_text, title):
    """The lines of a CLI11 help section ("Options:", "Subcommands:") up to the next one."""
    lines, inside = [], False
    for line in help_text.split("\n"):
        if line == title:
            inside = True
        elif inside and line and not line.startswith(" "):
            break
        elif inside:
            lines.append(line)
    return lines


def subcommands(help_text):
    return [m.group(1) for line in section(help_text, "Subcommands:")
            if (m := re.match(r"^  ([A-Za-z0-9][\w-]*)(\s|$)", line))]


def flags(help_text):
    """The long flags of the Options section (--help excluded)."""
    found = []
    for line in section(help_text, "Options:"):
        head = re.match(r"^  (\S[^ ]*(?: [A-Z]+)*)", line)
        if head:
            found += [f for f in re.findall(r"--[a-z][a-z0-9-]*", head.group(1))
                      if f != "--help" and f not in found]
    return found


def command_tree(binary, name):
    """[(path, help)] of a binary and all its subcommands, depth first in --help order."""
    texts, frontier = {}, [()]
    with concurrent.futures.ThreadPoolExecutor(max_workers=4) as pool:
        while frontier:  # one level at a time, its --help calls in parallel
            for path, text in zip(frontier, pool.map(lambda p: run_help(binary, list(p)),
                                                     frontier)):
                texts[path] = text
            frontier = [path + (sub,) for path in frontier for sub in subcommands(texts[path])]

    def visit(path):
        yield [name, *path], texts[path]
        for sub in subcommands(texts[path]):
            yield from visit(path + (sub,))

    return list(visit(()))


def find_binaries(args):
    """{key: path} from explicit flags, else from the executables under --build."""
    found = {k: getattr(args, k) for k in BINARY_NAMES if getattr(args, k)}
    if args.build and len(found) < len(BINARY_NAMES):
        for dirpath, dirnames, filenames in os.walk(args.build):
            dirnames[:] = [d for d in dirnames if not d.startswith(".") and d != "CMakeFiles"]
            for key, name in BINARY_NAMES.items():
                path = os.path.join(dirpath, name)
                if key not in found and name in filenames and os.access(path, os.X_OK):
                    found[key] = path
    missing = [BINARY_NAMES[k] for k in ("forestmap", "forestmapd") if k not in found]
    if missing:
        sys.exit(f"docs_check: cannot find {', '.join(missing)} (give --build DIR or the paths)")
    return found


# ---------------------------------------------------------------------------------------------
# GitHub's heading anchors


def strip_inline(text):
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)  # links and images: their text
    text = re.sub(r"<[^>]+>", "", text)                     # HTML tags
    return text.replace("`", "").replace("*", "")


def slug(heading):
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = strip_inline(heading).strip().lower()
    kept = "".join(c for c in text
                   if c in " -_" or unicodedata.category(c)[0] in "LN")
    return kept.replace(" ", "-")


def without_code(markdown):
    """The text with fenced code blocks blanked (line numbers kept) and inline code removed."""
    out, fence = [], None
    for line in markdown.split("\n"):
        marker = re.match(r"^\s*(```+|~~~+)", line)
        if fence:
            if marker and marker.group(1)[0] == fence[0] and len(marker.group(1)) >= len(fence):
                fence = None
            out.append("")
        elif marker:
            fence = marker.group(1)
            out.append("")
        else:
            out.append(re.sub(r"(`+)(?:(?!\1).)+?\1", "", line))
    return out


def headings(markdown):
    """[(level, text)] of the ATX headings outside code blocks."""
    return [(len(m.group(1)), m.group(2).strip()) for line in without_code(markdown)
            if (m := re.match(r"^(#{1,6})\s+(.*?)\s*#*\s*$", line))]


def anchors(markdown):
    seen, result = {}, set()
    for _, text in headings(markdown):
        base = slug(text)
        n = seen.get(base, 0)
        seen[base] = n + 1
        result.add(base if n == 0 else f"{base}-{n}")
    result.update(re.findall(r"<a\s+(?:name|id)=\"([^\"]+)\"", markdown))
    return result


# ---------------------------------------------------------------------------------------------
# The CLI reference


def cli_reference(binaries):
    trees = [command_tree(binaries["forestmap"], "forestmap")]
    if "lab" in binaries:
        trees.append(command_tree(binaries["lab"], "forestmap-lab"))
    trees.append(command_tree(binaries["forestmapd"], "forestmapd"))
    lines = [
        "# Command-line reference",
        "",
        "<!-- Generated by tests/tools/docs_check.py from the binaries' --help: do not edit. -->",
        "",
        "Every command's `--help`, as the built binaries print it. What the commands are for and",
        "how to use them: [user-guide.md](user-guide.md); `forestmapd` and its flags:",
        "[operations.md](operations.md). The test `docs_cli_reference` fails when this page and the",
        "binaries disagree; regenerate it after changing a command line:",
        "",
        "```sh",
        "python3 tests/tools/docs_check.py cli-reference --write --build build",
        "```",
        "",
        "## Contents",
        "",
    ]
    for tree in trees:
        for path, _ in tree:
            name = " ".join(path)
            lines.append(f"{'  ' * (len(path) - 1)}- [{name}](#{slug(name)})")
    for tree in trees:
        for path, text in tree:
            name = " ".join(path)
            lines += ["", f"{'#' * min(len(path) + 1, 4)} {name}", "", "```", text, "```"]
    return "\n".join(lines) + "\n"


def check_cli_reference(args, binaries):
    target = os.path.join(args.root, "docs", "cli.md")
    wanted = cli_reference(binaries)
    if args.write:
        with open(target, "w", encoding="utf-8") as f:
            f.write(wanted)
        print(f"docs_check: wrote {target}")
        return []
    try:
        with open(target, encoding="utf-8") as f:
            have = f.read()
    except FileNotFoundError:
        have = ""
    if have == wanted:
        return []
    diff = list(difflib.unified_diff(have.split("\n"), wanted.split("\n"), "docs/cli.md",
                                     "--help of the binaries", lineterm="", n=1))
    shown = "\n".join(diff[:60]) + ("\n..." if len(diff) > 60 else "")
    given = " ".join(f"--{k} {v}" for k, v in sorted(binaries.items()))
    return [f"docs/cli.md differs from the binaries' --help:\n{shown}\n"
            f"Regenerate it with: python3 tests/tools/docs_check.py cli-reference --write "
            f"{given}\n(or --build BUILD_DIR)"]


# ---------------------------------------------------------------------------------------------
# Coverage: every flag and command on the page that documents it


def read_page(root, name):
    with open(os.path.join(root, "docs", name), encoding="utf-8") as f:
        return f.read()


def mentions(page, words):
    """True when `words` (e.g. "map prune", "--tls-ca") occur in the page as a whole."""
    pattern = r"(?<![\w-])" + r"\s+".join(re.escape(w) for w in words.split()) + r"(?![\w-])"
    return re.search(pattern, page) is not None


def check_coverage(args, binaries):
    problems = []
    operations = read_page(args.root, "operations.md")
    for path, text in command_tree(binaries["forestmapd"], "forestmapd"):
        sub = " ".join(path[1:])
        if sub and not mentions(operations, sub):
            problems.append(f"docs/operations.md does not mention `forestmapd {sub}`")
        for flag in flags(text):
            if not mentions(operations, flag):
                problems.append(f"docs/operations.md does not mention {' '.join(path)} {flag}")

    guide = read_page(args.root, "user-guide.md")
    developer = read_page(args.root, "development.md") + read_page(args.root, "performance.md")
    forestmap = command_tree(binaries["forestmap"], "forestmap")
    lab = command_tree(binaries["lab"], "forestmap-lab") if "lab" in binaries else []
    lab_names = {p[1] for p, _ in lab if len(p) > 1} or LAB_COMMANDS
    for flag in flags(forestmap[0][1]):
        if not mentions(guide, flag):
            problems.append(f"docs/user-guide.md does not mention the global flag forestmap {flag}")
    for path, text in forestmap + lab:
        sub = " ".join(path[1:])
        if not sub or subcommands(text):
            continue  # a group ("map") is covered by its commands
        if path[1] in lab_names:
            if not mentions(developer, sub):
                problems.append(f"neither docs/development.md nor docs/performance.md mentions "
                                f"the lab command `{sub}`")
        elif not mentions(guide, sub):
            problems.append(f"docs/user-guide.md does not mention `forestmap {sub}`")
    return problems


# ---------------------------------------------------------------------------------------------
# Links, contents, length, tracker numbers


def pages(root):
    docs = os.path.join(root, "docs")
    names = sorted(n for n in os.listdir(docs) if n.endswith(".md"))
    return [os.path.join(root, "README.md")] + [os.path.join(docs, n) for n in names]


def links(markdown):
    """[(line number, target)] of inline links and images and of reference definitions."""
    found = []
    for number, line in enumerate(without_code(markdown), 1):
        for m in re.finditer(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]*)>?(?:\s+\"[^\"]*\")?\s*\)",
                             line):
            found.append((number, m.group(1)))
        ref = re.match(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(\s|$)", line)
        if ref:
            found.append((number, ref.group(1)))
    return found


def check_links(args):
    problems, cache = [], {}
    root = os.path.realpath(args.root)

    def anchors_of(path):
        if path not in cache:
            with open(path, encoding="utf-8") as f:
                cache[path] = anchors(f.read())
        return cache[path]

    for page in pages(args.root):
        rel = os.path.relpath(page, args.root)
        with open(page, encoding="utf-8") as f:
            text = f.read()
        for number, target in links(text):
            if not target or re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target):
                continue  # http:, https:, mailto:
            path, _, anchor = target.partition("#")
            resolved = os.path.realpath(os.path.join(os.path.dirname(page), path)) if path \
                else os.path.realpath(page)
            where = f"{rel}:{number}: link {target}"
            if os.path.commonpath([root, resolved]) != root:
                problems.append(f"{where} leaves the repository")
            elif not os.path.exists(resolved):
                problems.append(f"{where}: no file {os.path.relpath(resolved, root)}")
            elif anchor and resolved.endswith(".md") and anchor not in anchors_of(resolved):
                problems.append(f"{where}: no heading with anchor #{anchor} in "
                                f"{os.path.relpath(resolved, root)}")
        for number, line in enumerate(text.split("\n"), 1):
            for m in TRACKER_NUMBER.finditer(line):
                problems.append(f"{rel}:{number}: cites a tracker number ('{m.group(0)}'): say "
                                f"what is true of the product instead")
        sections = [t for level, t in headings(text) if level == 2]
        if page != pages(args.root)[0] and len(sections) >= 3:
            linked = {t.partition("#")[2] for _, t in links(text) if t.startswith("#")}
            for title in sections:
                if slug(title) not in linked | {"contents"}:
                    problems.append(f"{rel}: the contents do not link the section '{title}'")

    readme = pages(args.root)[0]
    with open(readme, encoding="utf-8") as f:
        text = f.read()
    count = text.count("\n")
    if count >= README_MAX_LINES:
        problems.append(f"README.md has {count} lines; keep it under {README_MAX_LINES} (move "
                        f"detail to docs/)")
    linked = {os.path.realpath(os.path.join(args.root, t.partition("#")[0]))
              for _, t in links(text)}
    for page in pages(args.root)[1:]:
        if os.path.realpath(page) not in linked:
            problems.append(f"README.md does not link {os.path.relpath(page, args.root)}")
    return problems


# ---------------------------------------------------------------------------------------------


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("what", choices=["cli-reference", "coverage", "links"])
    parser.add_argument("--root", default=os.path.join(os.path.dirname(__file__), "..", ".."),
                        help="the repository (default: this script's)")
    parser.add_argument("--build", help="build directory to find the binaries in")
    for key, name in BINARY_NAMES.items():
        parser.add_argument(f"--{key}", help=f"path of {name}")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--write", action="store_true", help="cli-reference: write docs/cli.md")
    mode.add_argument("--check", action="store_true", help="cli-reference: compare (default)")
    args = parser.parse_args()
    args.root = os.path.normpath(args.root)

    try:
        if args.what == "links":
            problems = check_links(args)
        elif args.what == "coverage":
            problems = check_coverage(args, find_binaries(args))
        else:
            problems = check_cli_reference(args, find_binaries(args))
    except (OSError, RuntimeError, subprocess.TimeoutExpired) as error:
        problems = [str(error)]
    for problem in problems:
        print(f"docs_check {args.what}: {problem}")
    if problems:
        print(f"docs_check {args.what}: {len(problems)} finding(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
