#!/usr/bin/env bash
# Installs every Debian 12 package that ForestMap's build, tests, benchmarks and demo need.
# Idempotent: packages already present are skipped by apt. Run as root (or via sudo).
#   install-deps.sh            everything (deploy/build.sh, deploy/test.sh)
#   install-deps.sh --product  only what building forestmapd and forestmap and their Debian
#                              packages needs (deploy/package.sh): no test tools, no npm
set -euo pipefail

# The product: compilers, CPack's tools (dpkg-shlibdeps computes the packages' Depends) and the
# -dev packages CMake looks for with -DFORESTMAP_BUILD_TESTS=OFF -DFORESTMAP_BUILD_LAB=OFF. The
# same list as deploy/Dockerfile's build stage (tests/deploy/image_test.py checks both against
# what CMake finds).
PRODUCT_PACKAGES=(
  build-essential cmake pkg-config dpkg-dev file lld
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  golang-github-gogo-googleapis-dev  # google/rpc/*.proto: error details (proto/error_details.h)
  libeigen3-dev libnanoflann-dev libcli11-dev nlohmann-json3-dev
  libpcl-dev
  libgdal-dev             # GeoPackage / GeoJSON / shapefile trees (client/io/geo_io.cc)
  libproj-dev             # CRSs (geo/crs.cc)
  libcairo2-dev           # forestmap plot: SVG and PNG pictures (client/cli/map_plot.cc)
  libsqlite3-dev libpq-dev  # the SQLite and PostgreSQL map stores (--db postgresql://...)
  libssl-dev              # token hashes (libcrypto), TLS certificates' checks
  libspdlog-dev           # forestmapd's structured logs
  libcpp-httplib-dev      # forestmapd --http and --metrics (server/http/)
)

PACKAGES=(
  "${PRODUCT_PACKAGES[@]}"
  libgtest-dev libgmock-dev libbenchmark-dev
  ninja-build             # deploy/build.sh and deploy/test.sh build with Ninja
  proj-bin                # cs2cs checks the WGS84 answers in the tests
  gdal-bin                # ogrinfo / ogr2ogr check the GIS exports in the tests
  chromium                # the web page's browser test (tests/server/http/http_page_test.cc)
  clang-format  # tests/tools/check_format.sh (the format check in the test run)
  python3  # tests/bench scripts and tests/tools checks (relocalization.sh, scan_to_pose.sh, truth_checks.py)
  postgresql  # initdb / pg_ctl for the tests' throwaway cluster (tests/pg_fixture.h)
  python3-grpcio python3-protobuf python3-numpy python3-pytest  # client/python and its tests
  python3-pip python3-setuptools python3-wheel python3-venv  # its wheel, built offline and installed in a venv
  openssl  # tests make TLS certificates with the CLI
  systemd  # systemd-analyze verify of deploy/forestmapd.service (a test)
  mmdebstrap  # a Debian 12 root filesystem for deploy/Dockerfile's runtime stage (a test)
  iproute2  # loopback up in that test's network namespace
  prometheus  # promtool, which checks the metrics exposition in a test
  clang libclang-rt-14-dev llvm  # libFuzzer targets (tests/fuzz; llvm-symbolizer for reports)
)

product=0
case "${1:-}" in
  "") ;;
  --product) product=1 PACKAGES=("${PRODUCT_PACKAGES[@]}") ;;
  *) echo "usage: install-deps.sh [--product]" >&2; exit 2 ;;
esac

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Node.js and npm, only to install the npm tools below (Debian 12: nodejs 18, npm 9). Checked by
# command, not by package: a Node.js from elsewhere (e.g. NodeSource's, which bundles npm and
# conflicts with Debian's npm package) is used as it is.
[ $product = 1 ] || command -v npm >/dev/null 2>&1 || missing+=(nodejs npm)

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

if [ $product = 1 ]; then
  echo "install-deps: done (the product's build only)"
  exit 0
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
