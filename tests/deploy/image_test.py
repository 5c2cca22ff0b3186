#!/usr/bin/env python3
"""deploy/Dockerfile checked without a Docker engine.

  image_test.py lists SOURCE_DIR
      The build stage's package list against what CMake finds when it configures the Dockerfile's
      build (forestmapd and forestmap, no tests, no lab): every file a find_package,
      pkg_check_modules, find_program or find_path found (the configure's CMakeCache.txt) belongs
      to a package that the list installs (itself or through its Depends), and every -dev package
      of the list owns one of those files; deploy/install-deps.sh's PRODUCT_PACKAGES (what
      `install-deps.sh --product` installs for deploy/package.sh) is the same list. The runtime
      stage installs only the project's .deb files, so that its libraries are their Depends
      (dpkg-shlibdeps), one list.

  image_test.py rootfs BUILD_DIR DATA_DIR
      The runtime stage for real: a Debian 12 root filesystem (mmdebstrap minbase, as the
      debian:*-slim images; the tarball is kept in BUILD_DIR/image-test for the next run), the
      packages cpack builds from BUILD_DIR, and the stage's instructions replayed in it (RUN in a
      chroot, COPY --from=build of the packages, USER, WORKDIR, ENV). Then, as `docker run` would,
      in a private network, PID and mount namespace (unshare): the ENTRYPOINT with the default CMD
      as the image's user, served until the HEALTHCHECK command passes, a real map uploaded and a
      frame relocalized with the image's forestmap; and the ENTRYPOINT with operator arguments
      (--listen elsewhere) in place of CMD.
Runs as root (chroot, unshare), in a private mount namespace on a tmpfs: nothing is left behind
but the cached tarball.
"""
import hashlib
import json
import os
import pathlib
import re
import shlex
import shutil
import subprocess
import sys
import tempfile

# Packages of the build list that own no file CMake finds: the compilers, CMake itself, the
# pkg-config that pkg_check_modules runs, the linker, and what cpack runs (dpkg-shlibdeps, file).
BUILD_TOOLS = {"build-essential", "cmake", "pkg-config", "dpkg-dev", "file", "lld"}
# The PATH docker gives a container's processes.
DOCKER_PATH = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"
# Cache entries of the configure that are not found dependencies.
NOT_DEPENDENCIES = re.compile(r"^(CMAKE_|FORESTMAP_SHARED_DATA$|FORESTMAP_TEST_PYTHON$|_)")


def fail(message):
    print(f"image_test: {message}", file=sys.stderr)
    sys.exit(1)


def run(command, **kwargs):
    return subprocess.run(command, check=True, text=True, **kwargs)


def output(command):
    return run(command, stdout=subprocess.PIPE).stdout


# ---- Dockerfile ----


def instructions(dockerfile):
    """[(KEYWORD, arguments)] with continuation lines joined and comments dropped."""
    result, pending = [], ""
    for line in pathlib.Path(dockerfile).read_text().splitlines():
        if not pending and (not line.strip() or line.lstrip().startswith("#")):
            continue
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        keyword, _, arguments = (pending + line).strip().partition(" ")
        result.append((keyword.upper(), arguments.strip()))
        pending = ""
    return result


def stages(dockerfile):
    """The instructions of each stage, from its FROM on."""
    result = []
    for keyword, arguments in instructions(dockerfile):
        if keyword == "FROM":
            result.append([])
        result[-1].append((keyword, arguments))
    return result


def apt_installs(stage):
    """The arguments of every `apt-get install` of the stage's RUN instructions."""
    packages = []
    for keyword, arguments in stage:
        if keyword != "RUN":
            continue
        for command in re.split(r"&&|;", arguments):
            words = shlex.split(command)
            if "apt-get" in words and "install" in words:
                after = words[words.index("install") + 1:]
                packages += [w for w in after if not w.startswith("-") and "=" not in w]
    return packages


# ---- lists ----


def path_names(path):
    """`path`, then the names a package may ship it by: under /lib, /bin, /sbin when those are
    links into /usr (merged /usr), and the file a symbolic link leads to."""
    return [path, re.sub(r"^/usr(/(lib|bin|sbin)/)", r"\1", path), os.path.realpath(path)]


def owners(paths):
    """{path: Debian packages owning it (dpkg -S), or none}, in one dpkg-query."""
    names = sorted({name for path in paths for name in path_names(path)})
    found = subprocess.run(["dpkg-query", "-S", *names], text=True, stdout=subprocess.PIPE,
                           stderr=subprocess.DEVNULL).stdout
    by_name = {}
    for line in found.splitlines():
        packages, _, owned = line.rpartition(": ")
        if not line.startswith("diversion"):
            by_name.setdefault(owned, set()).update(p.split(":")[0] for p in packages.split(", "))
    return {path: next((by_name[n] for n in path_names(path) if n in by_name), set())
            for path in paths}


