#!/usr/bin/env bash
# Installs every build and test dependency of cellflow from Debian 12 packages.
# Used by the README quick start and by .ci/run; safe to run again.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git clang-format
  libeigen3-dev libtet1.5-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libssl-dev openssl
  libprotobuf-dev protobuf-compiler libgrpc++-dev protobuf-compiler-grpc
  libsqlite3-dev sqlite3
  libhdf5-dev hdf5-tools
  libboost-dev
  libcli11-dev libspdlog-dev nlohmann-json3-dev
  libxml2-utils
  libzip-dev
  # The Python client (python/) and its tests: Debian's interpreter and modules,
  # pip/venv/setuptools/wheel for `pip install ./python`, meshio and matplotlib
  # for the mesh conversion and examples/python.
  python3 python3-yaml python3-grpcio python3-protobuf python3-numpy python3-h5py
  python3-pip python3-venv python3-setuptools python3-wheel
  python3-meshio python3-matplotlib
  # The result files' portability test (tests/io/h5md_portability_test.py):
  # h5py checks the H5MD rules, MDAnalysis's H5MD reader reads frames. Beside
  # the packages above python3-mdanalysis adds 30 packages, 13 MB: measured
  # 2026-12-01 download 2.9 s, unpack 2.0 s, byte-compile 3.9 s (one core);
  # without matplotlib and scipy it would be about 130 packages, 113 MB, 70 s.
  python3-mdanalysis
)
# The real-Slurm tests (ctest label "slurm", `CELLFLOW_CI_SLURM=1 .ci/run`)
# need the daemons; they are heavy and stay out of the default install.
if [ "${CELLFLOW_INSTALL_SLURM:-0}" = 1 ]; then packages+=(slurm-wlm munge); fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
