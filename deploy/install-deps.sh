#!/usr/bin/env bash
# Installs every Debian 12 package that ForestMap's build, tests, benchmarks and demo need.
# Idempotent: packages already present are skipped by apt. Run as root (or via sudo).
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  libsqlite3-dev libeigen3-dev libnanoflann-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev nlohmann-json3-dev
  libpcl-dev
  libproj-dev proj-bin    # CRSs (geo/crs.cc); cs2cs checks the WGS84 answers in the tests
  libgdal-dev gdal-bin    # GeoPackage / GeoJSON / shapefile trees (client/io/geo_io.cc); ogrinfo
  libcairo2-dev           # forestmap plot: SVG and PNG pictures (client/cli/map_plot.cc)
  golang-github-gogo-googleapis-dev  # google/rpc/*.proto: error details (proto/error_details.h)
  libcpp-httplib-dev      # forestmapd --http: the read-only web page (server/http/http_page.cc)
  chromium                # the web page's browser test (tests/server/http/http_page_test.cc)
  clang-format  # tests/tools/check_format.sh (the format check in the test run)
  python3  # tests/bench scripts and tests/tools checks (relocalization.sh, scan_to_pose.sh, truth_checks.py)
  libpq-dev   # the PostgreSQL map store (--db postgresql://...)
  postgresql  # initdb / pg_ctl for the tests' throwaway cluster (tests/pg_fixture.h)
  python3-grpcio python3-protobuf python3-numpy python3-pytest  # client/python and its tests
  python3-pip python3-setuptools python3-wheel python3-venv  # its wheel, built offline and installed in a venv
  systemd  # systemd-analyze verify of deploy/forestmapd.service (a test)
  dpkg-dev file  # cpack's Debian packages: dpkg-shlibdeps computes their Depends (deploy/package.sh)
  mmdebstrap  # a Debian 12 root filesystem for deploy/Dockerfile's runtime stage (a test)
  iproute2  # loopback up in that test's network namespace
  libssl-dev openssl  # token hashes (libcrypto); tests make TLS certificates with the CLI
  libspdlog-dev  # forestmapd's structured logs (--metrics uses libcpp-httplib-dev above)
  prometheus  # promtool, which checks the metrics exposition in a test
  lld  # the linker of every build (several times faster than GNU ld over a hundred programs)
  clang libclang-rt-14-dev llvm  # libFuzzer targets (tests/fuzz; llvm-symbolizer for reports)
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Node.js and npm, only to install the npm tools below (Debian 12: nodejs 18, npm 9). Checked by
# command, not by package: a Node.js from elsewhere (e.g. NodeSource's, which bundles npm and
# conflicts with Debian's npm package) is used as it is.
command -v npm >/dev/null 2>&1 || missing+=(nodejs npm)

SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
else
  echo "install-deps: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# Tools from the npm registry, pinned by deploy/tools/package-lock.json, into a prefix of ours
# (never the source tree; nothing is downloaded at build time): buf, which lints the API and
# checks it against the last release (CTest api_lint, api_breaking; buf.yaml).
TOOLS_PREFIX="${FORESTMAP_TOOLS_PREFIX:-/opt/forestmap-tools}"
TOOLS_DIR="$(cd "$(dirname "$0")/tools" && pwd)"
if cmp -s "$TOOLS_DIR/package-lock.json" "$TOOLS_PREFIX/package-lock.json" &&
   "$TOOLS_PREFIX/node_modules/.bin/buf" --version >/dev/null 2>&1; then
  echo "install-deps: npm tools present in $TOOLS_PREFIX"
else
  echo "install-deps: installing npm tools (buf) into $TOOLS_PREFIX"
  $SUDO mkdir -p "$TOOLS_PREFIX"
  $SUDO cp "$TOOLS_DIR/package.json" "$TOOLS_DIR/package-lock.json" "$TOOLS_PREFIX/"
  $SUDO npm ci --prefix "$TOOLS_PREFIX" --no-audit --no-fund --loglevel=error
fi
echo "install-deps: done"