def dependency_closure(packages):
    """`packages` and everything they depend on, recursively (installed packages): apt-cache
    prints each package it reaches once, unindented."""
    listed = output(["apt-cache", "depends", "--recurse", "--installed", "--no-recommends",
                     "--no-suggests", "--no-conflicts", "--no-breaks", "--no-replaces",
                     "--no-enhances", *packages])
    return {line.strip("<>").split(":")[0] for line in listed.splitlines()
            if line and not line.startswith(" ")}


def found_dependencies(source):
    """{cache entry: path} of what CMake found configuring the Dockerfile's build."""
    with tempfile.TemporaryDirectory(prefix="forestmap-image-lists-") as build:
        run(["cmake", "-S", source, "-B", build, "-DCMAKE_BUILD_TYPE=Release",
             "-DFORESTMAP_BUILD_TESTS=OFF", "-DFORESTMAP_BUILD_LAB=OFF"],
            stdout=subprocess.DEVNULL)
        cache = pathlib.Path(build, "CMakeCache.txt").read_text()
    entries = re.findall(r"^([^#/:\n]+):(?:FILEPATH|PATH)=(/.*)$", cache, re.MULTILINE)
    return {name: path for name, path in entries
            if not NOT_DEPENDENCIES.match(name) and os.path.exists(path)
            and not path.startswith(source)}


def product_packages(source):
    """PRODUCT_PACKAGES of deploy/install-deps.sh: the words of its bash array, comments dropped."""
    text = pathlib.Path(source, "deploy", "install-deps.sh").read_text()
    match = re.search(r"^PRODUCT_PACKAGES=\((.*?)^\)", text, re.MULTILINE | re.DOTALL)
    if not match:
        fail("deploy/install-deps.sh has no PRODUCT_PACKAGES=( ... ) list")
    return [word for line in match.group(1).splitlines()
            for word in line.partition("#")[0].split()]


def check_lists(source):
    build_stage, *_, runtime_stage = stages(os.path.join(source, "deploy", "Dockerfile"))
    build_list = apt_installs(build_stage)
    if not build_list:
        fail("no apt-get install in the build stage")
    closure = dependency_closure(build_list)
    problems, owning = [], set()
    product = product_packages(source)
    if sorted(product) != sorted(build_list):
        problems.append("deploy/install-deps.sh's PRODUCT_PACKAGES differ from the build stage's "
                        f"list: only in install-deps.sh {sorted(set(product) - set(build_list))}, "
                        f"only in the Dockerfile {sorted(set(build_list) - set(product))}")
    found = found_dependencies(source)
    owned_by = owners(found.values())
    for name, path in sorted(found.items()):
        packages = owned_by[path]
        if not packages:
            problems.append(f"{name}={path} belongs to no Debian package")
        elif not packages & closure:
            problems.append(f"{name}={path} ({', '.join(sorted(packages))}): not installed by "
                            "the build stage")
        if len(packages) == 1:  # a folder like /usr/include names no package
            owning |= packages
    for package in build_list:
        if package not in BUILD_TOOLS and package not in owning:
            problems.append(f"build stage installs {package}, which owns nothing CMake finds")
    runtime_list = apt_installs(runtime_stage)
    if not runtime_list or any(not p.endswith(".deb") for p in runtime_list):
        problems.append(f"runtime stage installs {runtime_list}: only the project's .deb files "
                        "(their Depends are the runtime libraries)")
    for problem in problems:
        print("image_test:", problem)
    print(f"build stage: {len(build_list)} packages; CMake found {len(found)} paths in "
          f"{len(owning)} packages; runtime stage: {' '.join(runtime_list)}")
    if problems:
        fail(f"{len(problems)} problem(s) in deploy/Dockerfile's package lists")


# ---- rootfs ----


# dpkg's configuration of the debian:*-slim images: no documentation, manual pages or locales.
SLIM_DPKG_OPTIONS = ["path-exclude=/usr/share/doc/*", "path-include=/usr/share/doc/*/copyright",
                     "path-exclude=/usr/share/man/*", "path-exclude=/usr/share/groff/*",
                     "path-exclude=/usr/share/info/*", "path-exclude=/usr/share/locale/*"]


def base_tarball(cache_dir, from_line, scratch):
    """A minbase Debian 12 root filesystem (the variant of the debian:*-slim images, with their
    dpkg excludes) from the host's apt sources, made once per base image and sources."""
    sources = sorted(pathlib.Path("/etc/apt/sources.list.d").glob("*.sources")) + [
        p for p in [pathlib.Path("/etc/apt/sources.list")] if p.exists() and p.stat().st_size]
    key = hashlib.sha256("".join([from_line, *SLIM_DPKG_OPTIONS,
                                  *(p.read_text() for p in sources)]).encode())
    tarball = pathlib.Path(cache_dir, f"minbase-{key.hexdigest()[:16]}.tar")
    if not tarball.exists():
        print(f"mmdebstrap: {tarball} (kept for the next runs)", flush=True)
        os.makedirs(cache_dir, exist_ok=True)
        partial = pathlib.Path(scratch, "minbase.tar")
        run(["mmdebstrap", "--quiet", "--variant=minbase", "--mode=root",
             *(f"--dpkgopt={option}" for option in SLIM_DPKG_OPTIONS), "bookworm", str(partial),
             *map(str, sources)], env={**os.environ, "TMPDIR": str(scratch)})
        shutil.move(partial, tarball)
    return tarball


def in_namespace(root, script, network=True):
    """Runs the bash `script` in new mount and PID namespaces (and a network one with only
    loopback unless `network`), with ROOT's /dev and /proc mounted; nothing outlives it."""
    setup = (f"set -euo pipefail; root={shlex.quote(str(root))}\n"
             'mount --rbind /dev "$root/dev"; mount -t proc proc "$root/proc"\n')
    if not network:
        setup += "ip link set lo up\n"
    flags = ["--mount", "--pid", "--fork", "--kill-child"] + ([] if network else ["--net"])
    return subprocess.run(["unshare", *flags, "bash", "-c", setup + script], text=True)


def replay(stage, root, packages_dir):
    """Replays the runtime stage's instructions into ROOT; returns the image's configuration."""
    image = {"user": "root", "workdir": "/", "env": {}, "entrypoint": [], "cmd": [],
             "healthcheck": []}
    shutil.copy("/etc/resolv.conf", root / "etc" / "resolv.conf")  # as docker build does
    for keyword, arguments in stage[1:]:
        if keyword == "RUN":
            print(f"RUN {arguments[:100]}...", flush=True)
            done = in_namespace(root, f'chroot "$root" {clean_env(image, image["workdir"])} '
                                      f'/bin/sh -c {shlex.quote(arguments)}')
            if done.returncode != 0:
                fail(f"RUN failed ({done.returncode}): {arguments}")
        elif keyword == "COPY":
            match = re.fullmatch(r"--from=build\s+/build/packages/\s+(/\S+)/", arguments)
            if not match:
                fail(f"COPY {arguments}: only the build stage's packages are replayed")
            target = root / match.group(1).lstrip("/")
            target.mkdir(parents=True, exist_ok=True)
            for deb in pathlib.Path(packages_dir).glob("*.deb"):
                shutil.copy(deb, target)
        elif keyword == "ENV":
            name, _, value = arguments.partition("=")
            image["env"][name] = value
        elif keyword in ("USER", "WORKDIR"):
            image[keyword.lower()] = arguments
        elif keyword in ("ENTRYPOINT", "CMD"):
            image[keyword.lower()] = json.loads(arguments)
        elif keyword == "HEALTHCHECK":
            image["healthcheck"] = json.loads(arguments.partition(" CMD ")[2])
        elif keyword not in ("VOLUME", "EXPOSE"):
            fail(f"{keyword}: not replayed by this test")
    return image


def user_ids(root, user):
    """'uid:gid' of the USER instruction's user:group, from ROOT's passwd and group files."""
    name, _, group = user.partition(":")
    ids = {}
    for table, key in (("passwd", name), ("group", group or name)):
        for line in (root / "etc" / table).read_text().splitlines():
            fields = line.split(":")
            if fields[0] == key:
                ids[table] = fields[2]
    if len(ids) != 2:
        fail(f"USER {user} is not in the image's passwd/group")
    return f"{ids['passwd']}:{ids['group']}"


def clean_env(image, workdir):
    """`env` as a container's processes get it: docker's PATH and the image's ENV, nothing of
    the host's environment."""
    assignments = [f"{k}={v}" for k, v in image["env"].items()]
    return " ".join(map(shlex.quote, ["/usr/bin/env", "-i", "-C", workdir, f"PATH={DOCKER_PATH}",
                                      *assignments]))


def container_script(image, ids, arguments, health):
    """Bash for one `docker run IMAGE ARGUMENTS` whose `health` command must pass, then the
    relocalization of a real frame, then `docker stop` (SIGTERM, exit 0)."""
    as_user = f'chroot --userspec={ids} "$root" {clean_env(image, image["workdir"])}'
    command = " ".join(map(shlex.quote, image["entrypoint"] + arguments))
    health_command = " ".join(map(shlex.quote, health))
    client = health_command.partition(" health")[0]  # forestmap --server ADDRESS
    return f"""
{as_user} {command} > "$root/tmp/server.log" 2>&1 &
server=$!
healthy=0
for _ in $(seq 50); do
  if {as_user} {health_command}; then healthy=1; break; fi
  kill -0 $server 2>/dev/null || break
  sleep 0.2
done
cat "$root/tmp/server.log"
[ $healthy = 1 ] || {{ echo "health check never passed: {health_command}"; exit 1; }}
{as_user} {client} map create stein --trees /tmp/data/map.csv
{as_user} {client} relocalize stein --trees /tmp/data/frame.csv > "$root/tmp/answer.json"
kill -TERM $server
wait $server || {{ echo "forestmapd did not stop cleanly"; exit 1; }}
"""


def check_rootfs(build, data_dir):
    """Runs in a mount namespace of its own (see main) with a tmpfs as its scratch space: the
    root filesystem and every mount made in it end with the process, however it ends."""
    source = pathlib.Path(__file__).resolve().parents[2]
    stage = stages(source / "deploy" / "Dockerfile")[-1]
    work = pathlib.Path(build, "image-test", "scratch")
    work.mkdir(parents=True, exist_ok=True)
    run(["mount", "-t", "tmpfs", "-o", "size=4g,mode=0755", "forestmap-image-test", str(work)])
    packages = work / "packages"
    run(["cpack", "--config", str(pathlib.Path(build, "CPackConfig.cmake")), "-B",
         str(packages)], stdout=subprocess.DEVNULL)
    tarball = base_tarball(pathlib.Path(build, "image-test"), stage[0][1], work)
    root = work / "root"
    root.mkdir()
    run(["tar", "-xf", str(tarball), "-C", str(root)])
    image = replay(stage, root, packages)
    missing = in_namespace(root, 'chroot "$root" ldd /usr/bin/forestmapd /usr/bin/forestmap'
                                 ' | grep "not found" && exit 1 || exit 0')
    if missing.returncode != 0:
        fail("the image's programs miss shared libraries (above)")
    check_runs(root, image, data_dir)


def check_runs(root, image, data_dir):
    """`docker run` with the default CMD, then with operator arguments, each in its own network
    namespace; each health-checked, relocalizing a real frame, and stopped."""
    sequence = pathlib.Path(data_dir, "sequences", "Oxford_Stein")
    frame = "500"  # an Oxford_Stein frame (103 trees); its truth pose is in poses.csv
    (root / "tmp" / "data").mkdir()
    shutil.copy(sequence / "map.csv", root / "tmp" / "data")
    rows = (sequence / "trees.csv").read_text().splitlines()
    (root / "tmp" / "data" / "frame.csv").write_text(
        "\n".join([rows[0]] + [r for r in rows if r.split(",")[0] == frame]) + "\n")
    truth = next(r.split(",") for r in (sequence / "poses.csv").read_text().splitlines()
                 if r.split(",")[0] == frame)
    ids = user_ids(root, image["user"])
    operator_args = ["--listen", "127.0.0.1:50052", "--db", "/tmp/operator.db"]
    operator_health = [image["healthcheck"][0], "--server", "127.0.0.1:50052", "health"]
    for arguments, health in ((image["cmd"], image["healthcheck"]),
                              (operator_args, operator_health)):
        print(f"docker run IMAGE {' '.join(arguments)}", flush=True)
        done = in_namespace(root, container_script(image, ids, arguments, health),
                            network=False)
        if done.returncode != 0:
            fail(f"the image did not serve with arguments {arguments}")
        answer = json.loads((root / "tmp" / "answer.json").read_text())
        error = ((answer["x"] - float(truth[2])) ** 2 + (answer["y"] - float(truth[3])) ** 2) ** 0.5
        print(f"frame {frame}: {answer['status']}, position error {error:.3f} m")
        if answer["status"] != "localized" or error > 0.5:
            fail(f"frame {frame} not relocalized within 0.5 m of its truth: {answer}")
    print("image_test: the runtime stage serves its health check")


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "lists":
        check_lists(os.path.abspath(sys.argv[2]))
    elif len(sys.argv) == 4 and sys.argv[1] == "rootfs":
        if os.geteuid() != 0:
            fail("rootfs needs root (mmdebstrap, chroot, unshare)")
        if not pathlib.Path(sys.argv[3], "sequences", "Oxford_Stein", "map.csv").exists():
            fail(f"no real data in {sys.argv[3]} (../shared/data)")
        if os.environ.get("FORESTMAP_IMAGE_TEST_NAMESPACE") != "1":
            # Again in a private mount namespace (check_rootfs).
            os.environ["FORESTMAP_IMAGE_TEST_NAMESPACE"] = "1"
            os.execvp("unshare", ["unshare", "--mount", "--propagation", "private",
                                  sys.executable, *sys.argv])
        check_rootfs(os.path.abspath(sys.argv[2]), sys.argv[3])
    else:
        fail("usage: image_test.py lists SOURCE_DIR | rootfs BUILD_DIR DATA_DIR")


if __name__ == "__main__":
    main()
